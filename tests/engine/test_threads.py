"""The CPU thread pool's size (engine/runtime.py auto_threads): TAICHI_ROCKS_THREADS when set, else every core up
to AUTO_THREADS_MAX; a bad value is refused with the variable's name."""

import pytest

from taichi_rocks.engine import runtime


@pytest.mark.parametrize("cores, want", [(1, 1), (2, 2), (4, 4), (16, runtime.AUTO_THREADS_MAX), (None, 1)])
def test_every_core_up_to_the_cap(monkeypatch, cores, want):
    monkeypatch.delenv(runtime.THREADS, raising=False)
    monkeypatch.setattr(runtime.os, "cpu_count", lambda: cores)
    assert runtime.auto_threads() == want


def test_the_variable_wins_and_is_checked(monkeypatch):
    monkeypatch.setattr(runtime.os, "cpu_count", lambda: 16)
    monkeypatch.setenv(runtime.THREADS, " 12 ")
    assert runtime.auto_threads() == 12 and runtime.threads_set()
    for bad in ("0", "-3", "two", "1.5"):
        monkeypatch.setenv(runtime.THREADS, bad)
        with pytest.raises(ValueError, match="TAICHI_ROCKS_THREADS must be a whole number >= 1"):
            runtime.auto_threads()


def test_the_pool_taichi_gets_follows_the_variable():
    """Not only the helper: the CPU backend's pool, counted as the process's threads once Taichi has started
    (/proc/self/task), grows by exactly the difference of two values of the variable (1 and 5: 5 is more than
    AUTO_THREADS_MAX, never the engine's own choice), and the runtime reports the value."""
    import subprocess
    import sys

    from cli_util import ROOT, _env

    code = ("import os; from taichi_rocks.engine.runtime import init_taichi, threads_in_use; "
            "init_taichi('cpu'); print(len(os.listdir('/proc/self/task')), threads_in_use())")
    procs = {n: subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env=_env(**{runtime.THREADS: n}),
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for n in (1, 5)}
    counts = {}
    for n, p in procs.items():
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err
        counts[n] = [int(x) for x in out.split()]
    assert [c[1] for c in counts.values()] == [1, 5]
    assert counts[5][0] - counts[1][0] == 4


def test_the_parallel_scan_variable_is_checked(monkeypatch):
    from taichi_rocks.engine.world import PARALLEL_SCAN, scan_in_parallel

    for value, want in (("1", True), (" 0 ", False)):
        monkeypatch.setenv(PARALLEL_SCAN, value)
        assert scan_in_parallel() is want
    for bad in ("yes", "true", "2", "on"):
        monkeypatch.setenv(PARALLEL_SCAN, bad)
        with pytest.raises(ValueError, match=f'TAICHI_ROCKS_PARALLEL_SCAN must be "1" .* or "0" .*, got {bad!r}'):
            scan_in_parallel()


@pytest.mark.parametrize("name, bad", [("TAICHI_ROCKS_THREADS", "0"), ("TAICHI_ROCKS_THREADS", "abc"),
                                       ("TAICHI_ROCKS_PARALLEL_SCAN", "yes")])
def test_the_api_refuses_a_bad_variable_clearly(taichi_cpu, monkeypatch, name, bad):
    """Also in a process whose Taichi runs already (a bad value is not left to the next process to find)."""
    from scenes_util import scene
    from taichi_rocks.engine.simulation import Simulation

    monkeypatch.setenv(name, bad)
    with pytest.raises(ValueError, match=f"{name} must be .*, got {bad!r}"):
        Simulation(scene(rocks=20, radius=3.0))
