"""What a task of a Taichi kernel costs from Python on this backend (``bench --only frame``): a loop adding 1 to a
field, parallel, serial and as four parallel loops in one kernel, and an empty kernel. On the CPU backend a
parallel task wakes the thread pool and waits for it; these figures are why a step's loops run serially on a few
cores (engine/loops.py, engine/variant.py). The kernels are the study's own, on a field of its own."""

import time

import numpy as np
import taichi as ti

from ..engine.runtime import threads_in_use
from ..engine.trees import FieldTrees

__all__ = ["measure_task_costs"]


@ti.kernel
def _add_parallel(f: ti.template(), n: ti.i32):
    for i in range(n):
        f[i] += 1


@ti.kernel
def _add_serial(f: ti.template(), n: ti.i32):
    ti.loop_config(serialize=True)
    for i in range(n):
        f[i] += 1


@ti.kernel
def _add_four(f: ti.template(), n: ti.i32):
    for i in range(n):
        f[i] += 1
    for i in range(n):
        f[i] += 1
    for i in range(n):
        f[i] += 1
    for i in range(n):
        f[i] += 1


@ti.kernel
def _empty():
    pass


def measure_task_costs(sizes=(1_000, 10_000, 100_000), calls: int = 200) -> dict:
    """Per call (median of ``calls``, after a warm-up): a loop adding 1 to a field of each size, parallel, serial
    (``ti.loop_config(serialize=True)``) and as four parallel loops in one kernel, and an empty kernel."""
    trees = FieldTrees()  # owned, as every field of the package (engine/trees.py); retired when done
    f = trees.field(ti.i32, (max(sizes),))
    trees.finalize()

    def per_call(fn) -> float:
        fn()
        ti.sync()
        ts = []
        for _ in range(calls):
            t0 = time.perf_counter()
            fn()
            ti.sync()
            ts.append(time.perf_counter() - t0)
        return 1e6 * float(np.median(ts))

    rows = [{"items": n, "parallel_us": per_call(lambda: _add_parallel(f, n)),
             "serial_us": per_call(lambda: _add_serial(f, n)), "four_parallel_us": per_call(lambda: _add_four(f, n))}
            for n in sizes]
    out = {"rows": rows, "empty_us": per_call(_empty), "threads": threads_in_use()}
    trees.release()
    return out
