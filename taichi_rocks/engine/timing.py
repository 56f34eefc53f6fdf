"""The engine's timing hook: how long each pass of a step takes, measured by the step itself.

``Simulation(scene, timer=PassTimer())`` (or ``sim.timer = PassTimer()``) makes every step time its passes
("rock pass", "hash + tires", "reorder", "origin shift", "coast", "tire pass", "vehicles + rays") with
``ti.sync()`` before and after each, so the figures are the passes' own wall time, not their asynchronous
launch. The default, :data:`NO_TIMER`, does nothing and costs one call per pass. The benchmark reads
:attr:`PassTimer.seconds`; it never replaces the engine's kernels.
"""

from __future__ import annotations

import contextlib
import time
from collections import defaultdict

import taichi as ti


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
