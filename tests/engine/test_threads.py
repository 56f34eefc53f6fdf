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
