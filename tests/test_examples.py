"""The README's game loop and examples/game_loop.py run as written (on the small scene, fewer frames), and the
mirror they keep from ``changes()`` is the bed ``state()`` reads."""

import re
import runpy
import sys

import numpy as np
import pytest

from cli_util import ROOT

pytestmark = pytest.mark.usefixtures("taichi_cpu")


def test_the_readme_game_loop_keeps_the_bed():
    text = (ROOT / "README.md").read_text()
    block = re.search(r"## In a game loop\n\n```python\n(.*?)```", text, re.S)[1]
    assert 'scene_with(scene, {"sim.accuracy": "game"})' in block and "sim.changes()" in block
    small = block.replace("scenes/convoy.toml", str(ROOT / "scenes" / "minimal.toml")).replace(
        "range(1, 601)", "range(1, 31)")
    assert small.count("minimal.toml") == 1 and "range(1, 31)" in small
    env: dict = {}
    exec(compile(small, "README.md", "exec"), env)
    sim, st = env["sim"], env["sim"].state()
    assert sim.dt == pytest.approx(1 / 60) and sim.step_count == 30
    assert np.array_equal(env["positions"], st["positions"]) and np.array_equal(env["phase"], st["phase"])


def test_the_game_loop_example(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["game_loop.py", str(ROOT / "scenes" / "minimal.toml"), "--frames", "20"])
    with pytest.raises(SystemExit) as done:
        runpy.run_path(str(ROOT / "examples" / "game_loop.py"), run_name="__main__")
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert "20 frames at 60 Hz" in out and "the mirror matches state() exactly" in out
    for part in ("advance_to", "impacts", "changes", "frame"):
        assert re.search(rf"{part}: median [0-9.]+ ms, p95 [0-9.]+ ms", out), part
