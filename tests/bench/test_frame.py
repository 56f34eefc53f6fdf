"""The frame study (bench/frame.py, ``taichi-rocks bench --only frame``): its tiny run writes frame.json and
frame.md whose figures hold together (each frame is the sum of its calls, the rows are counted, the task table
lists the step's kernels), refuses to overwrite, and the game preset is one step per 60 Hz frame."""

import json
import os

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
    # each case with the engine's choice of the step's variant, and (more than one core) the parallel one forced;
    # then the live player
    forced = ["parallel"] if (os.cpu_count() or 1) > 1 else []
    assert [(r["case"], r["loops_asked"]) for r in saved["loops"]] == [
        (c, v) for c in ("game", "dt = 2 ms") for v in ["auto"] + forced] + [("game, live player", "auto")]
    for r in saved["loops"]:
        assert r["loops"] in ("serial", "parallel") and (r["loops_asked"] == "auto" or r["loops"] == r["loops_asked"])
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
    for loops in ("parallel", "serial"):  # the task table of each variant, every task's share of the device time
        t = saved["tasks"][loops]
        kernels = [x["kernel"] for x in t["tasks"]]
        assert {"active_step", "active_finish"} <= set(kernels) and t["tasks_per_step"] > 0
        assert sum(x["share"] for x in t["tasks"]) == pytest.approx(1.0)
        assert (t["parallel_tasks_per_step"] > 0) == (loops == "parallel")
        if loops == "serial":
            assert kernels.count("active_step") == kernels.count("active_finish") == 1  # one serial task each
    v = saved["variants"]  # the crossover study: both variants timed at each size
    assert [r["rocks"] for r in v["rows"]] == [2_000, 6_000]
    assert all(r["serial_ms"] > 0 and r["parallel_ms"] > 0 for r in v["rows"])
    costs = v["task_costs"]  # what a task costs from Python: three sizes, three kinds of loop, an empty kernel
    assert [r["items"] for r in costs["rows"]] == [1_000, 10_000, 100_000] and costs["empty_us"] > 0
    assert all(r[k] > 0 for r in costs["rows"] for k in ("parallel_us", "serial_us", "four_parallel_us"))
    md = (tmp_path / "frame.md").read_text()
    assert frame_table(saved)[0] in md and "## The step's tasks" in md and live_lines(saved)[0] in md
    assert "## The variants' crossover" in md and "## What a task costs" in md
    with pytest.raises(FileExistsError, match="--overwrite"):
        run_frame_study(tmp_path, tiny=True, progress=False)


def test_the_crossover_between_the_measured_sizes():
    from taichi_rocks.bench.frame import crossover_of

    rows = lambda *g: [{"rocks": n, "serial_ms": 1.0 + x, "parallel_ms": 1.0} for n, x in g]
    assert crossover_of(rows((10, -0.5), (20, -0.1), (30, 0.3))) == 22  # gain -0.1 at 20, +0.3 at 30: a quarter on
    assert crossover_of(rows((10, -0.5), (20, -0.1))) is None  # the parallel variant never wins
    assert crossover_of(rows((10, 0.2), (20, 0.4))) == 0  # it always does
