"""Output places: checked before any work starts, refused in one line saying what was expected (an empty
--out, a file where a folder must be, a link to a folder for PLY frames is a folder), and a PLY export into an
existing folder writes into it, file by file, keeping the folder itself (its inode and permissions)."""

import os
import stat
from pathlib import Path

import pytest

from cli_util import cli_here, refused

ROOT = Path(__file__).resolve().parents[2]
MINIMAL = ROOT / "scenes" / "minimal.toml"
COMMANDS = {"simulate": ("simulate", "x.npz"), "render": ("render", "out"), "usd": ("export", "x.usdc"),
            "ply": ("export", "ply"), "sweep": ("sweep", "out")}


def _args(kind, out, sweep=None):
    command, _ = COMMANDS[kind]
    first = MINIMAL if command != "sweep" else sweep
    extra = ("--format", kind) if command == "export" else ()
    return (command, first, "--out", out, *extra)


def test_bad_places_are_refused_before_anything_runs_saying_what_was_expected(capsys, tmp_path):
    """An empty --out (it meant the current folder: render wrote its video there) and a file where a folder of the
    path must be (it said only "[Errno 17] File exists", after Taichi had started): one line, exit 2."""
    blocker = tmp_path / "afile"
    blocker.write_text("mine")
    sweep = tmp_path / "sw" / "sweep.toml"
    sweep.parent.mkdir()
    sweep.write_text(f'scene = "{MINIMAL}"\n[grid]\n"launch.grip" = [1e5]\n')
    for kind, (command, name) in COMMANDS.items():
        expected = {"simulate": "an .npz file name", "usd": "a .usdc file name"}.get(kind, "a folder name")
        refused(cli_here(capsys, *_args(kind, "", sweep)), "--out: an empty name", expected)
        refused(cli_here(capsys, *_args(kind, blocker / "sub" / name, sweep)), f"{blocker}: is a file, expected a folder")
    refused(cli_here(capsys, "simulate", MINIMAL, "--out", tmp_path / "x.npz", "--impacts", ""), "--impacts",
            "a .csv file name")
    refused(cli_here(capsys, "simulate", MINIMAL, "--out", tmp_path / "x.npz", "--impacts", blocker / "x.csv"),
            "expected a folder")
    assert sorted(os.listdir(tmp_path)) == ["afile", "sw"] and blocker.read_text() == "mine"
    assert os.listdir(tmp_path / "sw") == ["sweep.toml"]


def test_ply_into_an_existing_folder_keeps_it(taichi_cpu, capsys, tmp_path):
    """The folder keeps its inode and mode (2750 stays 2750; it became a new 755 folder); --overwrite with fewer
    frames leaves only the new ones."""
    folder = tmp_path / "frames"
    folder.mkdir()
    os.chmod(folder, 0o2750)
    before = folder.stat()
    r = cli_here(capsys, "export", MINIMAL, "--format", "ply", "--out", folder, "--frames", 3)
    assert r.returncode == 0, r.stderr
    after = folder.stat()
    assert (after.st_ino, stat.S_IMODE(after.st_mode)) == (before.st_ino, 0o2750)
    assert sorted(os.listdir(folder)) == [f"frame_0000{i}.ply" for i in range(3)]
    r = cli_here(capsys, "export", MINIMAL, "--format", "ply", "--out", folder, "--frames", 2, "--overwrite")
    assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(folder)) == [f"frame_0000{i}.ply" for i in range(2)]
    assert folder.stat().st_ino == before.st_ino


def test_ply_into_a_link_to_a_folder(taichi_cpu, capsys, tmp_path):
    """The link stays a link and the frames go into its folder (it failed with NotADirectoryError after the
    whole simulation)."""
    target = tmp_path / "target"
    target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target, target_is_directory=True)
    r = cli_here(capsys, "export", MINIMAL, "--format", "ply", "--out", link, "--frames", 2)
    assert r.returncode == 0, r.stderr
    assert link.is_symlink() and sorted(os.listdir(target)) == ["frame_00000.ply", "frame_00001.ply"]
    assert sorted(os.listdir(tmp_path)) == ["link", "target"]


def test_a_failed_ply_export_leaves_the_earlier_frames(taichi_cpu, tmp_path, monkeypatch):
    """A writer failing mid-run (an --overwrite): the earlier frames as they were, no temporaries."""
    from taichi_rocks.app.export import export_scene
    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.output.ply import PlyWriter

    folder = tmp_path / "frames"
    folder.mkdir()
    for i in range(3):
        (folder / f"frame_0000{i}.ply").write_bytes(b"old")
    write = PlyWriter.write

    def failing(self, fr):
        if fr["frame"] == 2:
            raise OSError(28, "No space left on device")
        write(self, fr)

    monkeypatch.setattr(PlyWriter, "write", failing)
    with pytest.raises(OSError):
        export_scene(load_scene(MINIMAL), out=folder, fmt="ply", frames=4, overwrite=True, progress=False)
    assert sorted(os.listdir(folder)) == [f"frame_0000{i}.ply" for i in range(3)]
    assert all((folder / f"frame_0000{i}.ply").read_bytes() == b"old" for i in range(3))
