"""The command line's options and exits not covered by tests/test_cli.py, run in this process
(``taichi_rocks.cli.main`` returns the exit status; Taichi is started once, the minimal scene's kernels compile
once): --seed on every command, default output paths, ``simulate --out DIR``, ``render --profile``,
``view --quit-after`` / ``--record --overwrite`` (up to the window), ``bench --quick`` and ``--only``, exit status 1
for the runtime guard and TAICHI_ROCKS_DEBUG. The window itself: tests/render/test_view_controls.py."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cli_util import ROOT

MINIMAL = ROOT / "scenes" / "minimal.toml"
FRAMES = 6  # 0.2 s of the minimal scene: rocks are launched from frame 2 on


def run(capsys, *args):
    """``taichi-rocks ARGS`` in this process: (exit status, stdout lines, stderr lines); argparse's own errors
    (it exits) give their status too."""
    from taichi_rocks.cli import main

    try:
        status = main([str(a) for a in args])
    except SystemExit as e:
        status = e.code
    out, err = capsys.readouterr()
    return status, out.strip().splitlines(), err.strip().splitlines()


def refused(capsys, *args) -> str:
    """Bad input: exit status 2, one line on stderr, no traceback. Returns the line."""
    status, _, err = run(capsys, *args)
    assert status == 2 and len(err) == 1 and "Traceback" not in err[0], (status, err)
    return err[0]


@pytest.fixture
def in_tmp(tmp_path, monkeypatch):
    """A fresh current folder (default outputs go to renders/ under it)."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


# ---------------------------------------------------------------------------------------------- --seed
def test_simulate_seed_changes_the_run_and_is_recorded(taichi_cpu, capsys, tmp_path):
    from taichi_rocks import load_run

    for name, seed in (("a", None), ("b", 7), ("c", 7)):
        status, out, err = run(capsys, "simulate", MINIMAL, "--out", tmp_path / f"{name}.npz", "--frames", FRAMES,
                               *(["--seed", seed] if seed is not None else []))
        assert status == 0 and out[0].startswith(f"wrote {tmp_path / name}.npz: {FRAMES} frames"), (out, err)
    a, b = load_run(tmp_path / "a.npz"), load_run(tmp_path / "b.npz")
    assert int(a["seed"]) == 1 and int(b["seed"]) == 7  # the scene's seed, or the one given
    assert np.abs(a["positions"][0] - b["positions"][0]).max() > 0.1  # another bed from the first frame on
    assert not np.array_equal(a["launches"], b["launches"]) or not np.array_equal(a["radii"], b["radii"])
    assert (tmp_path / "b.npz").read_bytes() == (tmp_path / "c.npz").read_bytes()  # and the same seed, the same run


def test_export_seed_changes_the_stage_and_is_recorded(taichi_cpu, capsys, tmp_path):
    from pxr import Usd, UsdGeom

    stages = {}
    for name, seed in (("a", None), ("b", 7)):
        out = tmp_path / f"{name}.usdc"
        status, _, err = run(capsys, "export", MINIMAL, "--out", out, "--frames", 2,
                             *(["--seed", seed] if seed is not None else []))
        assert status == 0, err
        stages[name] = Usd.Stage.Open(str(out))
    assert [stages[k].GetRootLayer().customLayerData["seed"] for k in "ab"] == [1, 7]
    pos = {k: np.array(UsdGeom.PointInstancer(s.GetPrimAtPath("/World/Bed/Rocks")).GetPositionsAttr().Get(0))
           for k, s in stages.items()}
    assert pos["a"].shape == pos["b"].shape and np.abs(pos["a"] - pos["b"]).max() > 0.1
    # PLY frames hold no seed; the seed still decides them
    for name, seed in (("pa", None), ("pb", 7)):
        assert run(capsys, "export", MINIMAL, "--format", "ply", "--out", tmp_path / name, "--frames", 1,
                   *(["--seed", seed] if seed is not None else []))[0] == 0
    assert (tmp_path / "pa" / "frame_00000.ply").read_bytes() != (tmp_path / "pb" / "frame_00000.ply").read_bytes()


def test_check_shows_the_seed_a_run_would_use(capsys, tmp_path):
    """`check` runs nothing (it has no --seed); its summary names the scene's seed."""
    scene = tmp_path / "seeded.toml"
    scene.write_text(MINIMAL.read_text().replace('name = "minimal"', 'name = "seeded"\nseed = 9'))
    status, out, _ = run(capsys, "check", MINIMAL, scene)
    assert status == 0
    heads = [line for line in out if line.startswith("scene ")]
    assert heads[0].endswith(", seed 1") and heads[1].endswith(", seed 9"), heads


@pytest.mark.parametrize("command", ["simulate", "export", "render", "view"])
def test_a_negative_seed_is_refused_before_anything(taichi_cpu, capsys, tmp_path, command):
    out = [] if command == "view" else ["--out", tmp_path / ("o.npz" if command == "simulate" else
                                                             "o.usdc" if command == "export" else "o")]
    line = refused(capsys, command, MINIMAL, "--seed", -1, *out)
    assert line == f"{MINIMAL}: seed: must be >= 0, got -1"
    assert list(tmp_path.iterdir()) == []


def test_render_seed_profile_and_default_folder(taichi_cpu, capsys, in_tmp, monkeypatch):
    """One real render (2 frames, 160x96, PNG, no --out): its simulation is the seeded one, the frames go to
    renders/<scene>/frames/, and --profile prints every stage's seconds."""
    from taichi_rocks.app import render as app_render
    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.render.stages import STAGES

    seen = []

    class Seen(Simulation):  # what the render simulates (only numbers kept: the World goes with the render)
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            seen.append((self.scene.seed, self.state()["positions"]))

    monkeypatch.setattr(app_render, "Simulation", Seen)
    status, out, err = run(capsys, "render", MINIMAL, "--seed", 5, "--profile", "--frames", 2, "--resolution",
                           "160x96", "--format", "png")
    assert status == 0, err
    folder = Path("renders") / "minimal"
    assert sorted(p.name for p in (in_tmp / folder / "frames").iterdir()) == ["frame_00000.png", "frame_00001.png"]
    assert sorted(p.name for p in in_tmp.rglob("*")) == sorted(["renders", "minimal", "frames", "frame_00000.png",
                                                                 "frame_00001.png", "profile.json"])
    assert out[0].startswith(f"wrote {folder / 'frames'}: 2 frames at ")
    profile = {line.split()[0]: float(line.split()[1]) for line in out[1:]}
    assert all(line.endswith(" s") for line in out[1:]), out
    assert set(profile) == {"simulation", *STAGES, "encoding", "encoding_busy", "other", "setup", "resume_replay",
                            "first_frame"}, out
    assert all(v >= 0 for v in profile.values())
    loop = sum(profile[k] for k in ("simulation", *STAGES, "encoding", "other"))
    assert profile["first_frame"] <= loop + 0.05  # the first frame is part of the loop the shares divide
    assert profile["resume_replay"] == 0.0
    saved = json.loads((in_tmp / folder / "profile.json").read_text())  # the same figures, and the run's machine
    assert saved["frames"] == 2 and saved["scene"] == "minimal" and saved["machine"]["taichi_arch"] == "cpu"
    assert all(abs(saved["profile"][k] - v) < 0.006 for k, v in profile.items())
    assert set(saved["profile_cpu"]) == {"simulation", *STAGES, "loop"}
    assert 0 < sum(saved["profile_cpu"][k] for k in ("simulation", *STAGES)) <= saved["profile_cpu"]["loop"] + 0.01
    [(seed, positions)] = seen
    assert seed == 5
    # the render's Simulation is gone: its World serves the two below
    scene = load_scene(MINIMAL)
    np.testing.assert_array_equal(positions, Simulation(scene, seed=5).state()["positions"])
    assert np.abs(positions - Simulation(scene).state()["positions"]).max() > 0.1


def test_render_without_profile_prints_only_what_it_wrote(taichi_cpu, capsys, tmp_path, monkeypatch):
    from taichi_rocks.app import render as app_render

    calls = []

    def fake(scene, **kwargs):
        calls.append((scene, kwargs))
        return {"frames_dir": str(kwargs["out_dir"] / "frames"), "frames": 3, "fps_measured": 2.5,
                "profile": {"simulation": 1.0}} if kwargs["profile"] else {"frames_dir": "f", "frames": 3}

    monkeypatch.setattr(app_render, "render_scene", fake)
    status, out, _ = run(capsys, "render", MINIMAL, "--out", tmp_path / "r", "--frames", 3)
    assert status == 0 and out == ["wrote f: 3 frames at 0.00 frames/s"], out
    (scene, kwargs), = calls
    assert kwargs["profile"] is False and kwargs["out_dir"] == tmp_path / "r" and scene.seed == 1
    status, out, _ = run(capsys, "render", MINIMAL, "--out", tmp_path / "r", "--profile")
    assert out[1:] == ["  simulation       1.00 s"], out


# ---------------------------------------------------------------------------------------------- view, up to the window
@pytest.fixture
def fake_window(monkeypatch):
    """``view`` with a display found and the window replaced by a record of what it was asked."""
    from taichi_rocks.app import view as app_view
    from taichi_rocks.render import display

    calls = []

    def view_scene(scene, **kwargs):
        calls.append((scene, kwargs))
        return {"frames_shown": 4, "frame": 3, "screenshots": [], "recorded": 4 if kwargs["record"] else 0,
                "seconds": 1.25}

    monkeypatch.setattr(display, "display_problem", lambda: None)
    monkeypatch.setattr(app_view, "view_scene", view_scene)
    return calls


def test_view_hands_seed_quit_after_and_record_to_the_window(taichi_cpu, capsys, tmp_path, fake_window):
    rec = tmp_path / "rec"
    status, out, err = run(capsys, "view", MINIMAL, "--seed", 5, "--quit-after", 1.25, "--record", rec,
                           "--resolution", "320x180")
    assert status == 0, err
    (scene, kwargs), = fake_window
    assert scene.seed == 5 and kwargs["quit_after"] == 1.25 and kwargs["record"] == rec
    assert kwargs["resolution"] == (320, 180) and kwargs["overwrite"] is False
    assert out == [f"view: 4 frames shown in 1.2 s, 4 frames written to {rec}"], out
    run(capsys, "view", MINIMAL)
    assert fake_window[1][0].seed == 1 and fake_window[1][1]["quit_after"] is None  # no limit by default
    for bad in ("0", "-2", "nan", "soon"):
        status, _, err = run(capsys, "view", MINIMAL, "--quit-after", bad)
        assert status == 2 and "--quit-after" in err[-1], err
    assert len(fake_window) == 2


def test_view_overwrite_clears_the_old_frames_of_a_record_folder_first(taichi_cpu, capsys, tmp_path, monkeypatch,
                                                                       fake_window):
    """--record into a folder holding frames: refused without --overwrite (the window never opens); with it the
    old frames are removed before the window opens, other files kept."""
    rec = tmp_path / "rec"
    rec.mkdir()
    for k in range(3):
        (rec / f"frame_{k:05d}.png").write_bytes(b"old")
    (rec / "notes.txt").write_text("mine")
    line = refused(capsys, "view", MINIMAL, "--record", rec)
    assert line == f"taichi-rocks view: {rec} is not empty (pass --overwrite to replace its frames)"
    assert fake_window == [] and len(list(rec.iterdir())) == 4

    def check_empty(scene, **kwargs):
        assert sorted(p.name for p in rec.iterdir()) == ["notes.txt"]  # already when the window opens
        return {"frames_shown": 1, "frame": 0, "screenshots": [], "recorded": 1, "seconds": 0.1}

    from taichi_rocks.app import view as app_view

    monkeypatch.setattr(app_view, "view_scene", check_empty)
    status, _, err = run(capsys, "view", MINIMAL, "--record", rec, "--overwrite")
    assert status == 0, err
    (rec / "file").write_text("")
    line = refused(capsys, "view", MINIMAL, "--record", rec / "file", "--overwrite")
    assert line == f"taichi-rocks view: {rec / 'file'}: exists and is not a folder"


# ---------------------------------------------------------------------------------------------- default outputs
def test_default_outputs_go_under_renders_scene(taichi_cpu, capsys, in_tmp):
    from taichi_rocks import load_run

    status, out, err = run(capsys, "simulate", MINIMAL, "--frames", 2)
    npz = Path("renders") / "minimal" / "minimal.npz"
    assert status == 0 and out[0].startswith(f"wrote {npz}: "), (out, err)
    assert load_run(in_tmp / npz)["positions"].shape == (2, 2000, 3)
    status, out, _ = run(capsys, "export", MINIMAL, "--frames", 2)
    usd = Path("renders") / "minimal" / "minimal.usdc"
    assert status == 0 and out[0].startswith(f"wrote {usd}: ") and (in_tmp / usd).stat().st_size > 0
    status, out, _ = run(capsys, "export", MINIMAL, "--frames", 2, "--format", "ply")
    ply = Path("renders") / "minimal" / "ply"
    assert status == 0 and out[0].startswith(f"wrote {ply}: ")
    assert sorted(p.name for p in (in_tmp / ply).iterdir()) == ["frame_00000.ply", "frame_00001.ply"]
    assert sorted(p.name for p in (in_tmp / "renders" / "minimal").iterdir()) == ["minimal.npz", "minimal.usdc",
                                                                                  "ply"]
    assert sorted(p.name for p in in_tmp.iterdir()) == ["renders"]
    # again: the defaults are outputs like any other, refused unless --overwrite
    line = refused(capsys, "simulate", MINIMAL, "--frames", 2)
    assert line == f"taichi-rocks simulate: {npz}: exists; pass --overwrite to replace it"


def test_simulate_out_a_folder_is_refused_with_or_without_overwrite(taichi_cpu, capsys, tmp_path):
    """--out names the .npz file; a folder there is refused (before anything runs), and --overwrite does not
    change that (it once said "pass --overwrite", then refused the folder with it)."""
    folder = tmp_path / "runs"
    folder.mkdir()
    (folder / "kept.npz").write_bytes(b"mine")
    for extra in ([], ["--overwrite"]):
        line = refused(capsys, "simulate", MINIMAL, "--out", folder, "--frames", 2, *extra)
        assert line == f"taichi-rocks simulate: {folder}: is a directory, expected an .npz file name"
    assert [p.name for p in folder.iterdir()] == ["kept.npz"] and (folder / "kept.npz").read_bytes() == b"mine"
    usd = tmp_path / "stage.usdc"
    usd.mkdir()
    line = refused(capsys, "export", MINIMAL, "--out", usd, "--frames", 2, "--overwrite")
    assert line == f"taichi-rocks export: {usd}: is a directory, expected a .usdc file name"


# ---------------------------------------------------------------------------------------------- bench
@pytest.fixture
def studies(monkeypatch):
    """The bench's studies replaced by records of what the command line asked them (the folder checks and the
    folder making around them stay)."""
    from taichi_rocks.bench import activity, launch, run as bench_run

    calls = []

    def full(out, cfg, arch, progress, backend="local", address=None):
        calls.append(("all", {"out": out, "mode": cfg.mode, "arch": arch, "progress": progress, "backend": backend,
                              "address": address}))
        return {"report": str(out / "report.md")}

    def launch_study(out, quick, arch, progress, tiny):
        calls.append(("launch", {"out": out, "quick": quick, "arch": arch, "progress": progress, "tiny": tiny}))
        return {"report": str(out / "launch_study.md")}

    def activity_study(**kwargs):
        calls.append(("activity", kwargs))
        return {"report": str(Path(kwargs["out_dir"]) / "activity.md")}

    monkeypatch.setattr(bench_run, "_run_bench", full)
    monkeypatch.setattr(launch, "_launch_study", launch_study)
    monkeypatch.setattr(activity, "run_activity_study", activity_study)
    return calls


def test_bench_quick_and_only_reach_the_studies(taichi_cpu, capsys, tmp_path, studies):
    out = tmp_path / "b"
    cases = [([], ("all", {"mode": "full"})), (["--quick"], ("all", {"mode": "quick"})),
             (["--only", "launch"], ("launch", {"quick": False, "tiny": False})),
             (["--only", "launch", "--quick"], ("launch", {"quick": True, "tiny": False})),
             (["--only", "activity"], ("activity", {"quick": False})),
             (["--only", "activity", "--quick", "--overwrite"], ("activity", {"quick": True, "overwrite": True}))]
    for args, (study, want) in cases:
        status, lines, err = run(capsys, "bench", "--out", out, *args)
        assert status == 0, err
        name, got = studies[-1]
        assert name == study and {k: got[k] for k in want} == want, (args, got)
        report = {"all": "report.md", "launch": "launch_study.md", "activity": "activity.md"}[study]
        assert lines == [f"wrote {out / report}"]
        assert got.get("progress") is None and got.get("arch", "cpu") == "cpu"
        assert Path(got.get("out", got.get("out_dir"))) == out
    assert len(studies) == len(cases)
    assert studies[-1][1]["overwrite"] is True and studies[-2][1]["overwrite"] is False
    status, _, err = run(capsys, "bench", "--out", out, "--only", "launch", "--arch", "vulkan")  # f32 only: allowed
    assert status == 0 and studies[-1][1]["arch"] == "vulkan", err
    status, _, err = run(capsys, "bench", "--only", "speed")
    assert status == 2 and "--only" in err[-1] and len(studies) == len(cases) + 1


def test_bench_default_folder_is_renders_bench(taichi_cpu, capsys, in_tmp, studies):
    assert run(capsys, "bench", "--quick")[0] == 0
    assert studies[-1][1]["out"] == Path("renders") / "bench" and (in_tmp / "renders" / "bench").is_dir()


# ---------------------------------------------------------------------------------------------- failures
@pytest.fixture
def sinking(monkeypatch):
    """From frame 2 on (t = 2/30 s), rock 5 is put half a metre into the ground after every advance: the
    runtime guard (Simulation.check_health, after every frame) must stop the run."""
    from taichi_rocks.engine.simulation import Simulation

    advance = Simulation.advance_to

    def advance_and_sink(self, t):
        advance(self, t)
        if t >= 2 / 30 - 1e-9:
            p = self.state()["positions"][5]
            self.set_rocks([5], positions=[p - [0.0, 0.0, 0.5]])

    monkeypatch.setattr(Simulation, "advance_to", advance_and_sink)


@pytest.mark.parametrize("command, name", [("simulate", "x.npz"), ("export", "x.usdc")])
def test_the_runtime_guard_exits_1_and_writes_nothing(taichi_cpu, capsys, tmp_path, sinking, command, name):
    out = tmp_path / "made" / name
    status, lines, err = run(capsys, command, MINIMAL, "--out", out, "--frames", FRAMES)
    assert status == 1 and len(err) == 1 and lines == [], (status, lines, err)
    assert re.match(rf"taichi-rocks {command}: simulation failed at step \d+ \(t = 0\.0667 s\): 1 rock\(s\) "
                    r"below the ground; first: rock 5 at position \[", err[0]), err  # frame 2, at 2/30 s
    z = float(err[0].split("at position [")[1].split("]")[0].split()[2])
    assert -0.5 < z < -0.45  # resting at its radius (2-5 cm) above the ground, moved 0.5 m down
    assert list(tmp_path.iterdir()) == []  # not even the folder it made


@pytest.fixture
def failing_check(monkeypatch):
    """``check`` meets an error nobody planned for (a bug): summarise divides by zero."""
    from taichi_rocks.config import scene

    def summarise(s, *args, **kwargs):
        return 1 / 0

    monkeypatch.setattr(scene, "summarise", summarise)


def test_an_unexpected_error_is_one_line_unless_debugging(capsys, monkeypatch, failing_check):
    monkeypatch.delenv("TAICHI_ROCKS_DEBUG", raising=False)
    status, _, err = run(capsys, "check", MINIMAL)
    assert status == 1 and err == ["taichi-rocks check: ZeroDivisionError: division by zero (set "
                                   "TAICHI_ROCKS_DEBUG=1 for details)"], err
    monkeypatch.setenv("TAICHI_ROCKS_DEBUG", "1")
    from taichi_rocks.cli import main

    with pytest.raises(ZeroDivisionError):  # raised on: the interpreter prints its traceback
        main(["check", str(MINIMAL)])
    monkeypatch.setenv("TAICHI_ROCKS_DEBUG", "")  # set but empty: not debugging
    assert run(capsys, "check", MINIMAL)[0] == 1


@pytest.mark.parametrize("debug", [False, True])
def test_taichi_rocks_debug_shows_the_traceback_of_python_m(tmp_path, debug):
    """The process as a user runs it (``python -m taichi_rocks``; the check command):
    the traceback reaches the terminal only with TAICHI_ROCKS_DEBUG set."""
    code = ("import runpy, sys; import taichi_rocks.config.scene as s; s.summarise = lambda scene, *a, **k: 1 / 0; "
            f"sys.argv = ['taichi-rocks', 'check', {str(MINIMAL)!r}]; runpy.run_module('taichi_rocks', "
            "run_name='__main__')")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("TAICHI_ROCKS_DEBUG", None)
    if debug:
        env["TAICHI_ROCKS_DEBUG"] = "1"
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, r.stderr
    lines = r.stderr.strip().splitlines()
    if debug:
        assert lines[0] == "Traceback (most recent call last):" and lines[-1] == "ZeroDivisionError: division by zero"
        assert any("summarise" in line or "lambda" in line for line in lines), lines
    else:
        assert lines == ["taichi-rocks check: ZeroDivisionError: division by zero (set TAICHI_ROCKS_DEBUG=1 for "
                         "details)"], lines
