"""A full disk: `simulate` (both layouts) and `export` (USD, PLY) end with one line naming the output and the
cause, exit 1, and leave nothing (the full layout died of SIGBUS, exit 135, leaving its temporary folder; USD
printed 2-20 lines of pxr's internals).

The disk is a 1 MB tmpfs mounted for the test where the machine allows it (root, in a container that may
mount); elsewhere the writers are made to fail as a full disk fails them: the space reservation of the
memory-mapped files, each file write and pxr's save raise ENOSPC.

Those disks are full before the last file is begun; a disk that fills while the file written last is half
written (:class:`Quota`: the writes of a run counted, then the same run with room for all but half of that
file) leaves no partial file either: the run's .npz, a PLY export's last frame, a render's last PNG."""

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

        class Full(_OpenFile):

            def write(self, data):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self.f.name)

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


class Quota:
    """``builtins.open`` for the files under ``folder`` opened for writing: their writes add up, and the write
    that crosses ``budget`` bytes writes what fits, then fails with ENOSPC, as a disk filling up does (None: no
    budget, only counted). ``written``: bytes so far; ``last``: the file written last and its bytes."""

    def __init__(self, monkeypatch, folder: Path, budget=None):
        import builtins

        self.folder, self.budget, self.written, self.last = str(folder), budget, 0, (None, 0)
        real_open = builtins.open
        quota = self

        class Counted(_OpenFile):
            def __init__(self, f, name):
                super().__init__(f)
                self.name = name

            def write(self, data):
                data = memoryview(data).cast("B") if not isinstance(data, str) else data
                room = len(data) if quota.budget is None else max(quota.budget - quota.written, 0)
                n = self.f.write(data[:room])
                quota.written += n
                size = (quota.last[1] if quota.last[0] == self.name else 0) + n
                quota.last = (self.name, size)
                if n < len(data):
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self.name)
                return n

        def opening(file, mode="r", *args, **kwargs):
            f = real_open(file, mode, *args, **kwargs)
            mine = isinstance(file, (str, Path)) and str(file).startswith(quota.folder)
            return Counted(f, str(file)) if mine and any(c in mode for c in "wxa+") else f

        monkeypatch.setattr(builtins, "open", opening)


class _OpenFile:
    """A file object of ``open`` standing in for ``f``: what it does not say itself, ``f`` does."""

    def __init__(self, f):
        self.f = f

    def __getattr__(self, name):
        return getattr(self.f, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.f.close()


def _files(folder: Path) -> list:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


# what the command writes last: the .npz of the run (its rows of changes, streamed before, copied into it), the
# last frame's PLY file, the last frame's PNG (written by the render's encoder thread)
FINAL_WRITES = {"simulate": ("simulate", "x.npz", "--only", "all", "--frames", 40),
                "ply": ("export", "ply", "--format", "ply", "--frames", 12),
                "png": ("render", "r", "--format", "png", "--frames", 4, "--resolution", "96x64")}


@pytest.mark.parametrize("case", list(FINAL_WRITES))
def test_a_disk_that_fills_during_the_final_write_leaves_no_partial_file(taichi_cpu, capsys, monkeypatch, tmp_path,
                                                                          case):
    """The run once with its writes counted, then again with room for all of them but half the file written
    last: one line naming it, exit 1, and no partial file (the .npz and the PLY folder are not there at all; the
    render keeps its finished frames for --resume, each whole, and no temporary)."""
    command, name, *flags = FINAL_WRITES[case]
    counted = Quota(monkeypatch, tmp_path / "a")
    (tmp_path / "a").mkdir()
    assert cli_here(capsys, command, MINIMAL, "--out", tmp_path / "a" / name, *flags).returncode == 0
    full, (last, size) = counted.written, counted.last
    assert size > 1000, (last, size)
    Quota(monkeypatch, tmp_path / "b", budget=full - size // 2)
    (tmp_path / "b").mkdir()
    out = tmp_path / "b" / name
    r = cli_here(capsys, command, MINIMAL, "--out", out, *flags)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(out) in lines[0] and "No space left on device" in lines[0], r.stderr
    left = _files(tmp_path / "b")
    if case == "png":
        frames = sorted((out / "frames").glob("*.png"))
        assert [p.name for p in frames] == [f"frame_{k:05d}.png" for k in range(len(frames))] and len(frames) == 3
        for p in frames:
            assert p.read_bytes() == (tmp_path / "a" / name / "frames" / p.name).read_bytes()
        assert not [f for f in left if Path(f).name.startswith(".") and "resume" not in f], left
    else:
        assert left == [], left
