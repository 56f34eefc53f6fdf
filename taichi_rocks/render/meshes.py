"""Mesh pieces, host side (NumPy, no Taichi): flat-shaded quads and boxes, wheels, and the posing of a vehicle.

A mesh is (vertices, normals, colours, indices), float64 / int64. The renderer transforms the vertices and
normals of each vehicle on the host every frame (GGUI 1.7.4's ``mesh_instance`` lights the *untransformed*
mesh, so a yawed vehicle would keep the shading of an unrotated one), turning each wheel about its axle.
No two visible faces may share a plane: lavapipe resolves z-fighting differently from frame to frame, which
would make renders irreproducible (pieces that touch overlap a little instead, or stand a few mm proud).
"""

import math
from typing import NamedTuple

import numpy as np

from .looks import HUB_COLOR, RIM_DARK_COLOR, TIRE_COLOR, TREAD_COLOR

__all__ = ["VehicleMesh", "pose_mesh", "merge", "quad", "box", "frustum", "wheel", "turn_about_axle",
           "WHEEL_SEGMENTS", "SPOKES"]

WHEEL_SEGMENTS = 16  # around a wheel: tread blocks alternate in colour segment by segment (even)
SPOKES = 4  # light spokes between dark openings on the rim (WHEEL_SEGMENTS a multiple of it)


class VehicleMesh(NamedTuple):
    """One vehicle's mesh in its body frame (x forward, y left, z up; origin at the body centre on the ground).

    ``wheel[v]``: the wheel vertex v belongs to (-1: the body); a wheel's vertices are relative to its centre
    ``centres[k]`` (body frame), so that turning it is a rotation about its own axle (y). ``rear[k]``: wheel k
    is a rear wheel."""

    verts: np.ndarray
    norms: np.ndarray
    cols: np.ndarray
    idx: np.ndarray
    wheel: np.ndarray
    centres: np.ndarray
    rear: np.ndarray

    def triangle_owner(self) -> np.ndarray:
        """Per triangle: the wheel it belongs to (-1: the body)."""
        return self.wheel[self.idx[0::3]]


def turn_about_axle(v: np.ndarray, angle) -> np.ndarray:
    """Points or normals (N, 3) turned about the y axis by ``angle`` (rad, scalar or (N,)), the way a wheel
    turns when the vehicle rolls forward (+x): x' = x cos a + z sin a, z' = -x sin a + z cos a."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([v[:, 0] * c + v[:, 2] * s, v[:, 1], -v[:, 0] * s + v[:, 2] * c], 1)


def pose_mesh(mesh: VehicleMesh, position, heading: float, angles=None):
    """The mesh's vertices and normals placed at ``position`` (local frame) with ``heading`` (rad), each wheel
    k turned about its axle by ``angles[k]`` (rad; positive rolls the vehicle forward); float64."""
    v, n = mesh.verts, mesh.norms
    on_wheel = mesh.wheel >= 0
    if angles is not None and len(mesh.centres):
        a = np.asarray(angles, np.float64)[np.maximum(mesh.wheel, 0)]
        v = np.where(on_wheel[:, None], turn_about_axle(v, a), v)
        n = np.where(on_wheel[:, None], turn_about_axle(n, a), n)
    if len(mesh.centres):
        v = v + np.where(on_wheel[:, None], mesh.centres[np.maximum(mesh.wheel, 0)], 0.0)
    ch, sh = math.cos(heading), math.sin(heading)
    rot = np.array([[ch, -sh, 0.0], [sh, ch, 0.0], [0.0, 0.0, 1.0]])
    return v @ rot.T + np.asarray(position, np.float64), n @ rot.T


def merge(parts):
    """Meshes concatenated into one (the indices of each offset by the vertices before it)."""
    vs, ns, cs, ids, off = [], [], [], [], 0
    for v, n, c, i in parts:
        vs.append(np.asarray(v, np.float64))
        ns.append(np.asarray(n, np.float64))
        cs.append(np.asarray(c, np.float64))
        ids.append(np.asarray(i, np.int64) + off)
        off += len(v)
    return np.concatenate(vs), np.concatenate(ns), np.concatenate(cs), np.concatenate(ids)


def quad(corners, normal, color):
    """One flat quad or triangle (3 or 4 corners in order round it), wound counter-clockwise seen from the
    ``normal`` side whichever way the corners were given."""
    v = np.asarray(corners, np.float64)
    nrm = np.asarray(normal, np.float64)
    if np.cross(v[1] - v[0], v[2] - v[0]) @ nrm < 0:
        v = v[::-1].copy()
    idx = np.array([0, 1, 2, 0, 2, 3] if len(v) == 4 else [0, 1, 2])
    return v, np.tile(nrm, (len(v), 1)), np.tile(np.asarray(color, np.float64), (len(v), 1)), idx


def box(center, size, colors):
    """Axis-aligned box: 24 vertices (flat faces). ``colors``: one rgb, or a dict face -> rgb for '+x', '-x',
    '+y', '-y', '+z', '-z' (faces left out are not drawn: they are hidden inside other pieces)."""
    if not isinstance(colors, dict):
        colors = {k: colors for k in ("+x", "-x", "+y", "-y", "+z", "-z")}
    cx, cy, cz = center
    hx, hy, hz = (s / 2 for s in size)
    x0, x1, y0, y1, z0, z1 = cx - hx, cx + hx, cy - hy, cy + hy, cz - hz, cz + hz
    faces = {
        "+x": ([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (1, 0, 0)),
        "-x": ([(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], (-1, 0, 0)),
        "+y": ([(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], (0, 1, 0)),
        "-y": ([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, -1, 0)),
        "+z": ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, 1)),
        "-z": ([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)], (0, 0, -1)),
    }
    return merge([quad(c, n, colors[k]) for k, (c, n) in faces.items() if k in colors])


def frustum(bottom, top, z0: float, z1: float, colors):
    """A six-sided solid between two horizontal rectangles centred on y = 0: ``bottom`` = (x0, x1, half width)
    at z0 and ``top`` = (x0, x1, half width) at z1 (a cabin with sloping windows). ``colors``: face -> rgb for
    "front" (+x), "back", "left" (+y), "right", "top" ("bottom" too if given); faces left out are not drawn."""
    (a0, a1, ay), (b0, b1, by) = bottom, top
    lo = [(a0, -ay, z0), (a1, -ay, z0), (a1, ay, z0), (a0, ay, z0)]
    hi = [(b0, -by, z1), (b1, -by, z1), (b1, by, z1), (b0, by, z1)]
    faces = {"front": [lo[1], lo[2], hi[2], hi[1]], "back": [lo[0], lo[3], hi[3], hi[0]],
             "left": [lo[3], lo[2], hi[2], hi[3]], "right": [lo[0], lo[1], hi[1], hi[0]], "top": hi, "bottom": lo}
    mid = np.mean(np.array(lo + hi, np.float64), axis=0)
    parts = []
    for name, corners in faces.items():
        if name not in colors:
            continue
        v = np.asarray(corners, np.float64)
        n = np.cross(v[1] - v[0], v[2] - v[0])
        n /= np.linalg.norm(n)
        if n @ (v.mean(axis=0) - mid) < 0:
            n = -n
        parts.append(quad(v, n, colors[name]))
    return merge(parts)


def _ring(radius, y, th):
    return np.stack([radius * np.cos(th), np.full(len(th), y), radius * np.sin(th)], 1)


def wheel(radius: float, width: float, seg: int = WHEEL_SEGMENTS, spokes: int = SPOKES):
    """A wheel centred at the origin, its axle along y: a tread of ``seg`` flat blocks alternating between two
    dark rubbers, dark sidewalls, and on each side a rim of ``spokes`` light spokes between dark openings
    round a light cap (the cap stands 4 mm proud). Its pattern turns with it, so the wheel is seen to roll."""
    th = np.linspace(0.0, 2.0 * np.pi, seg + 1)
    parts = []
    for k in range(seg):
        a, b = th[k], th[k + 1]
        mid = 0.5 * (a + b)
        corners = [(radius * math.cos(t), y, radius * math.sin(t)) for t, y in
                   ((a, -width / 2), (b, -width / 2), (b, width / 2), (a, width / 2))]
        parts.append(quad(corners, (math.cos(mid), 0.0, math.sin(mid)), TREAD_COLOR if k % 2 else TIRE_COLOR))
    per_spoke = max(seg // spokes, 2)
    for side in (1.0, -1.0):
        y = side * width / 2
        outer, rim, cap = _ring(radius, y, th), _ring(0.66 * radius, y, th), _ring(0.24 * radius, y, th)
        yc = y + side * 0.004
        cap_out = _ring(0.24 * radius, yc, th)
        for k in range(seg):
            nrm = (0.0, side, 0.0)
            parts.append(quad([outer[k], outer[k + 1], rim[k + 1], rim[k]], nrm, TIRE_COLOR))
            spoke = (k % per_spoke) < per_spoke // 2
            parts.append(quad([rim[k], rim[k + 1], cap[k + 1], cap[k]], nrm, HUB_COLOR if spoke else RIM_DARK_COLOR))
            parts.append(quad([cap_out[k], cap_out[k + 1], (0.0, yc, 0.0)], nrm, HUB_COLOR))
    return merge(parts)
