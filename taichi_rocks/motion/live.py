"""Vehicles driven at run time: a track of keyframed poses that the game sets (``Simulation.drive``, a
``kind = "live"`` path) or that a recorded drive replays (``kind = "recorded"``, config/drivefile.py), with the
pose at any time between them. One pose supplier beside the scripted paths (motion/paths.py): the engine asks it
``pose(t)`` as it asks them, and plans tire rays from it the same way.

Keyframe k: time t_k, world position p_k, heading h_k, speed v_k (signed, along the heading), yaw rate w_k and
the rear wheels' spin s_k (rad/s; NaN: rolling, the engine's rule). Between two keyframes, over T = t_1 - t_0
and s = (t - t_0) / T in (0, 1), with the cubic Hermite basis h00 = 2s^3 - 3s^2 + 1, h10 = s^3 - 2s^2 + s,
h01 = -2s^3 + 3s^2, h11 = s^3 - s^2 and V_k = v_k (cos h_k, sin h_k):

  position   p(s) = p_0 + h01 (p_1 - p_0) + T (h10 V_0 + h11 V_1)           (C1: the tires sweep continuously)
  velocity   p'(s) / T (the body's motion: it may slide sideways); speed = velocity . (cos h, sin h)
  heading    h(s) = wrap(h_0 + h01 wrap(h_1 - h_0) + T (h10 w_0 + h11 w_1)); yaw rate h'(s) / T
  wheel spin s_1 over (t_0, t_1] (the spin given with a pose holds from the pose before it)

At a keyframe's own time (within the clock's tolerance, 1e-9 max(1, t): the tolerance of ``advance_to``) the pose
is the keyframe's values themselves, with velocity v (cos h, sin h): a vehicle driven with a scripted path's
poses at its step times gets that path's bits. Before the first keyframe and after the last the vehicle goes
straight on at that keyframe's heading and speed (yaw rate 0): without any ``drive()`` a live vehicle keeps its
start heading at its start speed.

A jump (a teleport, a respawn): a segment over which the vehicle moves farther than its speeds allow,
|p_1 - p_0| > 2 max(|v_0|, |v_1|) T + JUMP_SLACK. The vehicle is then at the new pose from the first instant after
t_0 (coming straight back from p_1 along V_1), so the tire rays see a jump (engine/host.py ``ray_rows``: a tire that
moved much farther than its speed allows did not sweep the ground in between) and no streak of launches is
swept along it, as for a scripted path that jumps.

Live keyframes come from ``drive()`` poses, bound to a time at the start of the advance they are for
(:meth:`LivePath.bind`): the pose asked for at the end of ``advance_to(t)`` gets time t. A speed or yaw rate not
given is derived from the motion, as a path derives them: the speed the mean velocity over the segment
along the new heading ((p_1 - p_0) / T . (cos h_1, sin h_1)), the yaw rate wrap(h_1 - h_0) / T; over a jump
the speed before it and yaw rate 0. A frame the game did not drive leaves the vehicle going straight on; the next
drive() starts from the pose it reached then (a keyframe is put there, and the segment up to it, recognised by
its bits, stays straight on). The keyframes written out (:meth:`LivePath.rows`) hold every value the engine used
and how each segment is driven follows from them alone, so a recorded drive replays with the same bits.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from typing import NamedTuple

import numpy as np

from .paths import Path, Pose, _wrap

__all__ = ["JUMP_SLACK", "DrivePose", "LivePath", "drive_pose", "clock_tolerance"]

JUMP_SLACK = 1.0  # m: a segment longer than twice what its speeds allow plus this is a jump (module docstring)
COLUMNS = 7  # t, x, y, heading, speed, yaw_rate, wheel_spin (config/drivefile.py COLUMNS)


def clock_tolerance(t: float) -> float:
    """The clock's tolerance at time t (s): Simulation.advance_to's."""
    return 1e-9 * max(1.0, abs(t))


class DrivePose(NamedTuple):
    """A pose the game asked for (``Simulation.drive``), not yet bound to a time: world x, y (m), heading
    (rad, wrapped), speed (m/s), yaw rate (rad/s), wheel spin (rad/s) (None: derive / roll) and ``at`` (s; None:
    the end of the next advance)."""

    x: float
    y: float
    heading: float
    speed: float | None
    yaw_rate: float | None
    wheel_spin: float | None
    at: float | None


def _number(name: str, what: str, value, optional: bool = False):
    if value is None and optional:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"drive({name!r}): {what} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"drive({name!r}): {what} must be finite, got {value!r}")
    return v


def drive_pose(name: str, position, heading, speed=None, yaw_rate=None, wheel_spin=None, at=None,
               now: float = 0.0) -> DrivePose:
    """The checked pose of ``Simulation.drive`` (its arguments), at simulation time ``now``.

    Raises:
        ValueError: naming the vehicle and the value: a position that is not two finite numbers, a non-finite
            heading, speed, yaw rate or wheel spin, a time ``at`` not after ``now``.
    """
    try:
        xy = [float(v) for v in np.asarray(position, dtype=np.float64).ravel()]
    except (TypeError, ValueError):
        raise ValueError(f"drive({name!r}): position must be (x, y) in metres, got {position!r}") from None
    if len(xy) != 2:
        raise ValueError(f"drive({name!r}): position must be (x, y) in metres, got {position!r}")
    if not all(math.isfinite(v) for v in xy):
        raise ValueError(f"drive({name!r}): position must be finite, got {position!r}")
    h = _number(name, "heading", heading)
    v, w, s = (_number(name, k, x, optional=True) for k, x in
               (("speed", speed), ("yaw_rate", yaw_rate), ("wheel_spin", wheel_spin)))
    t = _number(name, "at", at, optional=True)
    if t is not None and not t > now + clock_tolerance(now):
        raise ValueError(f"drive({name!r}): at = {t!r} s has already passed (the simulation is at {now!r} s)")
    return DrivePose(xy[0], xy[1], _wrap(h), v, w, s, t)


def _hermite(s: float) -> tuple:
    """The cubic Hermite basis at s and its derivative: (h00, h10, h01, h11), (h00', h10', h01', h11')."""
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2),
            (6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s))


HERMITE, JUMP, STRAIGHT = 0, 1, 2  # how a segment is driven: interpolated, a jump, straight on (no drive)


def _straight(r, t: float) -> tuple:
    """The pose values going straight on (or back) from keyframe ``r`` at its heading and speed to time t; yaw
    rate 0, its wheel spin."""
    t0, x, y, h, v, _, spin = r
    c, s = math.cos(h), math.sin(h)
    d = v * (t - t0)
    return x + d * c, y + d * s, h, v, 0.0, v * c, v * s, spin


def _straight_row(r, t: float) -> tuple:
    """The keyframe at time t of a vehicle going straight on from keyframe ``r``."""
    x, y, h, v, w, _, _, spin = _straight(r, t)
    return (t, x, y, h, v, w, spin)


def _between(r0, r1, t: float) -> tuple:
    """The pose values at time t between keyframes r0 and r1 (the Hermite interpolation of the module
    docstring)."""
    t0, x0, y0, h0, v0, w0, _ = r0
    t1, x1, y1, h1, v1, w1, spin = r1
    T = t1 - t0
    (a00, a10, a01, a11), (d00, d10, d01, d11) = _hermite((t - t0) / T)
    c0, s0, c1, s1 = math.cos(h0), math.sin(h0), math.cos(h1), math.sin(h1)
    dx, dy = x1 - x0, y1 - y0
    x = x0 + a01 * dx + T * (a10 * v0 * c0 + a11 * v1 * c1)
    y = y0 + a01 * dy + T * (a10 * v0 * s0 + a11 * v1 * s1)
    vx = (d01 * dx) / T + d10 * v0 * c0 + d11 * v1 * c1
    vy = (d01 * dy) / T + d10 * v0 * s0 + d11 * v1 * s1
    dh = _wrap(h1 - h0)
    h = _wrap(h0 + a01 * dh + T * (a10 * w0 + a11 * w1))
    w = (d01 * dh) / T + d10 * w0 + d11 * w1
    return x, y, h, vx * math.cos(h) + vy * math.sin(h), w, vx, vy, spin


def _jumps(r0, r1) -> bool:
    """Whether the segment r0 -> r1 (keyframes: t, x, y, heading, speed, ...) is a jump (module docstring)."""
    T = r1[0] - r0[0]
    d = math.hypot(r1[1] - r0[1], r1[2] - r0[2])
    return d > 2.0 * max(abs(r0[4]), abs(r1[4])) * T + JUMP_SLACK


def _segment(r0, r1) -> int:
    """How the segment r0 -> r1 is driven: STRAIGHT where r1 is, to the bit, where r0 goes straight on (a
    keyframe put where an undriven vehicle had got to: its poses in between were straight on, and a replay
    gives them again), else JUMP or HERMITE."""
    same = _straight_row(r0, r1[0])
    if all(a == b or (math.isnan(a) and math.isnan(b)) for a, b in zip(same, r1)):
        return STRAIGHT
    return JUMP if _jumps(r0, r1) else HERMITE


class LivePath(Path):
    """A vehicle's keyframed track (module docstring). ``rows``: (t, x, y, heading, speed, yaw_rate, wheel_spin)
    keyframes in increasing time (wheel_spin NaN: rolling); ``live``: the game may add keyframes (drive());
    a recorded drive is not live. ``anchor``: the first keyframe's position (the point its poses are measured
    from)."""

    def __init__(self, rows, live: bool = True):
        a = np.array(rows, dtype=np.float64).reshape(-1, COLUMNS)
        if not len(a):
            raise ValueError("a live path needs at least one pose")
        self.live = bool(live)
        self._rows = [tuple(float(v) for v in r) for r in a]
        self._times = [r[0] for r in self._rows]
        self._kind = [HERMITE] + [_segment(self._rows[k - 1], self._rows[k]) for k in range(1, len(self._rows))]
        self.anchor = (self._rows[0][1], self._rows[0][2])
        self.pending: DrivePose | None = None
        self.horizon = math.inf if not live else self._times[-1]  # poses up to this time can no longer change

    @classmethod
    def starting(cls, start, heading: float, speed: float) -> "LivePath":
        """A live path at ``start`` (world x, y, m) at t = 0, heading ``heading`` (rad), ``speed`` (m/s)."""
        return cls([(0.0, float(start[0]), float(start[1]), _wrap(float(heading)), float(speed), 0.0, math.nan)])

    # ------------------------------------------------------------------------------------------ reading
    def rows(self) -> np.ndarray:
        """The keyframes, (K, 7) float64: t, x, y, heading, speed, yaw_rate, wheel_spin (NaN: rolling)."""
        return np.array(self._rows, dtype=np.float64).reshape(-1, COLUMNS)

    @property
    def still_after(self) -> float:  # type: ignore[override]
        """A live vehicle may always move (the game drives it); a recorded one stops for good at its last pose
        if it stands there."""
        if self.live or self._rows[-1][4] != 0.0:
            return math.inf
        return self._times[-1]

    def pose(self, t: float) -> Pose:
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f"pose time must be finite, got {t}")
        x, y, h, v, w, vx, vy, spin = self.pose_values(t)
        return Pose(np.array([x, y]), h, v, w, np.array([vx, vy]),
                    np.array([x - self.anchor[0], y - self.anchor[1]]), spin)

    def pose_values(self, t: float) -> tuple:
        """x, y (world), heading, speed, yaw rate, velocity x, y, wheel spin (NaN: rolling) at time t."""
        times, k = self._times, bisect_left(self._times, t)
        if k < len(times) and times[k] - t <= clock_tolerance(times[k]):
            return self._at_key(k)
        if k > 0 and t - times[k - 1] <= clock_tolerance(times[k - 1]):
            return self._at_key(k - 1)
        if k == 0 or k == len(times):
            return _straight(self._rows[0 if k == 0 else -1], t)
        r0, r1 = self._rows[k - 1], self._rows[k]
        kind = self._kind[k]
        if kind == JUMP:
            return _straight(r1, t)
        if kind == STRAIGHT:
            return _straight(r0, t)
        return _between(r0, r1, t)

    def _at_key(self, k: int) -> tuple:
        _, x, y, h, v, w, spin = self._rows[k]
        return x, y, h, v, w, v * math.cos(h), v * math.sin(h), spin

    # ------------------------------------------------------------------------------------------ driving
    def bind(self, t0: float, t1: float) -> None:
        """An advance from clock t0 to t1 starts: the pending drive() pose becomes the keyframe at its time (the
        advance's end unless it named one); the keyframes after t0 (a pose set for later with ``at``, a future
        left by a restore) go first, and a keyframe is put at t0 where the vehicle got to if none is there. Poses
        up to t1 are final from here on (``horizon``). Where a pose set for later is cut away so, the segment up
        to t0 is the Hermite cubic to the pose reached, no longer the curve the vehicle took towards the pose cut
        away: a replay of the keyframes differs there (docs/drives.md)."""
        p, self.pending = self.pending, None
        if p is not None:
            tol = clock_tolerance(t0)
            x, y, h, v, w, _, _, spin = self.pose_values(t0)  # where it is: straight on, or on its way to a pose
            self._truncate(t0 + tol)
            if self._times[-1] < t0 - tol:  # no keyframe here: one where it got (straight on: _straight_row's)
                self._append((t0, x, y, h, v, w, spin))
            self._append(self._keyframe(p, t1 if p.at is None else p.at))
        self.horizon = t1

    def _keyframe(self, p: DrivePose, t: float) -> tuple:
        """The keyframe of pose ``p`` at time t: the speed and yaw rate not given derived (module docstring)."""
        r0 = self._rows[-1]
        T = t - r0[0]
        spin = math.nan if p.wheel_spin is None else p.wheel_spin
        v_guess = r0[4] if p.speed is None else p.speed
        jump = _jumps(r0, (t, p.x, p.y, p.heading, v_guess))
        v, w = p.speed, p.yaw_rate
        if v is None:
            v = r0[4] if jump else ((p.x - r0[1]) * math.cos(p.heading) + (p.y - r0[2]) * math.sin(p.heading)) / T
        if w is None:
            w = 0.0 if jump else _wrap(p.heading - r0[3]) / T
        return (t, p.x, p.y, p.heading, v, w, spin)

    def _append(self, row: tuple) -> None:
        self._kind.append(_segment(self._rows[-1], row))
        self._rows.append(row)
        self._times.append(row[0])

    def _truncate(self, t: float) -> None:
        """Drop the keyframes after time t (keeping the first)."""
        k = max(1, bisect_right(self._times, t))
        del self._rows[k:], self._times[k:], self._kind[k:]

    # ------------------------------------------------------------------------------------------ checkpoints
    def saved(self, t: float) -> np.ndarray:
        """What a checkpoint at time t keeps: the keyframes from the last one at or before t on (K, 7)."""
        k = max(0, bisect_right(self._times, t + clock_tolerance(t)) - 1)
        return self.rows()[k:]

    def load(self, rows: np.ndarray, t: float) -> None:
        """Back to a checkpoint at time t: its keyframes replace those from the first of them on (earlier ones,
        the past, stay where this track has them); a pending pose is dropped."""
        rows = np.asarray(rows, np.float64).reshape(-1, COLUMNS)
        self.pending, self.horizon = None, t
        if not len(rows):
            return
        keep = bisect_left(self._times, rows[0, 0])
        del self._rows[keep:], self._times[keep:], self._kind[keep:]
        for r in rows:
            row = tuple(float(v) for v in r)
            if self._rows:
                self._append(row)
            else:
                self._rows, self._times, self._kind = [row], [row[0]], [HERMITE]
