"""The choice of a step's variant (engine/loops.py): its loops serial on the launching thread, or parallel.

Made on the host from what the engine knows without reading the device inside a step: the backend, the CPU
thread pool's size and the work, the rocks the step's loops visit (active stepping: the active list's length,
read when the hash table is fitted to it, every 32 steps; full stepping: every rock).

* off the CPU (CUDA, Vulkan): parallel, always (a serial loop runs on one GPU thread);
* on the CPU with one thread: serial (the pool has nothing to share out);
* on the CPU with p threads: serial while the work stays below the crossover c(p), parallel above it, with a
  band of hysteresis (back to serial below c(p) / 2) so that a list hovering at the crossover does not switch
  every fit. A parallel task costs F (about 55 us on these CPUs) before any work, and a rock costs s in each of
  the step's K loops (about 10 loops; s of 20-100 ns), so p threads pay off once N s K (1 - 1/p) > K F:
  N > F / (s (1 - 1/p)). :data:`CROSSOVER` holds the count measured by ``taichi-rocks bench --only frame``
  (its variant table) on a 2-core machine, scaled by p / (p - 1) for other pools.

``TAICHI_ROCKS_LOOPS`` ("serial", "parallel" or "auto") or ``Simulation.loops`` overrides the choice; each
variant compiles once, the first time it runs.
"""

from __future__ import annotations

from ..config.environment import LOOP_CHOICES as CHOICES, LOOPS, loops_wanted

__all__ = ["LOOPS", "CHOICES", "CROSSOVER", "crossover", "loops_from_env", "VariantChoice"]

CROSSOVER = 60_000  # rocks in a step's loops past which 2 threads beat one (bench --only frame: variants)


def loops_from_env() -> str:
    """``TAICHI_ROCKS_LOOPS`` as one of :data:`CHOICES` ("auto" when unset); ValueError naming the variable
    (config/environment.py: the command line checks it before anything starts)."""
    return loops_wanted()


def crossover(threads: int) -> float:
    """The work (rocks) past which ``threads`` CPU threads beat one (module docstring); infinite for one."""
    if threads <= 1:
        return float("inf")
    return CROSSOVER * threads / (2.0 * (threads - 1))


class VariantChoice:
    """The step's variant over time: :meth:`update` with the work when it is known, :attr:`serial` to read.

    ``on_cpu``, ``threads``: the backend and the CPU pool's size; ``mode``: "auto", "serial" or "parallel"."""

    def __init__(self, on_cpu: bool, threads: int, mode: str = "auto"):
        if mode not in CHOICES:
            raise ValueError(f"loops must be one of {', '.join(CHOICES)}, got {mode!r}")
        self.on_cpu, self.threads, self.mode = bool(on_cpu), int(threads), mode
        self.serial = self._fixed() if mode != "auto" or not on_cpu or threads <= 1 else True

    def _fixed(self) -> bool:
        if self.mode == "serial":
            return True
        if self.mode == "parallel":
            return False
        return self.on_cpu and self.threads <= 1

    def update(self, work: int) -> bool:
        """The work of the coming steps (rocks their loops visit); returns :attr:`serial`."""
        if self.mode != "auto" or not self.on_cpu or self.threads <= 1:
            self.serial = self._fixed()
            return self.serial
        c = crossover(self.threads)
        if self.serial and work > c:
            self.serial = False
        elif not self.serial and work < 0.5 * c:
            self.serial = True
        return self.serial
