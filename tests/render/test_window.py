"""render/window.py: Dear ImGui's layout file. A render started in a folder that holds the user's own imgui.ini
leaves it as it was (ImGui, under GGUI, wrote its defaults over it), and writes none where there was none; the
viewer's layout goes to the per-user configuration folder (tests/render/test_view.py checks it with a window)."""

import os
from pathlib import Path

from cli_util import cli_here

ROOT = Path(__file__).resolve().parents[2]


def test_render_leaves_the_imgui_ini_of_its_folder_alone(taichi_cpu, tmp_path, monkeypatch, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "imgui.ini").write_bytes(b"[Window][Mine]\nPos=1,2\n")
    os.utime(mine / "imgui.ini", (1_000_000_000, 1_000_000_000))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    for cwd in (mine, tmp_path / "empty"):
        cwd.mkdir(exist_ok=True)
        monkeypatch.chdir(cwd)
        r = cli_here(capsys, "render", ROOT / "scenes" / "minimal.toml", "--out", tmp_path / "out" / cwd.name,
                     "--frames", 2, "--resolution", "64x48", "--format", "png")
        assert r.returncode == 0, r.stderr
    assert (mine / "imgui.ini").read_bytes() == b"[Window][Mine]\nPos=1,2\n"
    assert (mine / "imgui.ini").stat().st_mtime == 1_000_000_000
    assert os.listdir(tmp_path / "empty") == []
    assert not (tmp_path / "config").exists()  # a hidden window keeps no layout at all


def test_layout_file_is_per_user(monkeypatch, tmp_path):
    from taichi_rocks.render.window import layout_file

    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert layout_file() == tmp_path / "taichi-rocks" / "imgui.ini"
    monkeypatch.delenv("XDG_CONFIG_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert layout_file() == tmp_path / "home" / ".config" / "taichi-rocks" / "imgui.ini"
