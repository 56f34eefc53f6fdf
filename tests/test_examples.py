"""The README's game loop and examples/game_loop.py run as written (on the small scene, fewer frames), and the
mirror they keep from ``changes()`` is the bed ``state()`` reads."""

import re
import runpy
import subprocess
import sys

import numpy as np
import pytest

from cli_util import ROOT

pytestmark = pytest.mark.usefixtures("taichi_cpu")


def test_the_readme_game_loop_keeps_the_bed(monkeypatch, tmp_path):
    """As written (the small scene, fewer frames), from a folder other than the repository's."""
    text = (ROOT / "README.md").read_text()
    block = re.search(r"## In a game loop\n\n```python\n(.*?)```", text, re.S)[1]
    assert 'scene_with(scene, {"sim.accuracy": "game"})' in block and "sim.changes()" in block
    small = block.replace('"convoy"', '"minimal"').replace("range(1, 601)", "range(1, 31)")
    assert small.count('"minimal"') == 1 and "range(1, 31)" in small
    monkeypatch.chdir(tmp_path)
    env: dict = {}
    exec(compile(small, "README.md", "exec"), env)
    sim, st = env["sim"], env["sim"].state()
    assert sim.dt == pytest.approx(1 / 60) and sim.step_count == 30
    assert np.array_equal(env["positions"], st["positions"]) and np.array_equal(env["phase"], st["phase"])


def test_shipped_scenes_are_found_from_any_folder(monkeypatch, tmp_path):
    from taichi_rocks import shipped_scene

    monkeypatch.chdir(tmp_path)
    assert shipped_scene("convoy") == ROOT / "scenes" / "convoy.toml"
    with pytest.raises(ValueError, match="name: no shipped scene 'konvoy' .*; the shipped scenes: .*convoy"):
        shipped_scene("konvoy")


def test_the_game_loop_example_wants_a_frame_to_time(capsys):
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "game_loop.py"), str(ROOT / "scenes" /
                        "minimal.toml"), "--frames", "1"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert "--frames: must be >= 2 (the first frame compiles and is not timed), got 1" in r.stderr


def test_the_game_loop_example(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["game_loop.py", str(ROOT / "scenes" / "minimal.toml"), "--frames", "20"])
    with pytest.raises(SystemExit) as done:
        runpy.run_path(str(ROOT / "examples" / "game_loop.py"), run_name="__main__")
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert "20 frames at 60 Hz" in out and "the mirror matches state() exactly" in out
    for part in ("advance_to", "impacts", "changes", "frame"):
        assert re.search(rf"{part}: median [0-9.]+ ms, p95 [0-9.]+ ms", out), part
