"""The tread's footprint ("patch" detection): every rock under the tread is run over, not only the one under
the tire's centre line.

The footprint of a tire is the rectangle tire_width x contact_length centred on the tire's bottom point b and
oriented along its heading f (half sizes hw, hl; left l = (-f_y, f_x)): corners b +- hl f +- hw l. Over a step
the tire moves from (b0, f0) to (b1, f1); the swept footprint is the convex hull of the 8 corners of the two
rectangles. With f0 = f1 this is exactly the Minkowski sum of the rectangle and the motion segment (the
convex hull of two translates of a convex set); with a turning tire it is the hull of the two rectangles,
which contains every position of a rectangle turning and moving linearly in between up to the chord error of
the turn (of order the step's heading change squared times the half-diagonal: micrometres at dt = 2 ms).

A rock (centre c, radius r) is run over when the XY distance from c to the swept footprint is <= r and its
bottom c_z - r is at most the tire's bottom + PATCH_TOL (a rock on the ground, not one flying over it).

The hull is computed once per tire and step on the host (Andrew's monotone chain, float64; ``hulls`` runs it
with NumPy over all tires and steps at once) and passed in the tire's ray row (world.HULL: 8 vertices
counter-clockwise, padded by repeating the last one). The kernel's
distance: c is inside iff it lies left of (or on) every edge and the hull has an area; otherwise the distance
is that to the nearest edge (the closest point of a convex polygon to an outside point is on its boundary). A
degenerate hull (zero area: a zero-width footprint that does not move sideways) is a segment or a point, and
only the edge distances count.
"""

import numpy as np
import taichi as ti

from . import tirerow
from .geometry import closest_on_segment
from .world import HULL, HULL_VERTICES


# ------------------------------------------------------------------------------------------------ host side
def footprint_corners(bottom: np.ndarray, forward: np.ndarray, half_width: np.ndarray,
                      half_length: np.ndarray) -> np.ndarray:
    """(T, 4, 2) corners of the footprint rectangles (XY)."""
    f = np.asarray(forward, np.float64)[:, :2]
    left = np.column_stack([-f[:, 1], f[:, 0]])
    b = np.asarray(bottom, np.float64)[:, :2]
    hw = np.broadcast_to(np.asarray(half_width, np.float64), len(b))[:, None]
    hl = np.broadcast_to(np.asarray(half_length, np.float64), len(b))[:, None]
    return np.stack([b + sl * hl * f + sw * hw * left for sl, sw in ((1, 1), (-1, 1), (-1, -1), (1, -1))], axis=1)


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull, counter-clockwise, without repeated or collinear vertices (monotone chain)."""
    pts = sorted({(float(x), float(y)) for x, y in points})
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _chains(px: np.ndarray, py: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The monotone chain of each row's first ``n`` points (px, py: (M, V), in the chain's order), all rows at
    once, with the same cross products and pops as ``_hull``: the stacks (x, y: (M, V + 2), the chain from
    column 2 on) and their sizes."""
    m, v = px.shape
    width = v + 2  # two unused slots first: the second from the top of a stack of fewer than 2 is in range
    sx, sy = np.zeros(m * width), np.zeros(m * width)
    top = np.arange(m) * width + 1  # flat index of each stack's top (its size is top - row start - 1)
    size = np.zeros(m, np.int64)
    for j in range(v):
        act = j < n
        if not act.any():
            break
        x, y = px[:, j], py[:, j]
        while True:
            can = act & (size >= 2)
            if not can.any():
                break
            ax, ay, ox, oy = sx[top], sy[top], sx[top - 1], sy[top - 1]
            pop = can & ((ax - ox) * (y - oy) - (ay - oy) * (x - ox) <= 0)
            if not pop.any():
                break
            size -= pop
            top -= pop
        top += act
        size += act
        sx[top[act]] = x[act]
        sy[top[act]] = y[act]
    return sx.reshape(m, width)[:, 2:], sy.reshape(m, width)[:, 2:], size


def hulls(points: np.ndarray) -> np.ndarray:
    """(N, V, 2): ``_hull`` of each row of ``points`` (N, V, 2), padded by repeating its last vertex; NumPy
    over all rows at once, the same bits and vertex order as ``_hull`` row by row."""
    pts = np.asarray(points, np.float64)
    rows, v = pts.shape[:2]
    if rows == 0:
        return np.zeros((0, v, 2))
    # sorted by (x, y), stable: of equal points the first in row order stays, as in _hull's set
    pts = np.take_along_axis(pts, np.lexsort((pts[..., 1], pts[..., 0]), axis=-1)[..., None], axis=1)
    dup = np.zeros((rows, v), bool)
    dup[:, 1:] = (pts[:, 1:, 0] == pts[:, :-1, 0]) & (pts[:, 1:, 1] == pts[:, :-1, 1])
    pts = np.take_along_axis(pts, np.argsort(dup, axis=1, kind="stable")[..., None], axis=1)  # distinct first
    n = v - dup.sum(axis=1)
    back = np.clip(n[:, None] - 1 - np.arange(v)[None, :], 0, v - 1)  # the upper chain runs backwards
    rev = np.take_along_axis(pts, back[..., None], axis=1)
    sx, sy, size = _chains(np.concatenate([pts[..., 0], rev[..., 0]]), np.concatenate([pts[..., 1], rev[..., 1]]),
                           np.concatenate([n, n]))
    both = np.stack([np.concatenate([sx[:rows], sx[rows:]], axis=1),
                     np.concatenate([sy[:rows], sy[rows:]], axis=1)], axis=-1)  # lower | upper
    lo = size[:rows] - 1
    m = np.maximum(lo + size[rows:] - 1, 1)  # one distinct point: the hull is that point
    k = np.minimum(np.arange(v)[None, :], m[:, None] - 1)
    src = np.where(k < lo[:, None], k, v + k - lo[:, None])
    src[n == 1] = 0
    return np.take_along_axis(both, src[..., None], axis=1)


def swept_footprint_hulls(b0, f0, b1, f1, half_width, half_length) -> np.ndarray:
    """(T, HULL_VERTICES, 2) hull of the footprints at the previous and the current step, per tire, padded by
    repeating its last vertex (a zero-length edge changes neither the inside test nor the distance)."""
    corners = np.concatenate([footprint_corners(b0, f0, half_width, half_length),
                              footprint_corners(b1, f1, half_width, half_length)], axis=1)
    if len(corners) < 64:  # few tires: the per-tire chain costs less than NumPy's per-call overhead
        out = np.zeros((len(corners), HULL_VERTICES, 2))
        for t, pts in enumerate(corners):
            h = _hull(pts)
            out[t, :len(h)] = h
            out[t, len(h):] = h[-1]
        return out
    return hulls(corners)


# ------------------------------------------------------------------------------------------------ kernels
@ti.func
def hull_vertex(w: ti.template(), t, k: ti.template()):
    return tirerow.xy(w, t, HULL + 2 * k)


@ti.func
def footprint_dist2(w: ti.template(), t, c):
    """Squared XY distance from the point c (XY) to tire t's swept footprint (0 inside)."""
    best = ti.cast(3.0e38, w.real)
    inside = True
    area = 0.0 * best
    for k in ti.static(range(HULL_VERTICES)):
        a = hull_vertex(w, t, k)
        b = hull_vertex(w, t, (k + 1) % HULL_VERTICES)
        e = b - a
        q = c - a
        if e[0] * q[1] - e[1] * q[0] < 0.0:
            inside = False
        area += a[0] * b[1] - a[1] * b[0]
        best = ti.min(best, (c - closest_on_segment(a, b, c)).norm_sqr())
    if inside and area > 0.0:
        best = 0.0 * best
    return best


@ti.func
def footprint_box(w: ti.template(), t):
    """XY bounding box (lo, hi) of tire t's swept footprint."""
    lo = hull_vertex(w, t, 0)
    hi = lo
    for k in ti.static(range(1, HULL_VERTICES)):
        v = hull_vertex(w, t, k)
        lo = ti.min(lo, v)
        hi = ti.max(hi, v)
    return lo, hi


def tread_columns(prev, cur, keep_prev: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """World.ray columns HALF_W .. the end (tread sizes, fender, flap, footprint hull in the local frame) of
    the rear tires ``prev`` -> ``cur`` (motion.vehicles.RearTires); where ``keep_prev`` is False the previous
    pose is taken to be the current one (a path that jumped)."""
    jump = ~np.asarray(keep_prev, bool)
    b0 = np.where(jump[:, None], cur.bottom, prev.bottom)
    f0 = np.where(jump[:, None], cur.forward, prev.forward)
    hulls = swept_footprint_hulls(b0, f0, cur.bottom, cur.forward, cur.half_width, cur.half_length)
    hulls -= np.asarray(origin, np.float64)[:2]
    head = np.column_stack([cur.half_width, cur.half_length, cur.radius, cur.fender, cur.flap])
    return np.concatenate([head, hulls.reshape(len(hulls), -1)], axis=1)
