"""The engine's timing hook: how long each pass of a step takes, measured by the step itself.

``Simulation(scene, timer=PassTimer())`` (or ``sim.timer = PassTimer()``) makes every step time its passes
("rock pass", "hash + tires", "reorder", "origin shift", "coast", "tire pass", "active step", "batch upload",
"vehicles + rays": the host side of the step) with ``ti.sync()`` before and after each, so the figures are
the passes' own wall time, not their asynchronous launch. The default, :data:`NO_TIMER`, does nothing and
costs one call per pass. The benchmark reads :attr:`PassTimer.seconds`; it never replaces the engine's
kernels.

:func:`kernel_tasks` reads Taichi's kernel profiler (a process started with ``init_taichi(...,
profiler=True)``): every offloaded task of every launch since :func:`clear_kernel_tasks`, as (kernel, task
index, kind, milliseconds) records; a task of kind "serial" runs on one thread, any other ("range_for", ...)
is a parallel loop (on the CPU backend each one wakes the thread pool and waits for it).
"""

from __future__ import annotations

import contextlib
import re
import time
from collections import defaultdict
from typing import NamedTuple

import taichi as ti
from taichi.lang import impl


class PassTimer:
    """Accumulates seconds and calls per pass name; :meth:`ms_per_step` averages them over steps."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)

    @contextlib.contextmanager
    def __call__(self, name: str):
        ti.sync()
        t = time.perf_counter()
        try:
            yield
        finally:
            ti.sync()
            self.seconds[name] += time.perf_counter() - t
            self.calls[name] += 1

    def reset(self) -> None:
        self.seconds.clear()
        self.calls.clear()

    def ms_per_step(self, steps: int) -> dict[str, float]:
        return {k: 1e3 * v / max(int(steps), 1) for k, v in self.seconds.items()}


class _NoTimer:
    """Times nothing."""

    _null = contextlib.nullcontext()

    def __call__(self, name: str):
        return self._null


NO_TIMER = _NoTimer()


class TaskRecord(NamedTuple):
    """One offloaded task of one launch: its kernel's name, its index in the kernel, its kind ("serial" or a
    parallel loop's: "range_for", ...) and its time (ms)."""

    kernel: str
    task: int
    kind: str
    ms: float


_TASK_NAME = re.compile(r"^(?P<kernel>.+?)_c\d+_\d+_kernel_(?P<task>\d+)_(?P<kind>[a-z_]+)$")


def clear_kernel_tasks() -> None:
    """Forget the kernel profiler's records so far."""
    ti.profiler.clear_kernel_profiler_info()


def kernel_tasks() -> list[TaskRecord]:
    """The kernel profiler's records since the last clear, in launch order."""
    prog = impl.get_runtime().prog
    prog.sync_kernel_profiler()
    prog.update_kernel_profiler()
    out = []
    for r in prog.get_kernel_profiler_records():
        m = _TASK_NAME.match(r.name)
        if m:
            out.append(TaskRecord(m["kernel"], int(m["task"]), m["kind"], float(r.kernel_time)))
    return out
