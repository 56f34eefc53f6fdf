"""The engine's face for measurements: what the benchmark (taichi_rocks/bench) needs beyond stepping a
Simulation, as public functions, so that nothing outside engine/ calls the engine's kernels, writes its fields
or reaches into a Simulation.

* :func:`separate_passes` - each pass of a step as a callable of its own (the rock pass with one part at a
  time, the hash build's clear, count, scan and scatter, the ray cells, the tire pass), with the arguments the
  step just taken gave it; :func:`rock_pass_call` - the rock pass with chosen parts and switches;
  :func:`clear_hash` - leaves the hash counts cleared as a step does; :func:`reorder` - the in-memory re-sort
  of the rocks by hash slot.
* :func:`fly_only` - chosen test rocks flown by the flight part of the rock pass alone (no ground, no
  recycling, no hash), the rock fields restored afterwards; :func:`set_flying` - every rock flying with given
  velocities; :func:`active_rocks` - the rock loops limited to the first n rock slots inside a ``with`` block.
* :func:`rocks_in_air` - rocks in flight (a kernel's count, both stepping modes); :func:`activity` - where the
  rocks are (active list, tiles, full tiles, resting rocks left active); :func:`move_frame` - the kernels'
  frame moved by any distance (tests of drawing far from the origin).
* :func:`launch_costs` - what a kernel launch costs in Python for the arguments a step passes (empty kernels,
  so only the launch is timed); :func:`task_labels` - what each task of active stepping's kernels does.

The pass-level probes take the rocks from the World's rock arrays: they need ``[sim] stepping = "full"``
(every rock in those arrays) and raise ValueError otherwise; :func:`set_flying` works in both modes.
Whole steps are timed by the step itself (engine/timing.py); settings change by building a Simulation from a
changed Scene (kernels compile once per World layout and switches: a Simulation of a layout and switches seen
before compiles nothing).
"""

from __future__ import annotations

import contextlib
import time
from typing import Callable

import numpy as np
import taichi as ti

from ..config.plan import Plan
from . import active, hashgrid, stepdata, tires
from .kernels import READS, Switches, rock_pass
from .launcher import Launcher
from .world import FLYING, RAY_FIELDS, RESTING, SLIDING, IPar


def _full_only(sim) -> None:
    if sim.plan.active:
        raise ValueError("this probe runs the passes of full stepping: build the scene with "
                         "[sim] stepping = \"full\"")


def _pass_args(sim) -> tuple:
    """The arguments of ``rock_pass`` between the World and the switches, as the step just taken passed them:
    the rays (read back from the World, where the step's count put them), dt, the bed centre and its move in
    that step (the followed vehicle's, recomputed: equal up to rounding), the lead direction, the mask's grid
    origin, the step number."""
    w = sim.world
    rays = w.ray.to_numpy().astype(np.float64) if w.n_tires else np.zeros((1, RAY_FIELDS))
    move = np.zeros(2)
    if sim.step_count > 0:
        before = sim.fleet.poses(sim.time - sim.dt)[sim.follow].position
        move = sim.bed_center[:2] - np.asarray(before[:2], float)
    c = sim._host.local_centre()
    frame = np.array([c, move, sim._host.lead, sim._stepper.grid_origin(c)])  # kernels.CENTRE .. GRID
    return rays, frame, float(sim.dt), int(sim.step_count)


def _switches(flight, recycle, count, center, integrator, gravity, drag, ground) -> Switches:
    """rock_pass's switches: which parts run (``count``: the hash count, the plan's ``splash``)."""
    return Switches(Plan(splash=count, flight=flight, recycle=recycle, center=center, integrator=integrator,
                         gravity=gravity, drag=drag, ground=ground), READS["rock_pass"])  # the rest off (Plan)


def rock_pass_call(sim, *, flight: bool = False, recycle: bool = False, count: bool = False, integrator=None,
                   gravity=None, drag=None, ground=None) -> Callable[[], None]:
    """A callable that runs the rock pass once with only the chosen parts (flight, recycle, count for the
    hash) and the plan's switches unless given, with the arguments of the step just taken (bound now: a call
    costs one launch and nothing else). It holds the World, not the Simulation."""
    _full_only(sim)
    p = sim.plan
    switches = _switches(bool(flight), bool(recycle), bool(count), p.center, integrator or p.integrator,
                         p.gravity if gravity is None else bool(gravity), drag or p.drag, ground or p.ground)
    return _bound_rock_pass(sim.world, _pass_args(sim), switches)


def _bound_rock_pass(w, args: tuple, switches: Switches) -> Callable[[], None]:
    rays, frame, dt, step = args

    def call() -> None:
        rock_pass(w, switches, rays, frame, dt, step)

    return call


def separate_passes(sim) -> list[tuple[str, Callable]]:
    """Each pass of a step on its own, in the order a step runs them, as (name, callable): "flight",
    "recycle" (parts of the rock pass), then "hash clear", "hash count" (the rock pass counting alone),
    "hash scan", "hash scatter", "trace rays" (single-ray detection) and "tire pass". Call them in this order
    (each needs the ones before it), then :func:`clear_hash`. Passes the plan does not run are left out."""
    _full_only(sim)
    p, w = sim.plan, sim.world
    args = _pass_args(sim)
    step = int(sim.step_count)
    part = lambda flight, recycle, count: _bound_rock_pass(
        w, args, _switches(flight, recycle, count, p.center, p.integrator, p.gravity, p.drag, p.ground))
    out = []
    if p.flight:
        out.append(("flight", part(True, False, False)))
    if p.recycle:
        out.append(("recycle", part(False, True, False)))
    if p.splash:
        out += [("hash clear", lambda: hashgrid.clear_counts(w)),
                ("hash count", part(False, False, True)),
                ("hash scan", lambda: hashgrid.inclusive_scan(w)),
                ("hash scatter", lambda: hashgrid.scatter(w, p.center))]
        if not p.swept:
            out.append(("trace rays", lambda: tires.trace_rays(w)))
        tire_switches = Switches(p, READS["hash_and_tires"])
        out.append(("tire pass", lambda: tires.tire_pass(w, tire_switches, step)))
    return out


def clear_hash(sim) -> None:
    """Clear the hash counts, as every step leaves them (nothing to do without a hash)."""
    if sim.plan.splash:
        hashgrid.clear_counts(sim.world)


def reorder(sim) -> None:
    """Re-sort the rocks in memory by hash slot, as the step does every ``reorder_every`` steps (plans that
    reorder only: centre insert, every rock hashed)."""
    _full_only(sim)
    if not sim.plan.reorder_every:
        raise ValueError("this simulation's plan does not reorder the rocks (reorder_every = 0)")
    sim._stepper.reorder()


@contextlib.contextmanager
def active_rocks(sim, n: int):
    """Inside the block the rock loops of every kernel run over the first ``n`` rock slots only."""
    _full_only(sim)
    w = sim.world
    saved = int(w.ipar[IPar.N_ROCKS])
    w.ipar[IPar.N_ROCKS] = int(n)
    try:
        yield
    finally:
        w.ipar[IPar.N_ROCKS] = saved


def set_flying(sim, velocities) -> None:
    """Every rock flying, with these velocities ((n_rocks, 3), m/s), from where it is."""
    n = sim.n_rocks
    sim.set_rocks(np.arange(n), velocities=velocities, phase=FLYING)


_ROCK = ("pos", "vel", "radius", "phase")


def fly_only(sim, x0_local, v0, radius, dt: float, steps: int, every: int, integrator: str, drag: str,
             gravity: bool = True) -> np.ndarray:
    """Fly k test rocks with the flight part of the rock pass alone (ground contact "none", no recycling,
    no hash): rock slots 0..k-1 get these positions (local frame), velocities and radii, flying; ``steps``
    passes of ``dt`` run over those k slots only. The rock fields and the rock count are restored afterwards.
    Returns the local positions every ``every`` steps, float64, shape (k, steps // every, 3)."""
    _full_only(sim)
    w = sim.world
    k = len(x0_local)
    npr = w.np_real()
    saved = {f: getattr(w, f).to_numpy() for f in _ROCK}
    test = {"pos": np.asarray(x0_local, np.float64), "vel": np.asarray(v0, np.float64),
            "radius": np.asarray(radius, np.float64), "phase": np.full(k, FLYING)}
    for f in _ROCK:
        a = saved[f].copy()
        a[:k] = test[f].astype(a.dtype if f == "phase" else npr)
        getattr(w, f).from_numpy(a)
    rays = np.zeros((1, RAY_FIELDS))
    frame = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 0.0]])  # centre, move, lead, grid: unused
    switches = _switches(True, False, False, sim.plan.center, integrator, bool(gravity), drag, "none")
    samples = []
    try:
        with active_rocks(sim, k):
            for s in range(1, steps + 1):
                rock_pass(w, switches, rays, frame, float(dt), s)
                if s % every == 0:
                    samples.append(w.pos.to_numpy()[:k].astype(np.float64))
    finally:
        for f in _ROCK:
            getattr(w, f).from_numpy(saved[f])
    return np.stack(samples, axis=1)


def rocks_in_air(sim) -> int:
    """How many rocks fly now (phase FLYING): counted in a kernel (Simulation.rocks_in_air)."""
    return sim.rocks_in_air()


def activity(sim) -> dict:
    """Where the rocks are now: "active" (the World's rock arrays: the active list with active stepping, every
    rock with full stepping), of them "flying", "sliding" and "resting"; with active stepping "stored" (in the
    tiles), "full_tiles" (tiles holding as many rocks as a tile can) and "homeless" (resting rocks left in the
    active list: their tile was full when they came to rest). One read-back of the active list's phases."""
    n = int(sim.active_count)
    ph = sim.world.phase.to_numpy()[:n] if n else np.zeros(0, np.int32)
    out = {"active": n, "flying": int(np.count_nonzero(ph == FLYING)), "sliding": int(np.count_nonzero(ph == SLIDING)),
           "resting": int(np.count_nonzero(ph == RESTING))}
    if sim.plan.active:
        w = sim.world
        counts = w.ts_count.to_numpy()
        out.update(stored=int(counts.sum()), full_tiles=int(np.count_nonzero(counts >= w.store_capacity)),
                   homeless=out["resting"])
    return out


def move_frame(sim, d) -> None:
    """Move the kernels' local frame by ``d`` (XY, m; any distance, unlike the floating origin's whole steps of
    ORIGIN_SNAP): every rock's local position (tiles included) by -d, the origin and its shift by +d. The same
    world drawn from another frame; the tiles keep their keys, so move the frame back before stepping."""
    d = np.asarray(d, np.float64)
    sim._stepper.shift_origin(d)
    h = sim._host
    h.shift = h.shift + d
    h.origin[:2] += d


def launch_costs(sim, reps: int = 2000) -> dict:
    """Microseconds of Python per launch of kernels that do nothing on the device, median of 5 rounds of
    ``reps`` launches: "empty" (no arguments), "step" (the World, a kernel's switches and three integers: a
    step's launch of active stepping, engine/active.py), "step, same arguments" (the same integers every
    launch: Taichi 1.7.4 caches nothing between launches), "step, the engine's launcher" (the step's launch as
    the engine makes it, engine/launcher.py: Taichi's launch with its Python side done once), "arrays" (the arguments the step's first launch
    took before its inputs were on the device: a (T, RAY_FIELDS) float64 array of rays, 5 rows of 2-vectors,
    a float and two integers)."""
    w, plan = sim.world, sim._stepper.switches["active_step"]
    fast = Launcher(stepdata.launch_ints)
    rays = np.zeros((max(w.n_tires, 1), RAY_FIELDS))
    frame = np.zeros((5, 2))
    counter = iter(range(1 << 40))
    cases = {"empty": lambda: stepdata.launch_empty(),
             "step": lambda: stepdata.launch_ints(w, plan, next(counter) & 63, next(counter), 0),
             "step, same arguments": lambda: stepdata.launch_ints(w, plan, 0, 1, 0),
             "step, the engine's launcher": lambda: fast(w, plan, next(counter) & 63, next(counter), 0),
             "arrays": lambda: stepdata.launch_arrays(w, plan, rays, frame, 0.002, next(counter), 0)}
    out = {k: [] for k in cases}
    for f in cases.values():
        f()
    ti.sync()
    for _ in range(5):
        for name, f in cases.items():
            t = time.perf_counter()
            for _ in range(reps):
                f()
            ti.sync()
            out[name].append((time.perf_counter() - t) / reps * 1e6)
    return {k: float(np.median(v)) for k, v in out.items()}


def task_labels() -> dict:
    """Kernel name -> the variants of what each of its offloaded tasks does, in order, one tuple per variant of
    distinct length (active stepping's step kernels: active.task_labels; the batch upload)."""
    return {**active.task_labels(), **{k: [stepdata.SERIAL_TASKS[k], v] for k, v in stepdata.TASKS.items()}}
