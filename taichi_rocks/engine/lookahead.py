"""The host side of the next steps, computed a batch at a time: vehicle poses, rear tires and tire ray rows.

What a step needs from the host (motion/vehicles.py poses at t + dt, the rear tires, their rays with the
swept footprint's hull) depends only on the clock, the scripted paths and the previous step's tires. The
``Lookahead`` computes it for the next ``Simulation.lookahead`` steps at once (the times accumulated exactly as
``Simulation.time += dt`` does, so every row has the bits the step-by-step computation gives) and serves it
one step at a time. Ray rows are kept relative to the origin's anchor; ``local_rays`` moves a step's rows
into the kernels' frame (the floating origin's shift at that step, which the simulation still decides step
by step) and parks the tires far from the bed, so a shift in the middle of a batch costs nothing.

A batch is used only while it is the continuation of the steps taken: the same dt, the clock at the time
its next row was computed for, and the previous tires the ones it served last. Anything else (restore, a
shorter last step of ``advance_to``, coasting, a step taken without it) starts a new batch on the next step.
Batches adapt to how long they last: one left after u steps is followed by one of u + 1 (the whole steps of
an ``advance_to`` frame, then its short step), one used up by one twice as long (up to ``lookahead``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from . import patch
from ..motion.vehicles import RearTires, TablePoses, VehiclePose, tire_fields
from .world import ACTIVE, HALF_W, HULL, RAY_FIELDS


def reach(scene) -> float:
    """How far from the bed centre (XY, m) a tire can touch a rock; tires farther away are parked."""
    return scene.bed.radius + 2.0 * float(scene.bed.rock_radius[1]) + 2.0


def ray_rows(prev: RearTires, cur: RearTires, dt: float, bed_rel: np.ndarray, reach_m: float):
    """The rays of the rear tires ``prev`` -> ``cur`` (rows of any number of tires and steps, relative to the
    anchor) in the World.ray layout, float64 (N, RAY_FIELDS), still relative to the anchor, and which tires
    are far from the bed (``bed_rel``: its centre relative to the anchor, (2,) or one per row): (rows, far)."""
    n = len(cur.spin)
    rows = np.zeros((n, RAY_FIELDS))
    # a tire that moved much farther than its speed allows (a path that jumps, e.g. a looping arc) did
    # not sweep the ground in between: its previous ray is taken to be the current one
    moved = np.linalg.norm(cur.center - prev.center, axis=1)
    speed = np.maximum(np.linalg.norm(cur.velocity, axis=1), np.linalg.norm(prev.velocity, axis=1))
    jumped = moved > 2.0 * speed * dt + 0.05
    rows[:, 0:3] = np.where(jumped[:, None], cur.center, prev.center)
    rows[:, 3:6] = np.where(jumped[:, None], cur.bottom, prev.bottom)
    rows[:, 6:9] = cur.center
    rows[:, 9:12] = cur.bottom
    rows[:, 12:15] = cur.velocity
    rows[:, 15:17] = cur.forward
    rows[:, 17] = cur.spin
    rows[:, HALF_W:] = patch.tread_columns(prev, cur, ~jumped, np.zeros(3))
    # tires far from the bed cannot touch a rock: their rays are parked (local_rays)
    bed_rel = np.asarray(bed_rel, np.float64)
    far = np.hypot(cur.center[:, 0] - bed_rel[..., 0], cur.center[:, 1] - bed_rel[..., 1]) > reach_m
    rows[:, ACTIVE] = ~far
    return rows, far


def local_rays(rows: np.ndarray, far: np.ndarray, shift: np.ndarray, park: np.ndarray) -> np.ndarray:
    """Rows of ``ray_rows`` in the kernels' frame (origin = anchor + ``shift``, XY): positions minus the
    shift; the far tires' rays parked, degenerate, at ``park`` (local frame, high above the bed)."""
    o = np.zeros(RAY_FIELDS)  # x - (+0.0) is x, bit for bit: the other columns are unchanged
    o[0:12] = np.tile([shift[0], shift[1], 0.0], 4)
    o[HULL:] = np.tile(shift[:2], (RAY_FIELDS - HULL) // 2)
    data = rows - o
    if far.any():
        data[far, 0:12] = np.tile(park, 4)
        data[far, HULL:] = np.tile(park[:2], (RAY_FIELDS - HULL) // 2)
        data[far, 17] = 0.0
    return data


@dataclass(frozen=True)
class Ahead:
    """One step served: the vehicles' poses, the rear tires (relative to the anchor) and, with splashing
    tires, their ray rows and far flags (``ray_rows``; None without)."""

    poses: Sequence[VehiclePose]
    tires: RearTires
    rows: np.ndarray | None
    far: np.ndarray | None


class _Batch:
    def __init__(self, times, dt, table, tires, rows, far, prev):
        self.times, self.dt, self.table, self.tires, self.rows, self.far = times, dt, table, tires, rows, far
        self.next = 0
        self.prev = prev  # the tires the next step's rays start from


class Lookahead:
    """The next ``sim.lookahead`` steps' host work, computed at once and served one step at a time (module
    doc)."""

    def __init__(self):
        self.batches = 0  # batches computed so far
        self._size = 1 << 30  # steps of the next batch (at most Simulation.lookahead)
        self.clear()

    def clear(self) -> None:
        """Forget the batch (restore(), anything that changes the clock or the tires other than a step)."""
        self._batch = None

    def take(self, sim, dt: float) -> Ahead:
        """The step that ``sim`` is taking (its clock already advanced by ``dt``)."""
        b = self._batch
        if (b is None or b.next >= len(b.times) or b.dt != dt or b.times[b.next] != sim.time
                or b.prev is not sim._tires_prev):
            if b is not None:  # a batch used up: the next twice as long; left early: as long as was used
                self._size = 2 * len(b.times) if b.next >= len(b.times) else b.next + 1
            b = self._batch = self._compute(sim, dt, max(1, min(self._size, int(sim.lookahead))))
        k = b.next
        tires = RearTires(*(a[k] for a in tire_fields(b.tires)))
        b.next, b.prev = k + 1, tires
        rows = None if b.rows is None else b.rows[k]
        return Ahead(TablePoses(sim.fleet, b.table, k), tires, rows, None if b.far is None else b.far[k])

    def _compute(self, sim, dt: float, steps: int) -> _Batch:
        times = [sim.time]
        for _ in range(steps - 1):
            times.append(times[-1] + dt)
        fleet = sim.fleet
        table = fleet.pose_table(times)
        cur = fleet.rear_tires_table(table)
        k, n = len(times), len(cur.spin[0])
        rows = far = None
        if sim.plan.splash and sim.world.n_tires:
            start = tire_fields(sim._tires_prev)
            prev = RearTires(*(np.concatenate([p[None], c[:-1]]).reshape(k * n, *c.shape[2:])
                               for p, c in zip(start, tire_fields(cur))))
            flat = RearTires(*(c.reshape(k * n, *c.shape[2:]) for c in tire_fields(cur)))
            bed = np.repeat(np.column_stack([table.rx[:, sim.follow], table.ry[:, sim.follow]]), n, axis=0)
            rows, far = ray_rows(prev, flat, dt, bed, reach(sim.scene))
            rows, far = rows.reshape(k, n, RAY_FIELDS), far.reshape(k, n)
        self.batches += 1
        return _Batch(times, dt, table, cur, rows, far, sim._tires_prev)
