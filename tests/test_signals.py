"""SIGTERM and SIGHUP end `simulate`, `render`, `export` (usd, ply) and `sweep` as Ctrl-C does: every temporary
removed (and the folders the command made), one line saying which signal, no traceback, exit 128 + the signal's
number (143, 129).

Each command runs twice at once, one for each signal; the signal is sent once the process shows it is working
(its temporaries are growing on disk, or a sweep's first run's row is written: the sweep then holds there,
tests/held_sweep.py), never after a sleep alone."""

import signal
import subprocess
from pathlib import Path

import pytest

from cli_util import reaped, start_cli, start_held_sweep, wait_for

ROOT = Path(__file__).resolve().parents[1]
MINIMAL = ROOT / "scenes" / "minimal.toml"
SIGNALS = (signal.SIGTERM, signal.SIGHUP)


def _bytes_in(folder: Path) -> int:
    total = 0
    for q in folder.rglob("*") if folder.is_dir() else ():
        try:
            total += q.stat().st_size if q.is_file() else 0
        except FileNotFoundError:
            pass
    return total


def _growing(folder: Path, proc) -> None:
    """Wait until something under ``folder`` holds bytes, then until it holds more (the run is writing)."""
    wait_for(lambda: _bytes_in(folder) > 0, proc, poll=0.02)
    first = _bytes_in(folder)
    wait_for(lambda: _bytes_in(folder) > first, proc, poll=0.02)


def _ended_by(proc, signum) -> None:
    proc.send_signal(signum)
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    assert proc.returncode == 128 + signum, (proc.returncode, err)
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("sweep: ")]  # a sweep's count said first
    assert "Traceback" not in err and len(lines) == 1, err
    assert "interrupted" in lines[0] and signal.Signals(signum).name in lines[0], err


def _each_signal(tmp_path, args_for, ready, kept=lambda p: False):
    """Start the command of ``args_for(root)`` once per signal (in the folder ``tmp_path/<signal>``), wait for
    ``ready(root, proc)``, send the signal; nothing is left under either folder but what ``kept`` accepts."""
    roots = {s: tmp_path / signal.Signals(s).name for s in SIGNALS}
    for root in roots.values():
        root.mkdir()
    procs = {s: start_cli(*args_for(roots[s])) for s in SIGNALS}
    with reaped(procs[SIGNALS[0]]), reaped(procs[SIGNALS[1]]):
        for s in SIGNALS:
            ready(roots[s], procs[s])
            _ended_by(procs[s], s)
    for s, root in roots.items():
        left = [p for p in root.rglob("*") if not kept(p.relative_to(root))]
        assert left == [], (signal.Signals(s).name, left)


def test_simulate(tmp_path):
    _each_signal(tmp_path, lambda root: ("simulate", MINIMAL, "--out", root / "new" / "x.npz", "--frames", 100000),
                 lambda root, p: _growing(root, p))


def test_render(tmp_path):
    """The partial video removed; the finished frames and the saved states kept, to resume from (as after
    Ctrl-C)."""
    def ready(root, p):
        wait_for(lambda: any(q.name.startswith(".minimal.partial") for q in (root / "out").glob(".*")), p)

    def kept(rel):
        return rel.parts[:2] in (("out",), ("out", "frames"), ("out", ".resume")) and ".partial" not in rel.name

    _each_signal(tmp_path, lambda root: ("render", MINIMAL, "--out", root / "out", "--resolution", "160x96",
                                         "--frames", 100000), ready, kept)


@pytest.mark.parametrize("fmt", ["usd", "ply"])
def test_export(tmp_path, fmt):
    out = "x.usdc" if fmt == "usd" else "ply"
    _each_signal(tmp_path, lambda root: ("export", MINIMAL, "--format", fmt, "--out", root / "new" / out,
                                         "--frames", 100000, "--fps", 240), lambda root, p: _growing(root, p))


def test_sweep(tmp_path):
    """The signal to the driver alone (a terminal's hang-up reaches the workers too; they end with it): it stops
    its workers and keeps the finished rows, as after Ctrl-C (a sweep resumes), and says so."""
    sweep_dir = tmp_path / "sweep"
    sweep_dir.mkdir()
    (sweep_dir / "base.toml").write_text(MINIMAL.read_text())
    (sweep_dir / "sweep.toml").write_text('scene = "base.toml"\nseeds = [1, 2, 3, 4, 5, 6, 7, 8]\nduration = 2.0\n'
                                          '[grid]\n"launch.grip" = [1e5, 2e5]\n[measure]\nmetrics = ["launch"]\n')
    names = {s: signal.Signals(s).name for s in SIGNALS}
    # each driver holds after its first row (tests/held_sweep.py): the second cannot finish its 16 runs while
    # the first is being ended, however fast the machine
    procs = {s: start_held_sweep("row", tmp_path / f"{names[s]}.row", sweep_dir / "sweep.toml", "--out",
                                 tmp_path / names[s], "--workers", 1, "--threads", 1) for s in SIGNALS}
    with reaped(procs[SIGNALS[0]]), reaped(procs[SIGNALS[1]]):
        for s, p in procs.items():
            out = tmp_path / names[s]
            wait_for((tmp_path / f"{names[s]}.row").exists, p, poll=0.02)
            _ended_by(p, s)
            assert not list(out.rglob(".*")), list(out.rglob(".*"))  # no temporaries
            rows = (out / "results.csv").read_text().splitlines()
            assert len(rows) == 2, rows  # the header and the finished run
