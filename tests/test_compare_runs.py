"""tools/compare_runs.py, the frame-by-frame comparison of two runs (CPU against CUDA on a GPU machine): known
answers on small synthetic runs, and its exit statuses from the command line."""

import importlib.util
import subprocess
import sys

import numpy as np
import pytest

from cli_util import ROOT

spec = importlib.util.spec_from_file_location("compare_runs", ROOT / "tools" / "compare_runs.py")
compare_runs = importlib.util.module_from_spec(spec)
spec.loader.exec_module(compare_runs)


def _run(frames=6, rocks=50, seed=0):
    rng = np.random.default_rng(seed)
    pos = np.cumsum(rng.normal(0, 0.1, (frames, rocks, 3)), axis=0) + 10.0
    return {"positions": pos, "phase": np.zeros((frames, rocks), np.int8), "launches": np.arange(frames),
            "time": np.arange(frames) / 60.0, "dt": np.float64(1 / 240)}


def test_identical_runs_agree():
    a = _run()
    res = compare_runs.compare(a, {k: np.copy(v) for k, v in a.items()})
    assert res["same"] and res["first"] is None
    assert all(r["beyond_tol"] == r["over_1m"] == r["phase"] == 0 for r in res["frames"])


def test_round_off_is_allowed_and_a_moved_rock_is_found():
    a = _run()
    b = {k: np.copy(v) for k, v in a.items()}
    b["positions"] = b["positions"] + 1e-7  # far under one ulp a step of a 10 m coordinate over 20 steps
    assert compare_runs.compare(a, b)["same"]
    b["positions"][3:, 7] += [0.0, 2.0, 0.0]  # rock 7 elsewhere from frame 3 on
    b["phase"][4, 9] = 1
    res = compare_runs.compare(a, b)
    assert not res["same"] and res["first"]["frame"] == 3 and [r[0] for r in res["first"]["rocks"]] == [7]
    assert [r["over_1m"] for r in res["frames"]] == [0, 0, 0, 1, 1, 1]
    assert [r["phase"] for r in res["frames"]] == [0, 0, 0, 0, 1, 0]
    assert "first frame where they part: 3" in compare_runs.report(res, 1)


def test_runs_that_differ_only_in_launches_or_only_in_phases_differ():
    """Positions to the bit, yet not the same runs: a launch counted in another frame, a rock in another phase."""
    a = _run()
    launches = {k: np.copy(v) for k, v in a.items()}
    launches["launches"][4] += 1
    res = compare_runs.compare(a, launches)
    assert not res["same"] and res["first"]["frame"] == 4 and res["first"]["rocks"] == []
    assert "first frame where they part: 4 (launches 4/5" in compare_runs.report(res, 1)
    phase = {k: np.copy(v) for k, v in a.items()}
    phase["phase"][2, 11] = 2
    res = compare_runs.compare(a, phase)
    assert not res["same"] and res["first"]["frame"] == 2 and [r[0] for r in res["first"]["rocks"]] == [11]
    assert [r["phase"] for r in res["frames"]] == [0, 0, 1, 0, 0, 0]


def test_runs_without_rocks_compare():
    a = _run(rocks=0)
    assert compare_runs.compare(a, {k: np.copy(v) for k, v in a.items()})["same"]
    b = {k: np.copy(v) for k, v in a.items()}
    b["launches"][1] = 7
    assert not compare_runs.compare(a, b)["same"]


def test_other_frames_are_refused():
    a = _run()
    with pytest.raises(ValueError):
        compare_runs.compare(a, _run(frames=5))


def test_the_command_says_whether_runs_agree(tmp_path):
    a, b = _run(), _run()
    b["positions"][2, 0] += 5.0
    for name, run in (("a", a), ("b", b)):
        np.savez(tmp_path / f"{name}.npz", **run)
    tool = [sys.executable, str(ROOT / "tools" / "compare_runs.py")]
    same = subprocess.run(tool + [str(tmp_path / "a.npz"), str(tmp_path / "a.npz")], capture_output=True, text=True)
    assert same.returncode == 0 and "agree to round-off" in same.stdout
    differ = subprocess.run(tool + [str(tmp_path / "a.npz"), str(tmp_path / "b.npz")], capture_output=True, text=True)
    assert differ.returncode == 1 and "first frame where they part: 2" in differ.stdout


def _tool(name, *args, cwd=None):
    return subprocess.run([sys.executable, str(ROOT / "tools" / name), *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, timeout=300)


def _one_line(r, *words):
    assert r.returncode == 2, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert "Traceback" not in r.stderr and len(lines) <= 2, r.stderr  # argparse: its usage line, then the error
    for w in words:
        assert w in lines[-1], lines[-1]


def test_compare_runs_refuses_bad_input_in_one_line(tmp_path):
    good = tmp_path / "a.npz"
    np.savez(good, **_run())
    (tmp_path / "text.npz").write_text("not a run\n")
    np.savez(tmp_path / "partial.npz", positions=np.zeros((2, 3, 3)), time=np.zeros(2))
    np.savez(tmp_path / "flat.npz", **{**_run(), "positions": np.zeros((6, 150))})
    _one_line(_tool("compare_runs.py", tmp_path / "missing.npz", good), "missing.npz: cannot be read",
              "No such file")
    _one_line(_tool("compare_runs.py", good, tmp_path / "text.npz"), "text.npz: cannot be read")
    _one_line(_tool("compare_runs.py", good, tmp_path / "partial.npz"), "partial.npz: not a --layout full run",
              "no phase, launches, dt")
    _one_line(_tool("compare_runs.py", good, tmp_path / "flat.npz"), "flat.npz: positions has shape (6, 150)")
    for tol in ("nan", "inf", "-1", "x"):
        _one_line(_tool("compare_runs.py", good, good, "--tol", tol), "--tol")
    _one_line(_tool("compare_runs.py", good, good, "--every", "0"), "--every")
    with pytest.raises(ValueError, match="--tol must be a finite distance"):
        compare_runs.compare(_run(), _run(), float("nan"))


def test_nudge_refuses_bad_input_in_one_line(tmp_path):
    minimal = ROOT / "scenes" / "minimal.toml"
    _one_line(_tool("nudge.py", tmp_path / "missing.toml"), "missing.toml: cannot read scene")
    for by in ("nan", "inf", "-1e-6"):
        _one_line(_tool("nudge.py", minimal, "--by", by), "--by")
    _one_line(_tool("nudge.py", minimal, "--steps", "-5"), "--steps")


def test_nudge_counts_the_rocks_that_part(taichi_cpu):
    """tools/nudge.py: the same run twice is the same (nothing apart); a 1e-6 m nudge of every rock leaves nearly
    every rock where it was (the minimal scene, 60 steps)."""
    spec = importlib.util.spec_from_file_location("nudge", ROOT / "tools" / "nudge.py")
    nudge = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(nudge)
    scene = str(ROOT / "scenes" / "minimal.toml")
    same = nudge.summary(nudge.run(scene, 60, 0.0))
    assert same["over_1mm"] == same["over_1m"] == 0 and same["max"] == 0.0 and same["rocks"] > 0
    moved = nudge.summary(nudge.run(scene, 60, 1e-6))
    assert moved["launches"][0] > 0
    assert 0.0 < moved["max"] and moved["over_1m"] <= 0.01 * moved["rocks"]
