"""The NumPy reference of the swept sphere-hull test, independent of engine/impacts.py, and a driver of its kernel.

Reference: the distance from points to a convex hexahedron from its 8 corners alone, as the least distance to
its 12 triangles (closest point on a triangle by Voronoi regions, Ericson 2005, 5.1.5) and 0 inside (behind
the plane of every triangle); then the first root of the convex function
f(t) = dist(p0 + t (p1 - p0)) - r on [0, 1]: its minimum by golden-section search (f is convex: the distance to
a convex set along a line), then bisection on [0, argmin] where f changes sign.
"""

import numpy as np
import taichi as ti

from taichi_rocks.engine.impacts import swept_sphere_hull
from taichi_rocks.motion.bodies import FACE_CORNERS, hexahedron_planes

TRIANGLES = [(f[0], f[1], f[2]) for f in FACE_CORNERS] + [(f[0], f[2], f[3]) for f in FACE_CORNERS]
GOLD = (np.sqrt(5.0) - 1.0) / 2.0


def _dot(x, y):
    return np.einsum("ij,ij->i", x, y)


def closest_on_triangle(p, a, b, c):
    """(N, 3) closest points of triangles abc (each (N, 3) or (3,)) to points p (N, 3)."""
    a, b, c = (np.broadcast_to(x, p.shape) for x in (a, b, c))
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = _dot(ap, ab), _dot(ap, ac)
    d3, d4 = _dot(bp, ab), _dot(bp, ac)
    d5, d6 = _dot(cp, ab), _dot(cp, ac)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        on_ab = a + (d1 / (d1 - d3))[:, None] * ab
        on_ac = a + (d2 / (d2 - d6))[:, None] * ac
        w_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        on_bc = b + w_bc[:, None] * (c - b)
        den = va + vb + vc
        inner = a + (vb / den)[:, None] * ab + (vc / den)[:, None] * ac
    regions = [  # in Ericson's order: the first that applies
        ((d1 <= 0) & (d2 <= 0), a),
        ((d3 >= 0) & (d4 <= d3), b),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), on_ab),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), on_ac),
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), on_bc),
    ]
    out = inner
    for cond, pts in reversed(regions):  # the last applied is the first that applies
        out = np.where(cond[:, None], pts, out)
    return out


class Hull:
    """Convex hexahedra from their corners ((8, 3): one, or (N, 8, 3): one per point asked about): distance,
    closest point and inside, all from the 12 triangles."""

    def __init__(self, corners):
        self.corners = np.asarray(corners, np.float64)
        c = self.corners if self.corners.ndim == 3 else self.corners[None]
        centre = c.mean(axis=1)
        # inside: behind the plane of each of the 12 triangles, each oriented away from the centre
        self._tri = [tuple(c[:, t[q]] for q in range(3)) for t in TRIANGLES]
        self._planes = []
        for a, b, cc in self._tri:
            n = np.cross(b - a, cc - a)
            n *= np.sign(_dot(n, a - centre))[:, None]
            self._planes.append((n, _dot(n, a)))
        # the same, stacked over the 12 triangles ((12, M, 3), M = 1 or N): one vectorised pass over all of them
        self._abc = [np.stack([t[q] for t in self._tri]) for q in range(3)]
        self._normals = np.stack([n for n, _ in self._planes])
        self._offsets = np.stack([off for _, off in self._planes])

    def closest(self, p):
        """(distance to the surface, closest surface point) for points p (N, 3): the nearest of the 12
        triangles, the first of them in their order on a tie. Several triangles go through NumPy in one pass
        (all 12 for a small batch, where the calls' overhead is what costs; fewer for a large one)."""
        p = np.atleast_2d(np.asarray(p, np.float64))
        n, rows = len(p), np.arange(len(p))
        best, where = np.full(n, np.inf), np.zeros_like(p)
        group = max(1, min(len(TRIANGLES), 4096 // max(n, 1)))
        for s in range(0, len(TRIANGLES), group):
            abc = [x[s:s + group] for x in self._abc]
            shape = (len(abc[0]), n, 3)
            a, b, c = (np.broadcast_to(x, shape).reshape(-1, 3) for x in abc)
            q = closest_on_triangle(np.broadcast_to(p, shape).reshape(-1, 3), a, b, c).reshape(shape)
            dd = np.sum((p - q) ** 2, axis=2)
            dd[np.isnan(dd)] = np.inf  # a triangle without a defined distance (degenerate) is never the nearest
            k = np.argmin(dd, axis=0)
            near = dd[k, rows]
            take = near < best
            best[take], where[take] = near[take], q[k, rows][take]
        return np.sqrt(best), where

    def take(self, idx) -> "Hull":
        """The hull of the points ``idx`` asked about (itself if it is one hexahedron for all)."""
        return Hull(self.corners[idx]) if self.corners.ndim == 3 else self

    def distance(self, p):
        p = np.atleast_2d(np.asarray(p, np.float64))
        d, _ = self.closest(p)
        inside = np.all(np.sum(p * self._normals, axis=2) <= self._offsets, axis=0)
        return np.where(inside, 0.0, d)


def _golden_min(f, lo, hi, iters):
    """Per path, the least value of the convex f on [lo, hi] and where it is (golden-section search)."""
    lo, hi = np.array(lo, np.float64), np.array(hi, np.float64)
    x1, x2 = hi - GOLD * (hi - lo), lo + GOLD * (hi - lo)
    f1, f2 = f(x1), f(x2)
    for _ in range(iters):
        left = f1 <= f2  # the minimum lies in [lo, x2]
        hi, lo = np.where(left, x2, hi), np.where(left, lo, x1)
        x1n, x2n = hi - GOLD * (hi - lo), lo + GOLD * (hi - lo)
        fn = f(np.where(left, x1n, x2n))
        f1, f2, x1, x2 = (np.where(left, fn, f2), np.where(left, f1, fn), np.where(left, x1n, x2),
                          np.where(left, x1, x2n))
    cand_t = np.stack([lo * 0.0 + lo, x1, x2, hi])
    cand_f = np.stack([f(cand_t[0]), f1, f2, f(cand_t[3])])
    k = np.argmin(cand_f, axis=0)
    idx = np.arange(len(k))
    return cand_f[k, idx], cand_t[k, idx]


def first_contacts(hull: Hull, p0, p1, r, iters=80, roots=True):
    """For N paths (arrays (N, 3), (N, 3), (N,)): hit, the first t in [0, 1] with dist(p(t)) <= r (nan if
    none; not searched without ``roots``), the least f = dist - r on the path and where it is."""
    p0, p1 = np.atleast_2d(np.asarray(p0, np.float64)), np.atleast_2d(np.asarray(p1, np.float64))
    r = np.broadcast_to(np.asarray(r, np.float64), (len(p0),))
    f = lambda t: hull.distance(p0 + t[:, None] * (p1 - p0)) - r
    zero = np.zeros(len(p0))
    f0 = f(zero)
    fmin, tmin = _golden_min(f, zero, zero + 1.0, iters)
    start = f0 <= 0.0
    fmin, tmin = np.where(start, np.minimum(f0, fmin), fmin), np.where(start, 0.0, tmin)
    hit = start | (fmin <= 0.0)
    b = np.where(start, 0.0, tmin)
    cross = np.flatnonzero(hit & ~start)  # only these have a root inside the path to find
    if roots and len(cross):
        h, q0, q1, rr = hull.take(cross), p0[cross], p1[cross], r[cross]
        a, bb = np.zeros(len(cross)), b[cross]
        for _ in range(64):  # bisection on [0, argmin], where f changes sign once
            m = 0.5 * (a + bb)
            inside = h.distance(q0 + m[:, None] * (q1 - q0)) - rr <= 0.0
            a, bb = np.where(inside, a, m), np.where(inside, m, bb)
        b[cross] = bb
    return hit, np.where(hit, b, np.nan), fmin, tmin


def first_contact(hull: Hull, p0, p1, r, iters=80):
    """:func:`first_contacts` of one path: (hit, t, fmin, t_min)."""
    hit, t, fmin, tmin = first_contacts(hull, p0, p1, r, iters)
    return bool(hit[0]), float(t[0]), float(fmin[0]), float(tmin[0])


def min_on(hull: Hull, p0, p1, r, t_hi, iters=80):
    """Per path, the least f = dist - r for t in [0, t_hi] (f is convex)."""
    p0, p1 = np.atleast_2d(np.asarray(p0, np.float64)), np.atleast_2d(np.asarray(p1, np.float64))
    f = lambda t: hull.distance(p0 + t[:, None] * (p1 - p0)) - r
    t_hi = np.broadcast_to(np.asarray(t_hi, np.float64), (len(p0),))
    return _golden_min(f, np.zeros(len(p0)), t_hi, iters)[0]


class SweptKernel:
    """engine.impacts.swept_sphere_hull over a batch of (p0, p1, r, part) in one precision."""

    def __init__(self, real, capacity=4096):
        self.real, self.cap = real, capacity
        self.np_real = np.float64 if real == ti.f64 else np.float32
        self.p0 = ti.Vector.field(3, real, capacity)
        self.p1 = ti.Vector.field(3, real, capacity)
        self.r = ti.field(real, capacity)
        self.planes = ti.Matrix.field(6, 4, real, capacity)
        self.corners = ti.Matrix.field(8, 3, real, capacity)
        self.hit = ti.field(ti.i32, capacity)
        self.face = ti.field(ti.i32, capacity)
        self.t = ti.field(real, capacity)
        self.point = ti.Vector.field(3, real, capacity)
        self.normal = ti.Vector.field(3, real, capacity)

        @ti.kernel
        def run(n: ti.i32):
            for i in range(n):
                pl, co = self.planes[i], self.corners[i]
                h, t, q, nrm, face = swept_sphere_hull(self.p0[i], self.p1[i], self.r[i], pl, co)
                self.hit[i], self.t[i], self.point[i], self.normal[i], self.face[i] = h, t, q, nrm, face

        self._run = run

    def __call__(self, p0, p1, r, corners, planes=None):
        """Arrays (N, 3), (N, 3), (N,), (N, 8, 3) [, (N, 6, 4)] in float64; results as float64 arrays."""
        p0, p1, corners = (np.asarray(a, np.float64).reshape(-1, *s) for a, s in
                           ((p0, (3,)), (p1, (3,)), (corners, (8, 3))))
        n = len(p0)
        r = np.broadcast_to(np.asarray(r, np.float64), (n,))
        if planes is None:  # each distinct body once (the tests repeat one body over thousands of paths)
            bodies, which = np.unique(corners.reshape(n, -1), axis=0, return_inverse=True)
            planes = np.array([hexahedron_planes(c.reshape(8, 3)) for c in bodies])[which.reshape(-1)]
        out = {k: [] for k in ("hit", "t", "point", "normal", "face")}
        for s in range(0, n, self.cap):
            e = min(s + self.cap, n)
            k = e - s
            pad = lambda a: np.concatenate([a[s:e], np.repeat(a[s:s + 1], self.cap - k, 0)]).astype(self.np_real)
            self.p0.from_numpy(pad(p0))
            self.p1.from_numpy(pad(p1))
            self.r.from_numpy(pad(r))
            self.planes.from_numpy(pad(planes))
            self.corners.from_numpy(pad(corners))
            self._run(k)
            for key in out:
                out[key].append(getattr(self, key).to_numpy()[:k].astype(np.float64))
        res = {k: np.concatenate(v) for k, v in out.items()}
        res["hit"] = res["hit"].astype(bool)
        res["face"] = res["face"].astype(int)
        return res
