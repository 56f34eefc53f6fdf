"""A full disk: `simulate` (both layouts) and `export` (USD, PLY) end with one line naming the output and the
cause, exit 1, and leave nothing (the full layout died of SIGBUS, exit 135, leaving its temporary folder; USD
printed 2-20 lines of pxr's internals).

The disk is a 1 MB tmpfs mounted for the test where the machine allows it (root, in a container that may
mount); elsewhere the writers are made to fail as a full disk fails them: the space reservation of the
memory-mapped files, each file write and pxr's save raise ENOSPC."""

import errno
import os
import subprocess
from pathlib import Path

import pytest

from cli_util import cli_here

ROOT = Path(__file__).resolve().parents[2]
MINIMAL = ROOT / "scenes" / "minimal.toml"


def _mount(folder: Path) -> bool:
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(folder)], capture_output=True)
    return r.returncode == 0


@pytest.fixture
def full_disk(tmp_path, monkeypatch):
    folder = tmp_path / "disk"
    folder.mkdir()
    mounted = _mount(folder)
    if not mounted:
        import builtins

        from taichi_rocks.output import npz

        def no_room(*args, **kwargs):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        monkeypatch.setattr(npz.os, "posix_fallocate", no_room)
        real_open = builtins.open

        class Full:
            def __init__(self, f):
                self.f = f

            def write(self, data):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self.f.name)

            def __getattr__(self, name):
                return getattr(self.f, name)

            def __enter__(self):
                return self

            def __exit__(self, *exc):
                self.f.close()

        def opening(file, mode="r", *args, **kwargs):
            f = real_open(file, mode, *args, **kwargs)
            return Full(f) if str(file).startswith(str(folder)) and ("w" in mode or "x" in mode) else f

        monkeypatch.setattr(builtins, "open", opening)
        try:
            from pxr import Sdf, Tf

            def save(self, *args):
                raise Tf.ErrorException("Error in 'WriteToAsset' at line 1 in file x.cpp : 'Error occurred writing "
                                        "file: No space left on device'")

            monkeypatch.setattr(Sdf.Layer, "Save", save)
        except ImportError:
            pass
    try:
        yield folder
    finally:
        if mounted:
            subprocess.run(["umount", str(folder)], check=True)


def _one_line(r, out):
    assert r.returncode == 1, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert f"{out}: " in lines[0] and "No space left on device" in lines[0], lines[0]
    assert "pxr" not in lines[0] and "ErrorException" not in lines[0], lines[0]


@pytest.mark.parametrize("how", [("simulate", "x.npz", "--layout", "full", "--frames", 200),
                                 ("simulate", "x.npz", "--only", "all", "--frames", 400),
                                 ("export", "x.usdc", "--frames", 60),
                                 ("export", "ply", "--format", "ply", "--frames", 60)],
                         ids=["full", "light", "usd", "ply"])
def test_a_full_disk_is_one_line_naming_the_output_and_leaves_nothing(taichi_cpu, capsys, full_disk, how):
    command, name, *flags = how
    out = full_disk / name
    _one_line(cli_here(capsys, command, MINIMAL, "--out", out, *flags), out)
    assert os.listdir(full_disk) == []
