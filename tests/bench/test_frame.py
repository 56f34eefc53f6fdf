"""The frame study (bench/frame.py, ``taichi-rocks bench --only frame``): its tiny run writes frame.json and
frame.md whose figures hold together (each frame is the sum of its calls, the rows are counted, the task table
lists the step's kernels), refuses to overwrite, and the game preset is one step per 60 Hz frame."""

import json

import numpy as np
import pytest

from taichi_rocks.bench.frame import _scene, frame_table, live_lines, run_frame_study
from taichi_rocks.config.presets import PRESETS


def test_game_preset_is_one_step_a_frame():
    sc = _scene({"sim.accuracy": "game"})  # the default scene: its file sets the detection, not dt
    assert sc.sim.dt == pytest.approx(1 / 60) and sc.sim.accuracy == "game"
    assert (sc.sim.integrator, sc.sim.detection, sc.sim.precision) == ("heun", "patch", "f32")
    assert PRESETS["game"]["dt"] == 1 / 60


def test_tiny_frame_study(tmp_path):
    res = run_frame_study(tmp_path, tiny=True, progress=False)
    assert res["errors"] == []
    saved = json.loads((tmp_path / "frame.json").read_text())
    assert [r["case"] for r in saved["loops"]] == ["game", "dt = 2 ms", "game, live player"]
    for r in saved["loops"]:
        live = r["case"] == "game, live player"  # its frame has drive(), and state() is not timed
        assert r["frames"] == 20 and r["threads"] >= 1 and r["rows_median"] >= 0
        for part in ("advance_to", "impacts", "changes") + (("drive",) if live else ("state",)):
            assert 0 < r[part]["median_ms"] <= r[part]["max_ms"]
        assert r["frame"]["median_ms"] <= r["frame"]["p95_ms"] <= r["frame"]["max_ms"]
        calls = r["advance_to"]["max_ms"] + r["impacts"]["max_ms"] + r["changes"]["max_ms"]
        assert r["frame"]["max_ms"] <= calls + (r["drive"]["max_ms"] if live else 0.0) + 1e-9
    pair = saved["live"]  # the live player against the scripted one, in one process
    assert pair["frames"] == 20 and pair["vehicle"] == "car" and np.isfinite(pair["extra_ms"])
    assert pair["scripted"]["frame"]["median_ms"] > 0 and pair["live"]["frame"]["median_ms"] > 0
    kernels = {t["kernel"] for t in saved["tasks"]["tasks"]}
    assert {"active_step", "active_finish"} <= kernels and saved["tasks"]["tasks_per_step"] > 0
    md = (tmp_path / "frame.md").read_text()
    assert frame_table(saved)[0] in md and "## The step's tasks" in md and live_lines(saved)[0] in md
    with pytest.raises(FileExistsError, match="--overwrite"):
        run_frame_study(tmp_path, tiny=True, progress=False)
