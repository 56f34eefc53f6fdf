"""Vehicles on their scripted paths: body pose and rear-tire rays, on the host (a few vehicles).

Positions come in two frames: world (``position``) and relative to the fleet's ``anchor`` (``rel``; the
simulation's floating origin is the anchor plus whole steps). ``rel`` is the path's own relative position
(``Pose.from_anchor``) plus the constant (path anchor - fleet anchor), never the difference of two large
world coordinates: moving a whole scene changes ``rel`` only by the rounding of the moved waypoints
themselves (~1e-16 of their distance from the world origin; none when the offset is exact in them).

A rear wheel sits at body offset (-wheelbase/2, +-track/2). Its rigid-body velocity is
v_wheel = v_body + yaw_rate * z x r_wheel, so the rear wheels of a turning vehicle slide outwards (the path
steers the body centre). Its tread speed is omega R = (v_wheel . heading) * (1 + slip), or, where the pose
gives the rear wheels' spin omega (a live vehicle driven with ``wheel_spin``: a burnout), omega R.

Poses come from each vehicle's path: a scripted one (motion/paths.py) or a track of keyframes (motion/live.py:
``kind = "live"``, driven by the game, and ``kind = "recorded"``). ``bind`` tells the live ones that an advance
from t0 to t1 starts (their pending ``drive()`` poses get their times), ``horizon`` is the time up to which every
pose is final (the engine plans its steps no further ahead, engine/host.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from .live import LivePath
from .paths import path_from_spec


@dataclass(frozen=True)
class VehiclePose:
    name: str
    position: np.ndarray  # (3,) world, body centre at ground level
    heading: float
    speed: float
    yaw_rate: float
    velocity: np.ndarray  # (3,)
    rel: np.ndarray | None = None  # (3,) position - (fleet anchor, 0), computed without world coordinates
    wheel_spin: float = math.nan  # rad/s of the rear wheels; NaN: rolling (the module docstring's rule)


@dataclass(frozen=True)
class RearTires:
    """Rear tires of the splashing vehicles, float64 (world frame, or relative to the fleet's anchor); one row
    per tire."""

    center: np.ndarray  # (T, 3)
    bottom: np.ndarray  # (T, 3)
    velocity: np.ndarray  # (T, 3)
    forward: np.ndarray  # (T, 2) unit heading
    spin: np.ndarray  # (T,) omega * R, signed
    half_width: np.ndarray  # (T,) half the tread's width, m
    half_length: np.ndarray  # (T,) half the contact patch's length, m
    radius: np.ndarray  # (T,) tire radius, m
    fender: np.ndarray  # (T,) fender angle, rad up the back of the tire
    flap: np.ndarray  # (T,) mud flap's lower edge above the ground, m; -1: no mud flap


def tire_fields(tires: RearTires) -> list[np.ndarray]:
    """The arrays of ``tires`` in field order (``RearTires(*tire_fields(t))`` is ``t`` again)."""
    return [getattr(tires, f.name) for f in fields(RearTires)]


@dataclass(frozen=True)
class PoseTable:
    """Every vehicle's pose at each of a few times, float64 (K, V) arrays with the bits of ``Fleet.poses``:
    world position (x, y), position relative to the fleet's anchor (rx, ry), heading, speed, yaw rate,
    velocity (vx, vy) and the rear wheels' spin (``wheel_spin``, rad/s; NaN: rolling)."""

    x: np.ndarray
    y: np.ndarray
    rx: np.ndarray
    ry: np.ndarray
    heading: np.ndarray
    speed: np.ndarray
    yaw_rate: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    wheel_spin: np.ndarray | None = None  # None: every wheel rolls


class TablePoses(Sequence):
    """Row ``k`` of a PoseTable as the list ``Fleet.poses`` gives (VehiclePose objects, built when read)."""

    def __init__(self, fleet: "Fleet", table: PoseTable, k: int):
        self._fleet, self._table, self._k = fleet, table, k
        self._built: dict = {}

    def __len__(self) -> int:
        return len(self._fleet.specs)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = range(len(self))[i]
        if i not in self._built:
            t, k, z = self._table, self._k, self._fleet.ground_z
            self._built[i] = VehiclePose(
                self._fleet.specs[i].name, np.array([t.x[k, i], t.y[k, i], z]), float(t.heading[k, i]),
                float(t.speed[k, i]), float(t.yaw_rate[k, i]), np.array([t.vx[k, i], t.vy[k, i], 0.0]),
                np.array([t.rx[k, i], t.ry[k, i], z]), math.nan if t.wheel_spin is None else float(t.wheel_spin[k, i]))
        return self._built[i]


def _path_of(spec):
    """The path of a scene's ``[vehicle.path]`` table: scripted (motion/paths.py) or a track (motion/live.py)."""
    if spec.kind == "live":
        return LivePath.starting(spec.start, math.radians(spec.heading), spec.speed)
    if spec.kind == "recorded":
        return LivePath(spec.rows, live=False)
    data = spec.model_dump()
    kind = data.pop("kind")
    return path_from_spec(kind, **data)


class Fleet:
    def __init__(self, scene):
        self.specs = tuple(scene.vehicles)
        self.names = [v.name for v in self.specs]
        self.ground_z = float(scene.world.ground_z)
        self.paths = [_path_of(v.path) for v in self.specs]
        self.live = [i for i, p in enumerate(self.paths) if getattr(p, "live", False)]  # driven by the game
        self.splashing = [i for i, v in enumerate(self.specs) if v.splash]
        # per vehicle: half tread width, half contact length, tire radius, fender angle (rad), flap edge
        self._tread = [(0.5 * v.tire_width, 0.5 * v.contact_length, v.tire_radius, math.radians(v.fender_angle),
                        v.mud_flap_clearance if v.mud_flaps else -1.0) for v in self.specs]
        self.anchor = np.zeros(2)  # world XY point that ``VehiclePose.rel`` is measured from

    def reference_point(self, i: int) -> np.ndarray:
        """The world XY point vehicle i's path computes its poses from (first waypoint, circle centre; its
        position at t = 0 for a path without one)."""
        path = self.paths[i]
        a = getattr(path, "anchor", None)
        return np.array(a if a is not None else path.pose(0.0).position[:2], dtype=np.float64)

    def _relative(self, path, pose) -> np.ndarray:
        a, loc = getattr(path, "anchor", None), getattr(pose, "from_anchor", None)
        if a is None or loc is None:
            return np.array([pose.position[0] - self.anchor[0], pose.position[1] - self.anchor[1], self.ground_z])
        return np.array([(a[0] - self.anchor[0]) + loc[0], (a[1] - self.anchor[1]) + loc[1], self.ground_z])

    def still_after(self, indices) -> float:
        """Time from which the vehicles ``indices`` never move again (0 for none; inf if one always may)."""
        return max((float(getattr(self.paths[i], "still_after", math.inf)) for i in indices), default=0.0)

    def bind(self, t0: float, t1: float) -> None:
        """An advance of the clock from t0 to t1 starts: the live vehicles' pending drive() poses get their times
        (motion/live.py ``LivePath.bind``)."""
        for i in self.live:
            self.paths[i].bind(t0, t1)

    def horizon(self) -> float:
        """The time up to which every vehicle's pose is final (inf without live vehicles)."""
        return min((self.paths[i].horizon for i in self.live), default=math.inf)

    def poses(self, t: float) -> list[VehiclePose]:
        out = []
        for spec, path in zip(self.specs, self.paths):
            p = path.pose(t)
            vel = np.array([p.velocity[0], p.velocity[1], 0.0])
            out.append(VehiclePose(spec.name, np.array([p.position[0], p.position[1], self.ground_z]),
                                   float(p.heading), float(p.speed), float(p.yaw_rate), vel,
                                   self._relative(path, p), float(p.wheel_spin)))
        return out

    def pose_table(self, times) -> PoseTable:
        """The poses at each of ``times`` (K), the same bits as ``poses(t)`` for each t."""
        cols = []
        for path in self.paths:
            a = getattr(path, "anchor", None)
            if hasattr(path, "pose_values_many") and a is not None:  # a profiled path: NumPy over the times
                v = path.pose_values_many(times)
                cols.append((a[0] + v[:, 0], a[1] + v[:, 1], (a[0] - self.anchor[0]) + v[:, 0],
                             (a[1] - self.anchor[1]) + v[:, 1], *v[:, 2:].T, np.full(len(v), math.nan)))
                continue
            rows = [self._values(path, t) for t in times]
            cols.append(tuple(np.array(rows, dtype=np.float64).reshape(-1, 10).T))
        k = len(times)
        return PoseTable(*(np.array([c[q] for c in cols]).reshape(-1, k).T.copy() for q in range(10)))

    def _values(self, path, t: float) -> tuple:
        """A pose table's row entries of ``path`` at time t: x, y, rx, ry, heading, speed, yaw rate, vx, vy, wheel
        spin (``poses(t)``'s bits)."""
        p = path.pose(t)
        rel = self._relative(path, p)
        return (p.position[0], p.position[1], rel[0], rel[1], float(p.heading), float(p.speed), float(p.yaw_rate),
                p.velocity[0], p.velocity[1], float(p.wheel_spin))

    def poses_of(self, i: int, t: float) -> tuple:
        """Vehicle i's entries of a pose table's row at time t (the order of PoseTable's fields)."""
        return self._values(self.paths[i], t)

    def rear_tires_table(self, table: PoseTable) -> RearTires:
        """``rear_tires(poses, relative=True)`` at every time of ``table`` at once: arrays (K, T, ...), the
        same bits as the per-time call."""
        k = table.heading.shape[0]
        vi, bx, by, cz, slip, radius, tread = [], [], [], [], [], [], []
        for i in self.splashing:
            spec = self.specs[i]
            for side in (1.0, -1.0):
                vi.append(i)
                bx.append(-0.5 * spec.wheelbase)
                by.append(side * 0.5 * spec.track)
                cz.append(self.ground_z + spec.tire_radius)
                slip.append(1.0 + spec.slip)
                radius.append(spec.tire_radius)
                tread.append(self._tread[i])
        n = len(vi)
        bx, by, cz, slip = (np.array(a, dtype=np.float64) for a in (bx, by, cz, slip))
        h = table.heading[:, vi]
        c, s = np.cos(h), np.sin(h)
        r0, r1 = c * bx - s * by, s * bx + c * by
        yaw = table.yaw_rate[:, vi]
        vel = np.stack([table.vx[:, vi] + yaw * -r1, table.vy[:, vi] + yaw * r0], axis=-1)
        fwd = np.stack([c, s], axis=-1)
        spin = (vel[..., None, :] @ fwd[..., :, None])[..., 0, 0] * slip  # as vel @ fwd, tire by tire
        given = None if table.wheel_spin is None else table.wheel_spin[:, vi]
        if given is not None and not np.isnan(given).all():  # a live vehicle's wheels spinning as the game says
            spin = np.where(np.isnan(given), spin, given * np.array(radius, dtype=np.float64))
        centre = np.stack([table.rx[:, vi] + r0, table.ry[:, vi] + r1, np.tile(cz, (k, 1))], axis=-1)
        bottom = centre.copy()
        bottom[..., 2] = self.ground_z
        velocity = np.concatenate([vel, np.zeros((k, n, 1))], axis=-1)
        tread = np.tile(np.array(tread, dtype=np.float64).reshape(1, n, 5), (k, 1, 1))
        return RearTires(centre, bottom, velocity, fwd, spin, *(tread[..., q] for q in range(5)))

    def rear_tires(self, poses: list[VehiclePose], relative: bool = False, vehicles=None) -> RearTires:
        """The rear tires in world coordinates, or (``relative``) relative to the fleet's anchor; ``vehicles``:
        only those of these (splashing) vehicles."""
        rows = []
        for i in self.splashing if vehicles is None else [i for i in self.splashing if i in vehicles]:
            spec, pose = self.specs[i], poses[i]
            base = pose.rel if relative else pose.position
            c, s = np.cos(pose.heading), np.sin(pose.heading)
            fwd = np.array([c, s])
            for side in (1.0, -1.0):
                bx, by = -0.5 * spec.wheelbase, side * 0.5 * spec.track
                r = np.array([c * bx - s * by, s * bx + c * by])
                vel = pose.velocity[:2] + pose.yaw_rate * np.array([-r[1], r[0]])
                centre = np.array([base[0] + r[0], base[1] + r[1], self.ground_z + spec.tire_radius])
                spin = float(vel @ fwd) * (1.0 + spec.slip)
                if not math.isnan(pose.wheel_spin):  # a live vehicle's wheels spinning as the game says
                    spin = pose.wheel_spin * spec.tire_radius
                rows.append((centre, np.array([centre[0], centre[1], self.ground_z]),
                             np.array([vel[0], vel[1], 0.0]), fwd, spin, *self._tread[i]))
        if not rows:
            z, e = np.zeros((0, 3)), np.zeros(0)
            return RearTires(z, z, z, np.zeros((0, 2)), e, e, e, e, e, e)
        return RearTires(*(np.array([row[k] for row in rows]) for k in range(10)))
