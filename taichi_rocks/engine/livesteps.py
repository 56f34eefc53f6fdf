"""The host side of a step in a scene with live vehicles (docs/drives.md), where the lookahead cannot batch
whole steps: a live pose is known only up to the end of the advance under way (engine/host.py ``Lookahead.pays``).
The scripted vehicles' part of the coming steps is still known, so it is computed up to 64 steps at a time, as a
lookahead batch (their poses, their rear tires, their tires' ray rows with the tread's swept footprint: the costly
part, engine/patch.py); each step then adds the live vehicles' poses, all tires' kinematics from the step's pose
row, the live tires' ray rows, which tires are near the bed (the bed follows whichever vehicle it follows), and
does the rest as a step alone does (engine/host.py ``HostSide.advance``): the bed, the origin, the kernels' frame,
the impacts' pose rows.

The same bits as step by step: each row of a batch is what the per-step computation gives for that time and
those previous tires (``Fleet.pose_table``, ``Fleet.rear_tires_table`` and ``ray_rows`` work row by row, tire
by tire); a tire's ray row depends only on that tire's previous and current state, the bed only in which tires
are near it, recomputed here. The batch is used while the steps continue it: the same dt, the clock at its next
row's time, the previous tires those this path served last; anything else starts a new one.

Measured (the default scene, the player live, one step a frame; docs/drives.md has the figures): the host side
of a step, which the scripted player's lookahead amortises over 64 steps, costs ~0.2 ms here against ~0.5 ms for
the step alone.
"""

from __future__ import annotations

import math

import numpy as np

from ..motion.vehicles import PoseTable, RearTires, TablePoses
from .host import HostSide, Lookahead, StepInput
from .impact_pass import pose_rows
from .patch import _hull
from .world import ACTIVE, BATCH_ROWS, HULL_VERTICES, RAY_FIELDS

__all__ = ["LiveHostSide", "LiveSteps", "ray_row"]


class LiveHostSide(HostSide):
    """HostSide for a scene with live vehicles: a whole step's batch where it pays (engine/host.py), else a step
    of :class:`LiveSteps` (whole steps of dt) or a step alone (a shorter last step of ``advance_to``)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.split = LiveSteps(self)

    def alone(self, st, dt: float) -> StepInput:
        if self.lookahead and dt == self.dt:
            return self.split.advance(st, dt)
        return super().alone(st, dt)


class LiveSteps:
    """Steps of a scene with live vehicles (module docstring) for a HostSide ``hs``."""

    def __init__(self, hs):
        self.hs = hs
        fleet = hs.fleet
        self.ahead = Lookahead(fleet, hs.follow, hs.n_tires > 0, hs.reach, planned=True)
        tire_vehicle = np.repeat(np.array(fleet.splashing, dtype=np.int64), 2)  # two rear tires each
        self.live_tires = np.flatnonzero(np.isin(tire_vehicle, fleet.live))
        self.live = np.array(fleet.live, dtype=np.int64)
        self._batch, self._next, self._served = None, 0, None

    def _row(self, time: float, tires_prev: RearTires, dt: float) -> tuple:
        """The batch and row of the step ending at ``time``; a new batch unless the steps continue it."""
        b, k = self._batch, self._next
        if b is None or k >= len(b.times) or b.dt != dt or b.times[k] != time or tires_prev is not self._served:
            b = self._batch = self.ahead.batch(time, tires_prev, dt, BATCH_ROWS)
            k = 0
        self._next = k + 1
        return b, k

    def _table(self, b, k: int, time: float) -> PoseTable:
        """Row k of the batch's pose table with the live vehicles' poses at ``time`` in their columns."""
        fleet = self.hs.fleet
        cols = {name: getattr(b.table, name)[k:k + 1].copy() for name in PoseTable.__dataclass_fields__}
        if cols["wheel_spin"] is None:
            cols["wheel_spin"] = np.full((1, len(fleet.paths)), np.nan)
        for i in fleet.live:
            p = fleet.poses_of(i, time)
            for name, value in zip(("x", "y", "rx", "ry", "heading", "speed", "yaw_rate", "vx", "vy", "wheel_spin"),
                                   p):
                cols[name][0, i] = value
        return PoseTable(**cols)

    def _tires(self, b, k: int, poses) -> RearTires:
        """Every rear tire now: the batch's row k, the live vehicles' tires computed from their poses
        (``Fleet.rear_tires``: the bits of ``rear_tires_table``); those alone kept in ``_live_now``."""
        fleet, lt = self.hs.fleet, self.live_tires
        arrays = [a[k] for a in b.tire_arrays]
        if len(lt):
            self._live_now = live = fleet.rear_tires(poses, relative=True, vehicles=fleet.live)
            for j, name in enumerate(("center", "bottom", "velocity", "forward", "spin")):
                arrays[j] = arrays[j].copy()
                arrays[j][lt] = getattr(live, name)
        return RearTires(*arrays)

    def advance(self, st, dt: float) -> StepInput:
        """The host side of one step (the clock already advanced): HostSide.advance's, the same bits."""
        hs = self.hs
        b, k = self._row(st.time, st.tires_prev, dt)
        table = self._table(b, k, st.time)
        poses = TablePoses(hs.fleet, table, 0)
        move = hs._follow(st, poses[hs.follow])
        moved = hs._keep_origin_near(st)
        now = self._tires(b, k, poses)
        rays = hs.no_rays
        if hs.n_tires:
            rows = b.rows[k].copy()
            lt = self.live_tires
            if len(lt):
                rows[lt] = [ray_row(st.tires_prev, int(t), self._live_now, j, dt) for j, t in enumerate(lt)]
            far = np.hypot(now.center[:, 0] - st.bed_rel[0], now.center[:, 1] - st.bed_rel[1]) > hs.reach
            rows[:, ACTIVE] = ~far
            rays = hs.local_rays(st, rows, far)
        st.tires_prev = self._served = now
        bodies = pose_rows(st.poses, poses, hs.targets, st.shift) if hs.targets else None
        st.poses = poses
        return StepInput(st.step_count, dt, st.local_centre(), move, st.lead, st.shift, rays, moved, bodies=bodies)


def ray_row(prev: RearTires, i: int, cur: RearTires, j: int, dt: float) -> list:
    """engine/host.py ``ray_rows`` of one tire (``prev`` tire i -> ``cur`` tire j, relative to the anchor) in plain
    floats, the same operations in the same order (the same bits: tests/engine/test_drive.py); ACTIVE left 1.
    For the live vehicles' few tires a step, where NumPy's cost per call is most of the work."""
    c0, b0, v0, f0 = (tuple(a[i].tolist()) for a in (prev.center, prev.bottom, prev.velocity, prev.forward))
    c1, b1, v1, f1 = (tuple(a[j].tolist()) for a in (cur.center, cur.bottom, cur.velocity, cur.forward))
    moved = math.sqrt((c1[0] - c0[0]) * (c1[0] - c0[0]) + (c1[1] - c0[1]) * (c1[1] - c0[1])
                      + (c1[2] - c0[2]) * (c1[2] - c0[2]))
    speed = max(math.sqrt(v1[0] * v1[0] + v1[1] * v1[1] + v1[2] * v1[2]),
                math.sqrt(v0[0] * v0[0] + v0[1] * v0[1] + v0[2] * v0[2]))
    jumped = moved > 2.0 * speed * dt + 0.05
    if jumped:
        c0, b0, f0 = c1, b1, f1
    hw, hl, radius, fender, flap = (float(a[j]) for a in (cur.half_width, cur.half_length, cur.radius, cur.fender,
                                                          cur.flap))
    corners = _corners(b0, f0, hw, hl) + _corners(b1, f1, hw, hl)
    hull = [tuple(v) for v in _hull(corners).tolist()]
    hull += [hull[-1]] * (HULL_VERTICES - len(hull))
    row = [*c0, *b0, *c1, *b1, *v1, *f1[:2], float(cur.spin[j]), 1.0, hw, hl, radius, fender, flap]
    for x, y in hull:
        row += [x - 0.0, y - 0.0]
    assert len(row) == RAY_FIELDS
    return row


def _corners(b, f, hw: float, hl: float) -> list:
    """engine/patch.py ``footprint_corners`` of one tire in plain floats (the same operations)."""
    lx, ly = -f[1], f[0]
    return [(b[0] + sl * hl * f[0] + sw * hw * lx, b[1] + sl * hl * f[1] + sw * hw * ly)
            for sl, sw in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
