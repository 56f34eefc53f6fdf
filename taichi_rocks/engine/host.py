"""The host side of a simulation: its clock, frame and vehicles (:class:`HostState`) and what each step needs
from the host (:class:`HostSide`): the vehicles' poses at t + dt (motion/vehicles.py), the bed following its
vehicle, the floating origin, the rear tires and their rays, computed a batch of steps at a time
(:class:`Lookahead`). No Taichi here: the steppers (engine/steppers.py) take a :class:`StepInput` to the kernels.

One step of length dt on the host:
  1. the clock advances (``time += dt``, exactly as step by step);
  2. poses at the new time; the bed centre moves under ``bed.follow`` and its leading direction turns to that
     vehicle's travel (kept while it stands); ``move`` is the bed's move, anchor-relative;
  3. floating origin: once the bed centre is farther than ORIGIN_RANGE from the origin, the shift moves to the
     snapped point nearest it (the kernels then move every rock by the difference, ``StepInput.origin_moved``);
  4. the rear tires now and their rays from the previous step's tires (``ray_rows``), in the kernels' frame
     (``local_rays``), tires far from the bed parked high above it;
  5. with impacts, the poses of the vehicles stones hit at the step's start and end, in the kernels' frame
     after this step's origin move (engine/impact_pass.py ``pose_rows``; a lookahead batch's at once,
     ``batch_pose_rows``).

Coordinates: kernels work in a local frame, world = origin + local. With ``origin = "floating"`` the origin is
anchor + shift: the anchor is the point the followed path is computed from (its first waypoint, where the bed
starts; a circle's centre), exact as the scene gives it; the shift moves in whole multiples of ORIGIN_SNAP
(exact in f32) to stay within ORIGIN_RANGE of the bed. All the kernels get (bed centre and its move, tire
rays, initial rocks) is computed relative to the anchor (``Pose.from_anchor``,
``Fleet.rear_tires(relative=True)``), never as a difference of world coordinates: the same scene moved anywhere
runs on the same bits (up to the rounding of the moved waypoints themselves), so f32 keeps sub-millimetre
precision and the same motion relative to the bed at any distance. ``origin = "world"``:
anchor and shift are 0 (world coordinates in the kernels).

Lookahead: what a step needs from the host depends only on the clock, the scripted paths and the previous
step's tires, so the next ``lookahead`` steps are computed at once (the times accumulated exactly as
``time += dt`` does, so every row has the bits the step-by-step computation gives) and served one step at a
time. Ray rows are kept relative to the anchor; ``local_rays`` moves a step's rows into the kernels' frame
(the shift at that step, which is still decided step by step), so a shift in the middle of a batch costs
nothing. A batch is used only while it is the continuation of the steps taken: the same dt, the clock at the
time its next row was computed for, and the previous tires the ones it served last. Anything else (restore, a
shorter last step of ``advance_to``, coasting, a step taken without it) starts a new batch on the next step.
Batches adapt to how long they last: one left after u steps is followed by one of u + 1 (the whole steps of an
``advance_to`` frame, then its short step), one used up by one twice as long (up to ``lookahead``).

Live vehicles (motion/live.py, docs/drives.md): a live pose is known only up to the end of the advance under way
(``Fleet.horizon``), so a batch ends there; a step for which a new batch would hold a single step is computed by
itself (``alone``: a batch of one step costs about twice as much), in a scene with live vehicles with its scripted
vehicles' part from a batch of their own (engine/livesteps.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from . import patch
from ..motion.live import clock_tolerance
from ..motion.vehicles import RearTires, TablePoses, tire_fields
from .impact_pass import batch_pose_rows, pose_rows
from .world import ACTIVE, BATCH_ROWS, HALF_W, HULL, RAY_FIELDS

__all__ = ["ORIGIN_SNAP", "ORIGIN_RANGE", "LOOKAHEAD", "HostState", "HostSide", "StepInput", "Lookahead", "Frames",
           "ray_rows", "local_rays", "reach"]

ORIGIN_SNAP = 64.0  # m: the origin moves from its anchor in whole multiples of this, so a shift is exact in f32
ORIGIN_RANGE = 128.0  # m: the origin moves when the bed centre is farther than this from it
LOOKAHEAD = BATCH_ROWS  # at most this many steps have their host side computed at once (the device's batch)


def snapped(xy: np.ndarray) -> np.ndarray:
    """The origin nearest to ``xy`` (XY, m): whole multiples of ORIGIN_SNAP."""
    return np.round(xy / ORIGIN_SNAP) * ORIGIN_SNAP


class HostState:
    """Everything of a simulation that lives on the host, in float64: the clock (``time``, ``step_count``),
    the frame (``anchor``, ``shift``, ``origin`` = anchor + shift), the bed (``bed_center`` in world
    coordinates, ``bed_rel`` relative to the anchor, ``lead`` its unit leading direction), the vehicles
    (``poses``, ``tires_prev``: the rear tires at the last step, anchor-relative) and the counters
    (``steps_coasted``, ``last_launches``)."""

    def __init__(self):
        self.step_count = 0
        self.time = 0.0
        self.anchor = np.zeros(3)
        self.shift = np.zeros(2)
        self.origin = np.zeros(3)
        self.bed_center = np.zeros(3)
        self.bed_rel = np.zeros(2)
        self.lead = np.array([1.0, 0.0])
        self.poses = []
        self.tires_prev = None
        self.steps_coasted = 0
        self.last_launches = 0

    def set_shift(self, shift) -> None:
        """Put the floating origin at anchor + shift (shift: whole multiples of ORIGIN_SNAP, or 0)."""
        self.shift = np.array(shift, dtype=np.float64)
        self.origin = self.anchor.copy()
        self.origin[:2] += self.shift

    def local_centre(self) -> np.ndarray:
        """The bed centre (XY) in the kernels' local frame, from anchor-relative coordinates only."""
        return self.bed_rel - self.shift

    def saved(self) -> dict:
        """The host part of a checkpoint."""
        return dict(step_count=np.int64(self.step_count), time=np.float64(self.time), origin=self.origin.copy(),
                    origin_anchor=self.anchor.copy(), origin_shift=self.shift.copy(),
                    bed_center=self.bed_center.copy(), bed_rel=self.bed_rel.copy(), lead=self.lead.copy())

    def load(self, data: dict) -> None:
        """The host part of a checkpoint back (clock, frame, bed; the poses and tires follow from the clock)."""
        self.step_count = int(data["step_count"])
        self.time = float(data["time"])
        self.bed_center = np.array(data["bed_center"], dtype=np.float64)
        if "origin_shift" in data:
            self.anchor = np.array(data["origin_anchor"], dtype=np.float64)
            self.bed_rel = np.array(data["bed_rel"], dtype=np.float64)
            self.set_shift(data["origin_shift"])
        else:  # saved before the origin had an anchor: this simulation's anchor, the saved origin
            self.bed_rel = self.bed_center[:2] - self.anchor[:2]
            self.set_shift(np.asarray(data["origin"], dtype=np.float64)[:2] - self.anchor[:2])
        self.lead = np.array(data["lead"], dtype=np.float64)


class StepInput(NamedTuple):
    """What one step's kernels get from the host: the step's number and length, the bed centre (XY, local
    frame), its move this step (anchor-relative), its leading direction, the origin's shift (XY, m), the rays
    (float64, World.ray layout, kernels' frame) and, if the origin moved before this step, by how much (XY);
    ``frames``: the lookahead batch's Frames this step is row ``row`` of (None: computed alone), which active
    stepping uploads once per batch (engine/stepdata.py); ``bodies``: with impacts the poses of the vehicles
    hit at the step's start and end (engine/impact_pass.py ``pose_rows``; None without).
    (A named tuple: made every step, it costs a fraction of a frozen dataclass.)"""

    step: int
    dt: float
    centre: np.ndarray
    move: np.ndarray
    lead: np.ndarray
    shift: np.ndarray
    rays: np.ndarray
    origin_moved: np.ndarray | None
    frames: "Frames | None" = None
    row: int = 0
    bodies: np.ndarray | None = None


@dataclass
class Frames:
    """Every step of a lookahead batch as the kernels see it, computed at once (HostSide.frames, the same bits
    as step by step): per step k the followed vehicle's world XY (``world``) and anchor-relative XY
    (``rel``: the bed centre), the bed's move, its leading direction, the origin's shift, its move before the
    step (``moved[k]``, None if it stayed), the bed centre in the kernels' frame (``local``) and the rays
    ((K, T, RAY_FIELDS) in the kernels' frame, or None without tires); with impacts the pose rows of the
    vehicles hit (``bodies``: (K, 7 T, 2), engine/impact_pass.py ``batch_pose_rows``) and each step's start
    time (``start``: (K,), the clock before the step). ``device``: set by the stepper that uploaded them."""

    world: np.ndarray
    rel: np.ndarray
    move: np.ndarray
    lead: np.ndarray
    shift: np.ndarray
    moved: list
    local: np.ndarray
    rays: np.ndarray | None
    dt: float
    bodies: np.ndarray | None = None
    start: np.ndarray | None = None
    device: object = None


class HostSide:
    """The host work of each step for one scene (module docstring): ``advance`` takes a HostState through one
    step and returns the kernels' StepInput. ``lookahead``: steps computed at once (0: step by step)."""

    def __init__(self, scene, fleet, follow: int, n_tires: int, lookahead: int = LOOKAHEAD, targets=()):
        self.fleet, self.follow, self.n_tires = fleet, int(follow), int(n_tires)
        self.targets = tuple(targets)  # with impacts: the vehicles stones hit (their poses go to the kernels)
        self.floating = scene.sim.origin == "floating"
        self.ground_z = float(scene.world.ground_z)
        self.dt = float(scene.sim.dt)
        self.reach = reach(scene)
        self.lookahead = lookahead
        self.ahead = Lookahead(fleet, self.follow, self.n_tires > 0, self.reach)
        self.no_rays = np.zeros((1, RAY_FIELDS))

    def start(self, st: HostState) -> None:
        """Time 0: the vehicles' poses, the bed under the followed vehicle, facing its heading, and the origin.
        Floating: the anchor is where the followed path is computed from (its first waypoint: the bed's
        start), the shift the bed's offset from it rounded to ORIGIN_SNAP (0 for waypoints); "world": both 0."""
        st.step_count, st.time = 0, 0.0
        st.anchor = np.zeros(3)
        if self.floating:
            st.anchor[:2] = self.fleet.reference_point(self.follow)
        self.fleet.anchor = st.anchor[:2].copy()
        st.poses = self.fleet.poses(0.0)
        c = st.poses[self.follow]
        st.bed_center = np.array([c.position[0], c.position[1], self.ground_z])
        st.bed_rel = c.rel[:2].copy()  # bed centre - anchor, never from world coordinates
        st.set_shift(snapped(st.bed_rel) if self.floating else np.zeros(2))
        st.lead = np.array([math.cos(c.heading), math.sin(c.heading)])
        st.tires_prev = self.fleet.rear_tires(st.poses, relative=True)

    def resume(self, st: HostState) -> None:
        """After the clock was set (restore, coasting): the poses and tires at that time."""
        self.fleet.anchor = st.anchor[:2].copy()
        st.poses = self.fleet.poses(st.time)
        st.tires_prev = self.fleet.rear_tires(st.poses, relative=True)

    def advance(self, st: HostState, dt: float) -> StepInput:
        """Steps 1 to 4 of the module docstring for ``st``; the rays are the splashing tires' (or a dummy row)."""
        st.step_count += 1
        st.time += dt
        if self.lookahead and dt == self.dt and self.ahead.pays(st.time, st.tires_prev, dt):
            b, k = self.ahead.take(st.time, st.tires_prev, dt, self.lookahead)  # the same bits as step by step
            if b.frames is None:
                b.frames = self.frames(st, b)
            return self._serve(st, b, k, dt)
        return self.alone(st, dt)

    def alone(self, st: HostState, dt: float) -> StepInput:
        """The step just counted on the clock, computed by itself (no batch)."""
        poses = self.fleet.poses(st.time)
        move = self._follow(st, poses[self.follow])
        moved = self._keep_origin_near(st)
        tires_now = self.fleet.rear_tires(poses, relative=True)
        rays = self.ray_data(st, st.tires_prev, tires_now, dt) if self.n_tires else self.no_rays
        st.tires_prev = tires_now
        bodies = pose_rows(st.poses, poses, self.targets, st.shift) if self.targets else None
        st.poses = poses
        return StepInput(st.step_count, dt, st.local_centre(), move, st.lead, st.shift, rays, moved, bodies=bodies)

    def _serve(self, st: HostState, b, k: int, dt: float) -> StepInput:
        """Step ``k`` of batch ``b`` into ``st`` (what _follow, _keep_origin_near and the rays do step by step)."""
        f = b.frames
        st.bed_center = np.array([f.world[k, 0], f.world[k, 1], st.bed_center[2]])
        st.bed_rel = f.rel[k]
        st.lead = f.lead[k]
        moved = f.moved[k]
        if moved is not None:
            st.set_shift(f.shift[k])
        st.tires_prev = b.prev  # the row's tires (take() set them)
        st.poses = TablePoses(self.fleet, b.table, k)
        bodies = None if f.bodies is None else f.bodies[k]
        rays = self.no_rays if f.rays is None else f.rays[k]
        return StepInput(st.step_count, dt, f.local[k], f.move[k], f.lead[k], st.shift, rays, moved, f, k, bodies)

    def frames(self, st: HostState, b) -> "Frames":
        """Every step of batch ``b`` from ``st`` (the state before its first step), NumPy over the batch with
        the operations of _follow, _keep_origin_near and local_rays step by step (the same bits)."""
        t, i = b.table, self.follow
        world = np.column_stack([t.x[:, i], t.y[:, i]])
        rel = np.column_stack([t.rx[:, i], t.ry[:, i]])
        move = rel - np.vstack([st.bed_rel[None, :2], rel[:-1]])
        vel = np.column_stack([t.vx[:, i], t.vy[:, i]])
        speed = np.hypot(vel[:, 0], vel[:, 1])
        moving = speed > 1e-9
        lead = np.empty_like(vel)
        lead[moving] = vel[moving] / speed[moving, None]
        last = np.maximum.accumulate(np.where(moving, np.arange(len(rel)), -1))  # kept while standing
        lead[~moving] = np.where((last[~moving] >= 0)[:, None], lead[np.maximum(last[~moving], 0)], st.lead)
        shift, moved = self._shifts(st.shift, rel)
        local = rel - shift
        rays = None
        if self.n_tires and b.rows is not None:
            park_z = st.bed_center[2] - st.origin[2] + 1000.0
            rays = batch_local_rays(b.rows, b.far, shift, local, park_z)
        bodies = start = None
        if self.targets:  # st.poses: the poses before the batch's first step
            bodies = batch_pose_rows(st.poses, t, self.targets, shift)
            start = np.array(b.times) - b.dt  # the clock before each step: time - dt, as step by step
        return Frames(world, rel, move, lead, shift, moved, local, rays, b.dt, bodies, start)

    def _shifts(self, shift0: np.ndarray, rel: np.ndarray) -> tuple:
        """The origin's shift at each step of a batch from ``shift0`` (_keep_origin_near step by step): (K, 2)
        shifts and, per step, its move (None where it stayed)."""
        k = len(rel)
        shift = np.empty((k, 2))
        moved = [None] * k
        cur, start = np.asarray(shift0, np.float64), 0
        while start < k:
            far = np.max(np.abs(rel[start:] - cur), axis=1) > ORIGIN_RANGE if self.floating else None
            if far is None or not far.any():
                shift[start:] = cur
                break
            j = start + int(np.argmax(far))
            shift[start:j] = cur
            new = snapped(rel[j])
            moved[j] = new - cur
            cur = shift[j] = new
            start = j + 1
        return shift, moved

    def _follow(self, st: HostState, pose) -> np.ndarray:
        """Move the bed under the followed vehicle (``pose``) and turn its leading edge to the vehicle's travel
        (kept while the vehicle stands); return the bed's move (XY), anchor-relative: the same bits wherever
        the scene is."""
        c, rel = pose.position, pose.rel[:2]
        move = rel - st.bed_rel
        st.bed_center = np.array([c[0], c[1], st.bed_center[2]])
        st.bed_rel = rel.copy()
        lead = pose.velocity[:2]
        if np.hypot(*lead) > 1e-9:
            st.lead = lead / np.hypot(*lead)
        return move

    def _keep_origin_near(self, st: HostState):
        """With ``origin = "floating"``: once the bed centre is farther than ORIGIN_RANGE from the origin, move
        the shift to the snapped point nearest it; return the (exact, whole multiples of ORIGIN_SNAP) move of
        the local frame, or None."""
        rel = st.bed_rel
        if self.floating and np.max(np.abs(rel - st.shift)) > ORIGIN_RANGE:
            new = snapped(rel)
            moved = new - st.shift
            st.set_shift(new)
            return moved
        return None

    def ray_data(self, st: HostState, prev, cur, dt: float = 0.0) -> np.ndarray:
        """The rays of every splashing rear tire, float64 (T, RAY_FIELDS) in the World.ray layout, in the
        kernels' frame; ``prev`` and ``cur`` are relative to the anchor (``Fleet.rear_tires(relative=True)``)."""
        if self.n_tires == 0:
            return np.zeros((1, RAY_FIELDS))
        return self.local_rays(st, *ray_rows(prev, cur, dt, st.bed_rel, self.reach))

    def local_rays(self, st: HostState, rows, far) -> np.ndarray:
        """Ray rows relative to the anchor (``ray_rows``) in the kernels' frame now; the tires far from the bed
        parked high above it."""
        if rows is None:
            return np.zeros((1, RAY_FIELDS))
        lc = st.local_centre()
        park = np.array([lc[0], lc[1], st.bed_center[2] - st.origin[2] + 1000.0])
        return local_rays(rows, far, st.shift, park)


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


def batch_local_rays(rows: np.ndarray, far: np.ndarray, shift: np.ndarray, local: np.ndarray,
                     park_z: float) -> np.ndarray:
    """``local_rays`` of every step of a batch at once: rows (K, T, RAY_FIELDS) and far (K, T) of ``ray_rows``,
    the shift (K, 2) and the bed centre in the kernels' frame (K, 2) at each step; far tires parked at the
    local centre, ``park_z`` high."""
    k = len(shift)
    o = np.zeros((k, RAY_FIELDS))  # x - (+0.0) is x, bit for bit: the other columns are unchanged
    o[:, 0:12] = np.tile(np.column_stack([shift, np.zeros(k)]), 4)
    o[:, HULL:] = np.tile(shift, (RAY_FIELDS - HULL) // 2)
    data = rows - o[:, None, :]
    if far.any():
        park = np.column_stack([local, np.full(k, park_z)])
        kk = np.nonzero(far)[0]
        data[far, 0:12] = np.tile(park, 4)[kk]
        data[far, HULL:] = np.tile(local, (RAY_FIELDS - HULL) // 2)[kk]
        data[far, 17] = 0.0
    return data


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


class _Batch:
    """A lookahead batch: the steps' times, the fleet's PoseTable, the rear tires (K, T, ...), the ray rows and
    far flags (relative to the anchor; None without tires) and, once served, their Frames."""

    def __init__(self, times, dt, table, tires, rows, far, prev):
        self.times, self.dt, self.table, self.tires, self.rows, self.far = times, dt, table, tires, rows, far
        self.next = 0
        self.prev = prev  # the tires the next step's rays start from
        self.frames = None
        self.tire_arrays = tire_fields(tires)

    def tires_at(self, k: int) -> RearTires:
        return RearTires(*(a[k] for a in self.tire_arrays))


class Lookahead:
    """The next steps' host work of a fleet, computed at once and served one step at a time (module
    docstring). ``follow``: the vehicle the bed follows; ``rays``: compute ray rows (splashing tires);
    ``reach_m``: farther from the bed centre, a tire is parked."""

    def __init__(self, fleet, follow: int, rays: bool, reach_m: float, planned: bool = False):
        self.fleet, self.follow, self.rays, self.reach_m = fleet, follow, rays, reach_m
        self.planned = planned  # batches past the fleet's horizon (engine/livesteps.py: the scripted part only)
        self.batches = 0  # batches computed so far
        self._size = 1 << 30  # steps of the next batch (at most the lookahead asked for)
        self.clear()

    def clear(self) -> None:
        """Forget the batch (restore(), anything that changes the clock or the tires other than a step)."""
        self._batch = None

    def _continues(self, time: float, tires_prev: RearTires, dt: float) -> bool:
        """Whether the batch in hand serves the step ending at ``time``."""
        b = self._batch
        return not (b is None or b.next >= len(b.times) or b.dt != dt or b.times[b.next] != time
                    or b.prev is not tires_prev)

    def pays(self, time: float, tires_prev: RearTires, dt: float) -> bool:
        """Whether the step ending at ``time`` is better served by a batch than alone: a batch in hand continues,
        or a new one would hold at least two steps (the poses are final up to the fleet's horizon: the end of
        the advance under way with live vehicles; a batch of one step costs about twice the step alone)."""
        if self._continues(time, tires_prev, dt):
            return True
        end = self.fleet.horizon()
        return end == math.inf or time + dt <= end + clock_tolerance(end)

    def take(self, time: float, tires_prev: RearTires, dt: float, limit: int) -> tuple:
        """The step being taken: the clock already advanced by ``dt`` to ``time``, ``tires_prev`` the tires of
        the step before; a new batch holds at most ``limit`` steps (and BATCH_ROWS). Returns (batch, its row):
        the row's tires are ``batch.tires_at(row)``, which the next take() expects as ``tires_prev``."""
        b = self._batch
        if not self._continues(time, tires_prev, dt):
            if b is not None:  # a batch used up: the next twice as long; left early: as long as was used
                self._size = 2 * len(b.times) if b.next >= len(b.times) else b.next + 1
            b = self._batch = self._compute(time, tires_prev, dt, max(1, min(self._size, int(limit), BATCH_ROWS)))
        k = b.next
        b.next = k + 1
        b.prev = b.tires_at(k)
        return b, k

    def batch(self, time: float, tires_prev: RearTires, dt: float, steps: int) -> _Batch:
        """A new batch of ``steps`` steps from the one ending at ``time`` (tires before it: ``tires_prev``)."""
        return self._compute(time, tires_prev, dt, steps)

    def _compute(self, time: float, tires_prev: RearTires, dt: float, steps: int) -> _Batch:
        times = [time]
        end = math.inf if self.planned else self.fleet.horizon()  # live: no pose is known past the advance's end
        end += clock_tolerance(end) if end < math.inf else 0.0
        for _ in range(steps - 1):
            if times[-1] + dt > end:
                break
            times.append(times[-1] + dt)
        table = self.fleet.pose_table(times)
        cur = self.fleet.rear_tires_table(table)
        k, n = len(times), len(cur.spin[0])
        rows = far = None
        if self.rays:
            start = tire_fields(tires_prev)
            prev = RearTires(*(np.concatenate([p[None], c[:-1]]).reshape(k * n, *c.shape[2:])
                               for p, c in zip(start, tire_fields(cur))))
            flat = RearTires(*(c.reshape(k * n, *c.shape[2:]) for c in tire_fields(cur)))
            bed = np.repeat(np.column_stack([table.rx[:, self.follow], table.ry[:, self.follow]]), n, axis=0)
            rows, far = ray_rows(prev, flat, dt, bed, self.reach_m)
            rows, far = rows.reshape(k, n, RAY_FIELDS), far.reshape(k, n)
        self.batches += 1
        return _Batch(times, dt, table, cur, rows, far, tires_prev)
