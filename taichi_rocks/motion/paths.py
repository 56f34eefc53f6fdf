"""Scripted paths of a vehicle's body centre in the XY ground plane (host side, NumPy/SciPy only).

Geometry (waypoints, ``smooth=True``): a C2 cubic spline r(u) = (x(u), y(u)) through the points,
parametrised by chord length (u_0 = 0, u_{i+1} = u_i + |p_{i+1} - p_i|), natural end conditions for
open paths, periodic ones for loops (closed by repeating the first point).  Arc length
s(u) = int_0^u |r'(w)| dw is tabulated once (Gauss-Legendre) and inverted by monotone cubic Hermite
interpolation (du/ds = 1/|r'|), refined until accurate to ~1e-8 m.  Heading = atan2(y', x'), curvature
kappa = (x' y'' - y' x'') / |r'|^3, yaw rate = kappa * ds/dt.  ``smooth=False``: straight segments
(heading piecewise constant, kappa = 0).  Circles are closed forms (kappa = +-1/R).

Timing: speed v_i >= 0 at each waypoint, constant acceleration in time between consecutive
waypoints: a segment of arc length L goes from v0 to v1 in T = 2 L / (v0 + v1) with
a = (v1 - v0) / T, s(tau) = v0 tau + a tau^2 / 2.  v0 = v1 = 0 means the vehicle never gets past:
it stays parked there forever (``duration is None``).

Every pose is computed relative to the path's ``anchor`` (first point / circle centre) so that huge
world coordinates keep their precision: ``Pose.from_anchor`` is that relative position, and
``Pose.position = anchor + from_anchor``. The relative position depends only on the waypoints relative to
the first one (a circle's radius and angles), not on where the path is: a path moved by an offset its
waypoints take exactly gives the same bits (the simulation's floating origin relies on it).
``pose(t)`` only does bisections and closed forms; ``pose_values(t)`` gives the same as plain floats, and
``pose_values_many(times)`` the same bits at many times at once: the arithmetic with NumPy over the times (the
same operations in the same order), the transcendental functions (hypot, atan2, remainder, cos, sin) through
``math`` one time at a time, as ``pose_values`` calls them (NumPy's own may round differently).
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["Pose", "Path", "WaypointPath", "CirclePath", "path_from_spec", "sample"]

_TWO_PI = 2.0 * math.pi


def _wrap(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    a = math.remainder(a, _TWO_PI)
    return a + _TWO_PI if a <= -math.pi else a


@dataclass(frozen=True, eq=False)
class Pose:
    position: np.ndarray  # (2,) m
    heading: float        # rad in (-pi, pi], direction of the nose
    speed: float          # m/s along the heading (negative when driving backwards)
    yaw_rate: float       # rad/s, d(heading)/dt
    velocity: np.ndarray  # (2,) m/s = speed * (cos h, sin h)
    from_anchor: np.ndarray | None = None  # (2,) m, position - path.anchor as computed (None: not known)
    wheel_spin: float = math.nan  # rad/s of the rear wheels; NaN: rolling (motion/vehicles.py's rule)


class Path:
    """Base class: ``pose(t)`` (t in s, finite; t < 0 is clamped to 0) and ``duration``
    (time of one traversal = loop period; None if the vehicle never gets to the end)."""

    duration: float | None = None
    #: from this time on the pose never changes again (inf: it may always move)
    still_after: float = math.inf
    #: the world point the poses are computed from (None: poses give only world positions)
    anchor: tuple[float, float] | None = None

    def pose(self, t: float) -> Pose:
        raise NotImplementedError


class _Timing:
    """Arc length s(t) and speed v(t) >= 0 with constant acceleration between knots."""

    def __init__(self, S, V, loop: bool):
        S = [float(x) for x in S]
        V = [float(x) for x in V]
        Tc, A = [0.0], []
        for i in range(len(S) - 1):
            L, v0, v1 = S[i + 1] - S[i], V[i], V[i + 1]
            if v0 + v1 <= 0.0:  # never gets past knot i: parked there forever
                break
            T = 2.0 * L / (v0 + v1)
            Tc.append(Tc[-1] + T)
            A.append((v1 - v0) / T if T > 0.0 else 0.0)
        self.S, self.V, self.Tc, self.A = S, V, Tc, A
        self.parked = len(A) < len(S) - 1
        self.s_end, self.t_end = S[len(A)], Tc[-1]
        self.period = Tc[-1] if (loop and not self.parked and Tc[-1] > 0.0) else None

    @property
    def duration(self) -> float | None:
        return None if self.parked else self.t_end

    def at_many(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``at`` of each of ``t`` (float64 array), the same bits."""
        s, v = np.full(t.shape, self.S[0]), np.full(t.shape, self.V[0])
        mid = t > 0.0
        tt = t
        if self.period is not None:
            tt = np.fmod(t, self.period)
        else:
            end = mid & (t >= self.t_end)
            s[end], v[end] = self.s_end, 0.0
            mid &= ~end
        if mid.any():
            x = tt[mid]
            i = np.minimum(np.searchsorted(self.Tc, x, side="right") - 1, len(self.A) - 1)
            S, V, A = np.asarray(self.S), np.asarray(self.V), np.asarray(self.A)
            tau, v0, a = x - np.asarray(self.Tc)[i], V[i], A[i]
            s[mid] = np.minimum(S[i] + tau * (v0 + 0.5 * a * tau), S[i + 1])
            v[mid] = np.maximum(v0 + a * tau, 0.0)
        return s, v

    def at(self, t: float) -> tuple[float, float]:
        if t <= 0.0:  # the start, with its speed
            return self.S[0], self.V[0]
        if self.period is not None:
            t = math.fmod(t, self.period)
        elif t >= self.t_end:
            return self.s_end, 0.0
        i = min(bisect_right(self.Tc, t) - 1, len(self.A) - 1)
        tau, v0, a = t - self.Tc[i], self.V[i], self.A[i]
        s = min(self.S[i] + tau * (v0 + 0.5 * a * tau), self.S[i + 1])
        return s, max(v0 + a * tau, 0.0)


class _ProfiledPath(Path):
    """A curve given by arc length (subclass ``_geom``) driven by a ``_Timing``."""

    _origin: tuple[float, float]
    _timing: _Timing
    _reverse: bool

    @property
    def anchor(self) -> tuple[float, float]:
        """The world point the poses are computed from (first waypoint, circle centre), exactly as given."""
        return self._origin

    def _geom(self, s: float) -> tuple[float, float, float, float]:
        """Local (x, y), tangent angle, signed curvature at arc length s."""
        raise NotImplementedError

    def _geom_many(self, s: np.ndarray) -> tuple:
        """``_geom`` at each of ``s`` as arrays (subclasses do it with NumPy, the same bits)."""
        return tuple(np.array(c, dtype=np.float64) for c in zip(*(self._geom(float(x)) for x in s)))

    @property
    def duration(self) -> float | None:  # type: ignore[override]
        return self._timing.duration

    @property
    def still_after(self) -> float:  # type: ignore[override]
        """At the end of a path that does not loop (or where it parks) the vehicle stops for good."""
        tm = self._timing
        return math.inf if tm.period is not None else tm.t_end

    def pose_values(self, t: float) -> tuple[float, float, float, float, float, float, float]:
        """``pose(t)`` as plain floats (the same bits, none of the arrays): from_anchor x, y, heading, speed,
        yaw rate, velocity x, y."""
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f"pose time must be finite, got {t}")
        s, v = self._timing.at(t)
        x, y, tangent, kappa = self._geom(s)
        yaw = kappa * v if v > 0.0 else 0.0
        if self._reverse:
            tangent, v = tangent + math.pi, -v if v > 0.0 else 0.0
        h = _wrap(tangent)
        return x, y, h, v, yaw, v * math.cos(h), v * math.sin(h)

    def pose_values_many(self, times) -> np.ndarray:
        """``pose_values`` at each of ``times``, (K, 7) float64, the same bits (module docstring)."""
        t = np.array(times, dtype=np.float64).ravel()
        if not np.all(np.isfinite(t)):
            raise ValueError(f"pose time must be finite, got {t[~np.isfinite(t)][0]}")
        s, v = self._timing.at_many(t)
        x, y, tangent, kappa = self._geom_many(s)
        yaw = np.where(v > 0.0, kappa * v, 0.0)
        if self._reverse:
            tangent, v = tangent + math.pi, np.where(v > 0.0, -v, 0.0)
        h = np.array([_wrap(a) for a in tangent.tolist()])
        cos = np.array([math.cos(a) for a in h.tolist()])
        sin = np.array([math.sin(a) for a in h.tolist()])
        return np.column_stack([x, y, h, v, yaw, v * cos, v * sin])

    def pose(self, t: float) -> Pose:
        x, y, h, v, yaw, vx, vy = self.pose_values(t)
        return Pose(np.array([self._origin[0] + x, self._origin[1] + y]), h, v, yaw, np.array([vx, vy]),
                    np.array([x, y]))


def _speeds(speed, n: int) -> np.ndarray:
    v = np.asarray(speed, dtype=np.float64)
    v = np.full(n, float(v)) if v.ndim == 0 else v
    if v.shape != (n,):
        raise ValueError(f"speed must be a number or one value per waypoint ({n}), got shape {v.shape}")
    if not np.all(np.isfinite(v)) or np.any(v < 0.0):
        raise ValueError("speeds must be finite and >= 0")
    return v


class WaypointPath(_ProfiledPath):
    """Path through waypoints: C2 chord-length spline (``smooth``) or straight segments.

    ``speed``: constant >= 0 or one value per waypoint (constant acceleration in between).
    ``loop``: closed path (back to the first point), repeating with period ``duration``;
    a last point equal to the first is dropped (with its speed).  ``reverse``: same positions,
    driven backwards (heading = tangent + pi, negative speed).
    """

    GL_NODES, GL_WEIGHTS = np.polynomial.legendre.leggauss(5)

    def __init__(self, points, speed, *, loop: bool = False, smooth: bool = True, reverse: bool = False):
        P = np.array(points, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 2 or len(P) < 2 or not np.all(np.isfinite(P)):
            raise ValueError("points must be >= 2 finite [x, y] pairs")
        v = _speeds(speed, len(P))
        if loop and len(P) > 2 and np.array_equal(P[0], P[-1]):
            P, v = P[:-1], v[:-1]
        self.points, self.loop, self.smooth, self._reverse = P, bool(loop), bool(smooth), bool(reverse)
        self._origin = (float(P[0, 0]), float(P[0, 1]))
        Q = P - P[0]
        if loop:
            Q, v = np.vstack([Q, Q[:1]]), np.append(v, v[0])
        chord = np.hypot(*np.diff(Q, axis=0).T)
        if np.any(chord <= 0.0):
            raise ValueError("two consecutive waypoints are equal")
        if smooth and loop and len(P) < 3:
            raise ValueError("a smooth loop needs >= 3 distinct points")
        S = self._build_spline(Q, chord) if smooth else self._build_polyline(Q, chord)
        self.arc_lengths = S  # arc length at each waypoint (plus the closing point for loops)
        self.length = float(S[-1])
        self._timing = _Timing(S, v, self.loop)

    def _build_polyline(self, Q, chord) -> np.ndarray:
        S = np.concatenate([[0.0], np.cumsum(chord)])
        self._S, self._Q = S.tolist(), Q.tolist()
        d = np.diff(Q, axis=0)
        self._seg_heading = np.arctan2(d[:, 1], d[:, 0]).tolist()
        self._geom, self._geom_many = self._geom_polyline, self._geom_polyline_many
        return S

    def _build_spline(self, Q, chord) -> np.ndarray:
        u = np.concatenate([[0.0], np.cumsum(chord)])
        cs = CubicSpline(u, Q, axis=0, bc_type="periodic" if self.loop else "natural")
        speed_at = lambda x: np.linalg.norm(cs(x, 1), axis=-1)  # |r'(u)|

        def arc(a, b):  # 5-point Gauss-Legendre of |r'| on each [a, b]
            q = a[:, None] + 0.5 * (b - a)[:, None] * (self.GL_NODES[None, :] + 1.0)
            return 0.5 * (b - a) * (speed_at(q.ravel()).reshape(q.shape) @ self.GL_WEIGHTS)

        # Table u_k -> s_k, refined per spline segment until the Hermite inverse u(s) is accurate:
        # at each sub-interval's midpoint, |s(u_hermite(s_mid)) - s_mid| < tol.
        tol = 1e-8 * max(1.0, float(u[-1]) * 1e-3)
        m = np.full(len(chord), int(np.clip(200_000 // len(chord), 1, 8)))
        while True:
            seg = np.repeat(np.arange(len(chord)), m)
            frac = np.arange(len(seg)) - np.repeat(np.cumsum(m) - m, m)
            uu = np.append(u[seg] + chord[seg] * frac / m[seg], u[-1])
            h = arc(uu[:-1], uu[1:])
            s = np.concatenate([[0.0], np.cumsum(h)])
            # monotone cubic Hermite for u(s): slope du/ds = 1/|r'|, limited to 3x the secants
            sec = np.diff(uu) / np.maximum(h, 1e-300)
            sp = speed_at(uu)
            slope = np.divide(1.0, sp, out=np.full_like(sp, np.inf), where=sp > 0.0)
            slope[:-1] = np.minimum(slope[:-1], 3.0 * sec)
            slope[1:] = np.minimum(slope[1:], 3.0 * sec)
            u_mid = 0.5 * (uu[:-1] + uu[1:]) + 0.125 * h * (slope[:-1] - slope[1:])
            err = np.abs(arc(uu[:-1], u_mid) - 0.5 * h)
            bad = np.zeros(len(chord), bool)
            bad[seg[err > tol]] = True
            if not bad.any() or len(seg) > 300_000:
                break
            m[bad] *= 4
        self._s_tab, self._u_tab, self._du_tab = s.tolist(), uu.tolist(), slope.tolist()
        self._seg, self._knots = seg.tolist(), u.tolist()
        c = cs.c  # (4, nseg, 2): coefficients of (u - u_k)^3 .. ^0
        self._coef = [tuple(c[:, k, :].T.ravel().tolist()) for k in range(len(chord))]
        self._geom, self._geom_many = self._geom_spline, self._geom_spline_many
        return s[np.concatenate([[0], np.cumsum(m)])]

    def _geom_polyline(self, s):
        S = self._S
        k = min(max(bisect_right(S, s) - 1, 0), len(S) - 2)
        L = S[k + 1] - S[k]
        w = min(max((s - S[k]) / L, 0.0), 1.0)
        (x0, y0), (x1, y1) = self._Q[k], self._Q[k + 1]
        return x0 + w * (x1 - x0), y0 + w * (y1 - y0), self._seg_heading[k], 0.0

    def _tables(self) -> dict:
        """The curve's tables as NumPy arrays (built once, for ``_geom_many``)."""
        if getattr(self, "_np", None) is None:
            names = ("_S", "_Q", "_seg_heading") if not self.smooth else (
                "_s_tab", "_u_tab", "_du_tab", "_seg", "_knots", "_coef")
            self._np = {n: np.asarray(getattr(self, n)) for n in names}
        return self._np

    def _geom_polyline_many(self, s):
        tab = self._tables()
        S = tab["_S"]
        k = np.minimum(np.maximum(np.searchsorted(S, s, side="right") - 1, 0), len(S) - 2)
        L = S[k + 1] - S[k]
        w = np.minimum(np.maximum((s - S[k]) / L, 0.0), 1.0)
        Q = tab["_Q"]
        x0, y0, x1, y1 = Q[k, 0], Q[k, 1], Q[k + 1, 0], Q[k + 1, 1]
        return x0 + w * (x1 - x0), y0 + w * (y1 - y0), tab["_seg_heading"][k], np.zeros(len(s))

    def _geom_spline_many(self, s):
        tab = self._tables()
        st, ut, dt = tab["_s_tab"], tab["_u_tab"], tab["_du_tab"]
        k = np.minimum(np.maximum(np.searchsorted(st, s, side="right") - 1, 0), len(st) - 2)
        h = st[k + 1] - st[k]
        pos = h > 0.0
        w = np.zeros(len(s))
        w[pos] = np.minimum(np.maximum((s[pos] - st[k][pos]) / h[pos], 0.0), 1.0)
        w2, w3 = w * w, w * w * w
        u = ((2 * w3 - 3 * w2 + 1) * ut[k] + (w3 - 2 * w2 + w) * h * dt[k]
             + (3 * w2 - 2 * w3) * ut[k + 1] + (w3 - w2) * h * dt[k + 1])
        u = np.minimum(np.maximum(u, ut[k]), ut[k + 1])
        seg = tab["_seg"][k]
        d = u - tab["_knots"][seg]
        ax, bx, cx, ex, ay, by, cy, ey = tab["_coef"][seg].T
        x = ((ax * d + bx) * d + cx) * d + ex
        y = ((ay * d + by) * d + cy) * d + ey
        x1, y1 = (3 * ax * d + 2 * bx) * d + cx, (3 * ay * d + 2 * by) * d + cy
        x2, y2 = 6 * ax * d + 2 * bx, 6 * ay * d + 2 * by
        n = np.array([math.hypot(a, b) for a, b in zip(x1.tolist(), y1.tolist())])
        kappa = np.zeros(len(s))
        big = n > 1e-12
        kappa[big] = (x1[big] * y2[big] - y1[big] * x2[big]) / (n[big] * n[big] * n[big])
        tangent = np.array([math.atan2(b, a) for a, b in zip(x1.tolist(), y1.tolist())])
        return x, y, tangent, kappa

    def _geom_spline(self, s):
        st, ut, dt = self._s_tab, self._u_tab, self._du_tab
        k = min(max(bisect_right(st, s) - 1, 0), len(st) - 2)
        h = st[k + 1] - st[k]
        w = min(max((s - st[k]) / h, 0.0), 1.0) if h > 0.0 else 0.0
        w2, w3 = w * w, w * w * w
        u = ((2 * w3 - 3 * w2 + 1) * ut[k] + (w3 - 2 * w2 + w) * h * dt[k]
             + (3 * w2 - 2 * w3) * ut[k + 1] + (w3 - w2) * h * dt[k + 1])
        u = min(max(u, ut[k]), ut[k + 1])
        seg = self._seg[k]
        d = u - self._knots[seg]
        ax, bx, cx, ex, ay, by, cy, ey = self._coef[seg]
        x = ((ax * d + bx) * d + cx) * d + ex
        y = ((ay * d + by) * d + cy) * d + ey
        x1, y1 = (3 * ax * d + 2 * bx) * d + cx, (3 * ay * d + 2 * by) * d + cy
        x2, y2 = 6 * ax * d + 2 * bx, 6 * ay * d + 2 * by
        n = math.hypot(x1, y1)
        kappa = (x1 * y2 - y1 * x2) / (n * n * n) if n > 1e-12 else 0.0
        return x, y, math.atan2(y1, x1), kappa


class CirclePath(_ProfiledPath):
    """Circle (or arc) at constant speed; angles in radians.

    Starts at ``center + radius (cos a0, sin a0)``, counter-clockwise unless ``clockwise``, and
    covers ``sweep`` rad (> 2 pi = several laps).  ``loop=True`` restarts from the start every
    ``duration`` (seamless for a full circle; an arc jumps back to its start).  ``loop=False``
    parks at the end of the sweep.
    """

    def __init__(self, center, radius: float, speed: float, *, clockwise: bool = False,
                 start_angle: float = 0.0, sweep: float = _TWO_PI, loop: bool = True, reverse: bool = False):
        c = np.asarray(center, dtype=np.float64)
        if c.shape != (2,) or not np.all(np.isfinite(c)):
            raise ValueError("center must be a finite [x, y]")
        if not (math.isfinite(radius) and radius > 0.0):
            raise ValueError("radius must be > 0")
        if not (math.isfinite(sweep) and sweep > 0.0):
            raise ValueError("sweep must be > 0")
        if not (math.isfinite(start_angle)):
            raise ValueError("start_angle must be finite")
        v = float(_speeds(speed, 2)[0])
        self.center, self.radius, self.sweep = c, float(radius), float(sweep)
        self.start_angle, self.clockwise, self.loop = float(start_angle), bool(clockwise), bool(loop)
        self._origin, self._reverse = (float(c[0]), float(c[1])), bool(reverse)
        self._sign = -1.0 if clockwise else 1.0
        self.length = self.radius * self.sweep
        self._timing = _Timing([0.0, self.length], [v, v], self.loop)

    def _geom(self, s):
        a = self.start_angle + self._sign * s / self.radius
        R = self.radius
        return R * math.cos(a), R * math.sin(a), a + self._sign * 0.5 * math.pi, self._sign / R

    def _geom_many(self, s):
        a = self.start_angle + self._sign * s / self.radius
        R = self.radius
        cos = np.array([math.cos(x) for x in a.tolist()])
        sin = np.array([math.sin(x) for x in a.tolist()])
        return R * cos, R * sin, a + self._sign * 0.5 * math.pi, np.full(len(s), self._sign / R)


def path_from_spec(kind: str, **kwargs) -> Path:
    """Build a path from a scene's ``[vehicle.path]`` table (circle angles in degrees); the live and recorded
    kinds are motion/live.py's (motion/vehicles.py builds them)."""
    if kind == "waypoints":
        return WaypointPath(**kwargs)
    if kind == "circle":
        for key in ("start_angle", "sweep"):
            if key in kwargs:
                kwargs[key] = math.radians(kwargs[key])
        return CirclePath(**kwargs)
    raise ValueError(f"path kind must be 'waypoints' or 'circle', got {kind!r}")


def sample(path: Path, times) -> dict:
    """Poses at ``times`` as arrays: t, position (T, 2), heading, speed, yaw_rate, velocity (T, 2)."""
    times = np.asarray(times, dtype=np.float64).ravel()
    poses = [path.pose(t) for t in times]
    return {
        "t": times,
        "position": np.array([p.position for p in poses]).reshape(-1, 2),
        "heading": np.array([p.heading for p in poses]),
        "speed": np.array([p.speed for p in poses]),
        "yaw_rate": np.array([p.yaw_rate for p in poses]),
        "velocity": np.array([p.velocity for p in poses]).reshape(-1, 2),
    }
