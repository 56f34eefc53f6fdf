"""How the benchmark times things and holds its simulations.

Every timing: warm-up (compile) first, then repeated calls with ``ti.sync()`` before and after the timed region,
summarised by the median. Passes inside a real step are timed by the step itself (the engine's timing hook,
engine/timing.py ``PassTimer``); passes on their own are called through engine/probes.py. A simulation's
settings change by building a new Simulation from the changed Scene that carries on from a checkpoint of the
old one (:meth:`Built.rebuild`): the old one is released first (its World is not held beside the new one), and
kernels compile once per World layout and switches, so switching back and forth compiles nothing after the
first time.
"""

from __future__ import annotations

import gc
import time
import weakref

import numpy as np
import taichi as ti

from ..engine import probes
from ..engine.simulation import Simulation
from ..engine.timing import PassTimer
from ..engine.world import FLYING

# the engine's names of its fused passes, as the report has always called them
_PASS_LABELS = {"rock pass": "rock pass (fused)", "hash + tires": "hash scan+scatter+tires (fused)",
                "active step": "active step (two launches: tiles, rock pass | hash, tires, settle)",
                "vehicles + rays": "vehicles + rays (host)"}


def stats(seconds) -> dict:
    a = np.asarray(seconds, float) * 1e3
    return {"median_ms": float(np.median(a)), "mean_ms": float(np.mean(a)), "min_ms": float(np.min(a)),
            "max_ms": float(np.max(a)), "reps": int(len(a))}


def timed_call(fn) -> float:
    """Seconds of one call, with ti.sync() before and after."""
    ti.sync()
    t = time.perf_counter()
    fn()
    ti.sync()
    return time.perf_counter() - t


def time_calls(fn, reps: int, warmup: int = 1) -> dict:
    """Warm-up calls (compile), then `reps` timed calls with ti.sync() around each."""
    for _ in range(warmup):
        fn()
    ti.sync()
    return stats([timed_call(fn) for _ in range(reps)])


class Built:
    """A Simulation plus its build time (construction + first step = compile)."""

    def __init__(self, scene, arch, label):
        self.arch = arch
        t = time.perf_counter()
        self.sim = Simulation(scene, arch=arch)
        ti.sync()
        self.ctor_s = time.perf_counter() - t
        self.label = label
        self.first_step_s = None

    def step_timed(self, n: int) -> list:
        out = [timed_call(self.sim.step) for _ in range(n)]
        if self.first_step_s is None and out:
            self.first_step_s = out[0]
        return out

    def rebuild(self, scene) -> None:
        """Carry on under a changed scene: a new Simulation of ``scene`` continues from a checkpoint of the
        current one (same rocks, clock and origin). The current one is released first, so that two Worlds are
        never held at once (RuntimeError if something else still holds it). Kernels compile once per World
        layout and switches: a scene needing other fields (another layout: with active stepping, switching
        recycling off changes the tile store's layout, counted in ``layout_switches``) compiles its kernels
        the first time, and A/B switches compile each side once."""
        state = self.sim.checkpoint()
        world, timer = self.sim.world, self.sim.timer
        gone = weakref.ref(self.sim)
        self.sim = None
        if gone() is not None:
            gc.collect()
        if gone() is not None:
            raise RuntimeError(f"{self.label}: the simulation is still referenced elsewhere; its World would stay "
                               "beside the new one")
        sim = Simulation(scene, arch=self.arch, timer=timer)
        self.layout_switches = getattr(self, "layout_switches", 0) + (sim.world.layout != world.layout)
        sim.restore(state)
        self.sim = sim


def launched_ids(sim) -> np.ndarray:
    """Rock ids launched so far (hit_step >= 0), sorted. With active stepping a launched rock that has come to
    rest in a tile again no longer counts (its hit step is not stored)."""
    r = sim.rock_arrays()
    if "hit_step" not in r:
        return np.zeros(0, np.int64)
    return np.flatnonzero(r["hit_step"] >= 0).astype(np.int64)


def n_flying(sim) -> int:
    """Rocks flying now, wherever the rocks are kept (Simulation.rock_arrays)."""
    return int(np.sum(sim.rock_arrays()["phase"] == FLYING))


def in_step_profile(sim, steps: int) -> dict:
    """ms per step of each pass inside real steps (the engine's timing hook), and the rest of the step."""
    timer, saved = PassTimer(), sim.timer
    sim.timer = timer
    times = []
    try:
        for _ in range(steps):
            t = time.perf_counter()
            sim.step()
            ti.sync()
            times.append(time.perf_counter() - t)
    finally:
        sim.timer = saved
    prof = {_PASS_LABELS.get(k, k): v for k, v in timer.ms_per_step(steps).items()}
    total = 1e3 * float(np.mean(times))
    prof["host and launch overhead"] = max(0.0, total - sum(prof.values()))
    return {"mean_step_ms_with_syncs": total, "per_pass_ms": prof}


def separate_passes_ms(sim, reps: int) -> dict:
    """Each pass on its own, after a normal step each round (engine/probes.py ``separate_passes``: the rock
    pass with one part at a time, then clear, count, scan, scatter, trace rays, tire pass); medians of the
    rounds after the first (it compiles). The counts are cleared again at the end of each round."""
    out: dict[str, list] = {}
    for _ in range(reps + 1):
        sim.step()
        ti.sync()
        for name, fn in probes.separate_passes(sim):
            out.setdefault(name, []).append(timed_call(fn))
        probes.clear_hash(sim)
    res = {k: 1e3 * float(np.median(v[1:])) for k, v in out.items()}
    if sim.plan.splash:
        res["hash build (clear+count+scan+scatter)"] = sum(res[k] for k in ("hash clear", "hash count", "hash scan",
                                                                            "hash scatter"))
    return res
