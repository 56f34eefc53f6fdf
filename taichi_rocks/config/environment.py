"""The environment variables that steer the engine, read and checked here (no Taichi: the command line checks
them before it starts anything, engine/runtime.py and engine/world.py use them).

* ``TAICHI_ROCKS_THREADS``: the CPU backend's thread pool, a whole number >= 1 (unset or empty: the engine's
  choice, engine/runtime.py ``auto_threads``);
* ``TAICHI_ROCKS_PARALLEL_SCAN``: "1" or "0", the hash's prefix sum in parallel or not on any backend (unset or
  empty: in parallel off the CPU only, engine/world.py ``scan_in_parallel``);
* ``TAICHI_ROCKS_LOOPS``: "auto", "serial" or "parallel", how a step's loops run (unset or empty: "auto", the
  engine's choice, engine/variant.py).

Any other value is an error naming the variable (one line), never ignored.
"""

from __future__ import annotations

import os
from typing import Optional

__all__ = ["THREADS", "PARALLEL_SCAN", "LOOPS", "LOOP_CHOICES", "threads_wanted", "parallel_scan_wanted",
           "loops_wanted", "environment_problem"]

THREADS = "TAICHI_ROCKS_THREADS"
PARALLEL_SCAN = "TAICHI_ROCKS_PARALLEL_SCAN"
LOOPS = "TAICHI_ROCKS_LOOPS"
LOOP_CHOICES = ("auto", "serial", "parallel")


def _value(name: str) -> str:
    return os.environ.get(name, "").strip()


def threads_wanted() -> Optional[int]:
    """``TAICHI_ROCKS_THREADS`` as a number of threads, None when unset; ValueError naming it when it is not a
    whole number >= 1."""
    raw = _value(THREADS)
    if not raw:
        return None
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"{THREADS} must be a whole number >= 1, got {raw!r}")
    return n


def parallel_scan_wanted() -> Optional[bool]:
    """``TAICHI_ROCKS_PARALLEL_SCAN``: True for "1", False for "0", None when unset; ValueError naming it for any
    other value."""
    raw = _value(PARALLEL_SCAN)
    if not raw:
        return None
    if raw not in ("0", "1"):
        raise ValueError(f'{PARALLEL_SCAN} must be "1" (scan in parallel) or "0" (serially), got {raw!r}')
    return raw == "1"


def loops_wanted() -> str:
    """``TAICHI_ROCKS_LOOPS`` as one of :data:`LOOP_CHOICES` ("auto" when unset); ValueError naming it for any
    other value."""
    raw = _value(LOOPS).lower()
    if not raw:
        return "auto"
    if raw not in LOOP_CHOICES:
        raise ValueError(f"{LOOPS} must be one of {', '.join(LOOP_CHOICES)}, got {raw!r}")
    return raw


def environment_problem(threads: bool = True) -> Optional[str]:
    """The first bad value among these variables (``threads``: TAICHI_ROCKS_THREADS too), one line, or None."""
    for check in ((threads_wanted,) if threads else ()) + (parallel_scan_wanted, loops_wanted):
        try:
            check()
        except ValueError as e:
            return str(e)
    return None
