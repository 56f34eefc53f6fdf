"""Task functions for tests/app/test_runner.py, imported by the runner's worker processes."""

import os
import signal
import time


def task(t: dict) -> dict:
    """x > 0: a result; 0: an exception; -1: the worker kills itself; -2: a task that never ends."""
    x = t["x"]
    if x == 0:
        raise ValueError("no zero\nsecond line")
    if x == -1:
        os.kill(os.getpid(), signal.SIGKILL)
    if x == -2:
        time.sleep(600)
    return {"double": 2 * x, "pid": os.getpid(), "threads": os.environ.get("TAICHI_ROCKS_THREADS")}
