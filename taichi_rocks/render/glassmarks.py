"""Windscreen marks, host side (NumPy): the shape of a chip or a crack on the glass, made once per hit, and the
glass's coordinates the renderer draws them in.

Marks (:func:`mark_segments`): a chip or a crack on a windscreen stays as line segments on the glass, shaped by
its damage class and sized by its severity s (render/marks.py ``severity``: how far its measure lies above the
class's threshold, in [0, 1], log scale):

  chip   a bullseye with a star: a ring of radius 0.35 R and 5-7 arms of 0.6-1.0 R, R = CHIP_R (8 -> 20 mm);
  crack  the chip's star at the point, and a line crack through it, L = CRACK_L (20 -> 60 cm) end to end, as
         two jagged arms (bent at CRACK_STEPS points by up to CRACK_JITTER rad) with 2-4 branches of 0.2-0.4 of
         an arm at 25-50 degrees off it.

Windscreen chips are typically 5-20 mm bullseyes and stars, and a crack from a stone runs from a few cm to
across the glass; a mark's shape is drawn from a hash of (rock, step) (render/marks.py ``mark_rng``), so it is
the same in every run.

Glass coordinates (y, v): y across the car, v metres up the glass from its foot (the belt line), so lengths on
the sloping glass are true. The windscreen (motion/cabin.py: the front face of the cabin, from the belt line to
the roof) is the plane p(y, v) = (base_x, 0, belt) + y e_y + v e_v, e_v = (top_x - base_x, 0, roof - belt) / L,
L the glass's length up its slope (:func:`glass_point`), and the glass the trapezoid between its bottom and top
edges: half widths base_half at v = 0 and top_half at v = L (:func:`glass_edges`: four half-planes). A mark lies
on that plane whatever depth the contact point was reported at (a stone is found a few mm inside the glass,
more at speed), clipped to the glass GLASS_MARGIN inside its edges.

Drawn (render/markmesh.py, a kernel; :func:`glass_ribbons` is its NumPy reference): each segment a ribbon
``width_px`` pixels wide at its distance from the camera, clipped to the glass GLASS_EDGE inside its edges, so
that every pixel of a mark lies on the glass (a line is drawn at a width in pixels, past the ends of whatever it
lies on), GLASS_GAP inside the glass from the driver's seat (behind the windscreen's frame, render/interior.py
INSET, which hides what its pillars cover) or outside it seen from outside; the depth test hides what the
cabin's frame, the dashboard or another body covers. The width is the view's, not the mark's: the shape is made
once, the ribbons each frame.
"""

from __future__ import annotations

import math

import numpy as np

from ..motion.cabin import cabin_of
from .marks import CRACK, clip_convex, mark_rng

__all__ = ["mark_segments", "glass_point", "glass_normal", "glass_edges", "glass_frame", "glass_ribbons",
           "along_glass", "cabin_for", "CHIP_R", "CRACK_L", "GLASS_GAP", "GLASS_MARGIN", "GLASS_EDGE",
           "GLASS_FRAME"]

CHIP_R = (0.008, 0.02)  # m: the chip's radius, at s = 0 and s = 1
CRACK_L = (0.20, 0.60)  # m: the crack's length end to end, at s = 0 and s = 1
CRACK_STEPS = 6  # bends per arm of a crack
CRACK_JITTER = 0.35  # rad: at most this much turn at a bend
GLASS_GAP = 0.002  # m between a mark and the glass, on the camera's side
GLASS_MARGIN = 0.01  # m: marks stop this far inside the glass's edges
GLASS_EDGE = 0.002  # m: and their ribbons, drawn a few pixels wide, this far
GLASS_FRAME = ("base_x", "belt", "ev_x", "ev_z", "n_x", "n_z", "length", "base_half", "slope")  # glass_frame


def cabin_for(spec):
    """The cabin (motion/cabin.py) of vehicle ``spec`` in the body frame on the ground."""
    return cabin_of(spec, 0.0)


def _star(c, r, rng) -> list:
    """A chip around ``c`` (glass coordinates y, v): a ring of 8 segments and 5-7 arms."""
    segs = []
    ring = [c + 0.35 * r * np.array([math.cos(a), math.sin(a)]) for a in np.linspace(0, 2 * math.pi, 9)]
    segs += list(zip(ring[:-1], ring[1:]))
    n = int(rng.integers(5, 8))
    for a in rng.uniform(0, 2 * math.pi) + np.arange(n) * 2 * math.pi / n + rng.uniform(-0.3, 0.3, n):
        segs.append((c, c + r * rng.uniform(0.6, 1.0) * np.array([math.cos(a), math.sin(a)])))
    return segs


def _arm(start, angle, length, rng, steps=CRACK_STEPS) -> list:
    """A jagged line from ``start`` at ``angle``, ``length`` long: ``steps`` segments, each bent a little."""
    pts, a = [np.asarray(start, np.float64)], angle
    for _ in range(steps):
        a += rng.uniform(-CRACK_JITTER, CRACK_JITTER)
        pts.append(pts[-1] + (length / steps) * np.array([math.cos(a), math.sin(a)]))
    return pts


def _crack(c, s, rng) -> list:
    """A line crack through ``c``: two arms, mostly across the glass, with branches, and the chip at c."""
    half = 0.5 * (CRACK_L[0] + s * (CRACK_L[1] - CRACK_L[0]))
    base = rng.uniform(-0.6, 0.6)  # rad from the horizontal: stone cracks run mostly across a windscreen
    segs = _star(c, CHIP_R[1], rng)
    for side in (0.0, math.pi):
        arm = _arm(c, base + side, half * rng.uniform(0.7, 1.0), rng)
        segs += list(zip(arm[:-1], arm[1:]))
        for _ in range(int(rng.integers(1, 3)) + (1 if s > 0.5 else 0)):
            k = int(rng.integers(1, len(arm) - 1))
            turn = math.radians(rng.uniform(25, 50)) * rng.choice((-1.0, 1.0))
            d = arm[k + 1] - arm[k]
            branch = _arm(arm[k], math.atan2(d[1], d[0]) + turn, half * rng.uniform(0.2, 0.4), rng, 3)
            segs += list(zip(branch[:-1], branch[1:]))
    return segs


def mark_segments(e, s: float, cabin) -> np.ndarray:
    """The mark of event ``e`` (a chip or a crack, body frame) of severity ``s`` on the windscreen of ``cabin``:
    segments (K, 2, 2) in glass coordinates (y, v), clipped to the glass GLASS_MARGIN inside its edges (see the
    module docstring; :func:`glass_point` puts them in the body frame)."""
    rng = mark_rng(e)
    c = np.array([float(e["point"][1]), along_glass(cabin, float(e["point"][2]))])
    if int(e["damage"]) == CRACK:
        segs = _crack(c, s, rng)
    else:
        segs = _star(c, CHIP_R[0] + s * (CHIP_R[1] - CHIP_R[0]), rng)
    out = []
    for a, b in segs:
        a, b = _clip(cabin, np.asarray(a), np.asarray(b))
        if a is not None:
            out.append((a, b))
    return np.array(out, np.float64).reshape(-1, 2, 2)


def _slope_length(cabin) -> float:
    return math.hypot(cabin.top_x - cabin.base_x, cabin.roof - cabin.belt)


def along_glass(cabin, z):
    """m up the glass from its foot to height ``z``: glass coordinates are (y, this), lengths true on it."""
    return (z - cabin.belt) * _slope_length(cabin) / (cabin.roof - cabin.belt)


def _height(cabin, v):
    return cabin.belt + v * (cabin.roof - cabin.belt) / _slope_length(cabin)


def _inside(cabin, p) -> bool:
    y, z = p[0], _height(cabin, p[1])
    if not (cabin.belt + GLASS_MARGIN <= z <= cabin.roof - GLASS_MARGIN):
        return False
    u = (z - cabin.belt) / (cabin.roof - cabin.belt)
    return abs(y) <= cabin.base_half + u * (cabin.top_half - cabin.base_half) - GLASS_MARGIN


def _clip(cabin, a, b):
    """The part of segment a-b (glass coordinates) from a up to where it leaves the glass (None if a is out)."""
    if not _inside(cabin, a):
        return None, None
    if _inside(cabin, b):
        return a, b
    lo, hi = 0.0, 1.0
    for _ in range(20):  # the glass is convex: bisect to its edge
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _inside(cabin, a + mid * (b - a)) else (lo, mid)
    return a, a + lo * (b - a)


def glass_point(cabin, g) -> np.ndarray:
    """Glass coordinates (..., 2) as body-frame points (..., 3) on the windscreen's plane of ``cabin``."""
    g = np.asarray(g, np.float64)
    z = _height(cabin, g[..., 1])
    return np.stack([cabin.windscreen_x(z), g[..., 0], z], -1)


def glass_normal(cabin) -> np.ndarray:
    """The outward unit normal of the windscreen of ``cabin`` (body frame)."""
    n = np.array([cabin.roof - cabin.belt, 0.0, cabin.base_x - cabin.top_x])
    return n / np.linalg.norm(n)


def glass_edges(cabin, margin: float) -> list:
    """The windscreen of ``cabin`` in glass coordinates (y, v) as half-planes (a, b, c): a y + b v <= c,
    ``margin`` inside its edges."""
    top = along_glass(cabin, cabin.roof)
    k = (cabin.top_half - cabin.base_half) / top  # the half width grows this much per metre up the glass
    h = math.hypot(1.0, k)
    return [(0.0, -1.0, -margin), (0.0, 1.0, top - margin), (1.0 / h, -k / h, cabin.base_half / h - margin),
            (-1.0 / h, -k / h, cabin.base_half / h - margin)]


def glass_frame(cabin) -> np.ndarray:
    """The windscreen of ``cabin`` as the kernel of render/markmesh.py takes it (:data:`GLASS_FRAME`): its foot
    (base_x, belt), e_v's x and z, the outward normal's x and z, its length up the slope, its half width at the
    foot and the growth of the half width per metre up."""
    n = glass_normal(cabin)
    length = _slope_length(cabin)
    return np.array([cabin.base_x, cabin.belt, (cabin.top_x - cabin.base_x) / length,
                     (cabin.roof - cabin.belt) / length, n[0], n[2], along_glass(cabin, cabin.roof),
                     cabin.base_half, (cabin.top_half - cabin.base_half) / along_glass(cabin, cabin.roof)])


def glass_ribbons(segments: np.ndarray, cabin, inside: bool, eye, px_per_rad: float, width_px: float) -> np.ndarray:
    """Windscreen mark segments (K, 2, 2: glass coordinates of ``cabin``) as ribbons on the glass, drawn from
    ``eye`` (body frame; ``px_per_rad``: the camera's pixels per radian): triangles (T, 3, 3), body frame,
    GLASS_GAP off the glass on the camera's side (towards the cabin if ``inside``). Each ribbon is ``width_px``
    pixels wide at its distance from the eye and clipped to the glass GLASS_EDGE inside its edges (a fan of the
    clipped quad). The NumPy reference of render/markmesh.py's kernel, which draws them."""
    g = np.asarray(segments, np.float64).reshape(-1, 2, 2)
    if not len(g):
        return np.empty((0, 3, 3))
    dist = np.linalg.norm(glass_point(cabin, g).mean(axis=1) - np.asarray(eye, np.float64), axis=1)
    half = 0.5 * float(width_px) * dist / float(px_per_rad)
    d = g[:, 1] - g[:, 0]
    norm = np.linalg.norm(d, axis=1)
    keep = norm > 1e-9
    g, d, half, norm = g[keep], d[keep], half[keep], norm[keep]
    across = np.stack([-d[:, 1], d[:, 0]], 1) * (half / norm)[:, None]
    quads = np.stack([g[:, 0] - across, g[:, 0] + across, g[:, 1] + across, g[:, 1] - across], 1)  # (K, 4, 2)
    edges = glass_edges(cabin, GLASS_EDGE)
    tris = []
    for q in quads:  # convex: a fan of the clipped quad stays inside
        poly = clip_convex(q, edges)
        if len(poly) >= 3:
            tris.append(np.stack([np.repeat(poly[:1], len(poly) - 2, 0), poly[1:-1], poly[2:]], 1))
    if not tris:
        return np.empty((0, 3, 3))
    pts = glass_point(cabin, np.concatenate(tris)) + (-GLASS_GAP if inside else GLASS_GAP) * glass_normal(cabin)
    return pts.reshape(-1, 3, 3)
