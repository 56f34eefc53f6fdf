"""Vehicle meshes, host side (NumPy, no Taichi): flat-shaded boxes and tire cylinders in the body frame.

A mesh is (vertices, normals, colours, indices), float64 / int64. The renderer transforms the vertices and
normals of each vehicle on the host every frame (GGUI 1.7.4's ``mesh_instance`` lights the *untransformed*
mesh, so a yawed vehicle would keep the shading of an unrotated one).
"""

import math
from typing import NamedTuple

import numpy as np

from .looks import BUMPER_COLOR, GLASS_COLOR, HUB_COLOR, TAIL_LIGHT_COLOR, TIRE_COLOR

__all__ = ["VehicleMesh", "vehicle_kind", "vehicle_mesh", "merge", "pose_mesh"]


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


def pose_mesh(mesh: VehicleMesh, position, heading: float, angles=None):
    """The mesh's vertices and normals placed at ``position`` (local frame) with ``heading`` (rad), each wheel
    k turned about its axle by ``angles[k]`` (rad; positive rolls the vehicle forward); float64."""
    v, n = mesh.verts, mesh.norms
    if angles is not None and len(mesh.centres):
        a = np.asarray(angles, np.float64)[np.maximum(mesh.wheel, 0)]
        c, s = np.cos(a), np.sin(a)
        w = mesh.wheel >= 0
        # rotation about +y by a: x' = x cos a + z sin a, z' = -x sin a + z cos a
        v = np.where(w[:, None], np.stack([v[:, 0] * c + v[:, 2] * s, v[:, 1], -v[:, 0] * s + v[:, 2] * c], 1), v)
        n = np.where(w[:, None], np.stack([n[:, 0] * c + n[:, 2] * s, n[:, 1], -n[:, 0] * s + n[:, 2] * c], 1), n)
    v = v + np.where((mesh.wheel >= 0)[:, None], mesh.centres[np.maximum(mesh.wheel, 0)], 0.0)
    ch, sh = math.cos(heading), math.sin(heading)
    rot = np.array([[ch, -sh, 0.0], [sh, ch, 0.0], [0.0, 0.0, 1.0]])
    return v @ rot.T + np.asarray(position, np.float64), n @ rot.T


def _quad_faces(corners, normal, color):
    """One flat quad (4 corners CCW seen from the normal side)."""
    v = np.asarray(corners, np.float64)
    return v, np.tile(normal, (4, 1)), np.tile(color, (4, 1)), np.array([0, 1, 2, 0, 2, 3])


def _box(center, size, colors):
    """Axis-aligned box: 24 vertices (flat faces). colors: dict face -> rgb for '+x','-x','+y','-y','+z','-z'."""
    cx, cy, cz = center
    hx, hy, hz = (s / 2 for s in size)
    x0, x1, y0, y1, z0, z1 = cx - hx, cx + hx, cy - hy, cy + hy, cz - hz, cz + hz
    faces = {
        "+x": ([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (1, 0, 0)),
        "-x": ([(x0, y1, z0), (x0, y0, z0), (x0, y0, z1), (x0, y1, z1)], (-1, 0, 0)),
        "+y": ([(x1, y1, z0), (x0, y1, z0), (x0, y1, z1), (x1, y1, z1)], (0, 1, 0)),
        "-y": ([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, -1, 0)),
        "+z": ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, 1)),
        "-z": ([(x0, y1, z0), (x1, y1, z0), (x1, y0, z0), (x0, y0, z0)], (0, 0, -1)),
    }
    return merge([_quad_faces(c, n, colors[k]) for k, (c, n) in faces.items()])


def _tire(center, radius, width, seg=20):
    """Cylinder with its axis along y: dark tread and sidewalls, light hub discs."""
    cx, cy, cz = center
    th = np.linspace(0.0, 2.0 * np.pi, seg, endpoint=False)
    c, s = np.cos(th), np.sin(th)
    parts = []
    # tread: 2 rings, smooth normals
    ring = lambda y, rr: np.stack([cx + rr * c, np.full(seg, y), cz + rr * s], 1)
    y0, y1 = cy - width / 2, cy + width / 2
    v = np.concatenate([ring(y0, radius), ring(y1, radius)])
    nrm = np.concatenate([np.stack([c, 0 * c, s], 1)] * 2)
    idx = []
    for k in range(seg):
        k2 = (k + 1) % seg
        idx += [k, k2, seg + k2, k, seg + k2, seg + k]
    parts.append((v, nrm, np.tile(TIRE_COLOR, (2 * seg, 1)), np.array(idx)))
    # sidewalls (annulus) and hubs (disc), both sides
    for y, ny in ((y1, 1.0), (y0, -1.0)):
        outer, inner = ring(y, radius), ring(y, 0.55 * radius)
        v = np.concatenate([outer, inner])
        idx = []
        for k in range(seg):
            k2 = (k + 1) % seg
            a = [k, k2, seg + k2, k, seg + k2, seg + k]
            idx += a if ny < 0 else [a[0], a[2], a[1], a[3], a[5], a[4]]
        parts.append((v, np.tile((0, ny, 0), (2 * seg, 1)), np.tile(TIRE_COLOR, (2 * seg, 1)), np.array(idx)))
        hub = np.concatenate([inner, [(cx, y + 0.002 * ny, cz)]])
        idx = []
        for k in range(seg):
            k2 = (k + 1) % seg
            idx += [seg, k2, k] if ny < 0 else [seg, k, k2]
        parts.append((hub, np.tile((0, ny, 0), (seg + 1, 1)), np.tile(HUB_COLOR, (seg + 1, 1)), np.array(idx)))
    return merge(parts)


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


def vehicle_kind(spec) -> str:
    """"truck", "van" or "car", from the proportions (the scene format has no vehicle type)."""
    L, H = float(spec.length), float(spec.height)
    if H >= 2.6 or L >= 6.5:
        return "truck"
    if H >= 1.75:
        return "van"
    return "car"


def vehicle_mesh(spec, ground_z: float = 0.0) -> VehicleMesh:
    """Body-frame mesh of one vehicle (x forward, y left, z up; origin at the body centre on the ground).

    Returns a :class:`VehicleMesh`. Tires (dark tread, light hubs) at (+-wheelbase/2,
    +-track/2), centre height tire_radius. The body (length x width, from 0.8 tire radius up to that plus
    ``height``) is shaped by :func:`vehicle_kind`: a car has a lower body and a glazed cabin with a roof in the
    body colour, a van a tall body glazed at the front, a truck a cab at the front and a cargo box behind.
    """
    col = np.clip(np.asarray(spec.color, np.float64), 0, 1)
    glass = np.array(GLASS_COLOR)
    dark = col * 0.8
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    R, TW = float(spec.tire_radius), float(spec.tire_width)
    z0 = ground_z + 0.8 * R
    same = lambda c: {k: c for k in ("+x", "-x", "+y", "-y", "+z", "-z")}
    kind = vehicle_kind(spec)
    parts = []
    if kind == "car":
        lower_h = 0.5 * H
        parts.append(_box((0.0, 0.0, z0 + lower_h / 2), (L, W, lower_h), same(col)))
        cab = {k: glass for k in ("+x", "-x", "+y", "-y", "-z")}
        cab["+z"] = col * 0.92
        cab_h = H - lower_h
        parts.append(_box((-0.06 * L, 0.0, z0 + lower_h + cab_h / 2), (0.52 * L, 0.88 * W, cab_h), cab))
    elif kind == "van":
        lower_h = 0.55 * H
        parts.append(_box((0.0, 0.0, z0 + lower_h / 2), (L, W, lower_h), same(col)))
        up_h = H - lower_h
        xf1 = L / 2 - 0.04 * L  # the upper body: glazed front part [xf0, xf1], closed rear part [-L/2, xf0]
        xf0 = xf1 - 0.3 * L
        wind = same(col * 0.95)
        wind.update({"+x": glass, "+y": glass, "-y": glass})
        parts.append(_box(((xf0 + xf1) / 2, 0.0, z0 + lower_h + up_h / 2), (xf1 - xf0, 0.97 * W, up_h), wind))
        rear = same(col * 0.95)
        rear["-x"] = glass  # rear window
        parts.append(_box(((xf0 - L / 2) / 2, 0.0, z0 + lower_h + up_h / 2), (xf0 + L / 2, 0.97 * W, up_h), rear))
    else:  # truck: chassis, cab at the front, cargo box behind
        chassis_h = 0.22 * H
        parts.append(_box((0.0, 0.0, z0 + chassis_h / 2), (L, 0.9 * W, chassis_h), same(np.array(TIRE_COLOR) * 2)))
        cab_l = min(2.2, 0.3 * L)
        cab_h = 0.78 * H - chassis_h
        low_h = 0.5 * cab_h
        parts.append(_box((L / 2 - cab_l / 2, 0.0, z0 + chassis_h + low_h / 2), (cab_l, W, low_h), same(col)))
        cab = same(col)
        cab.update({"+x": glass, "+y": glass, "-y": glass})  # windscreen and side windows
        up_h = cab_h - low_h
        parts.append(_box((L / 2 - cab_l / 2, 0.0, z0 + chassis_h + low_h + up_h / 2), (cab_l, W, up_h), cab))
        box_l = L - cab_l - 0.15
        box_h = H - chassis_h
        cargo = same(np.clip(col * 1.08 + 0.04, 0, 1))
        cargo["-x"] = dark
        parts.append(_box((-L / 2 + box_l / 2, 0.0, z0 + chassis_h + box_h / 2), (box_l, W, box_h), cargo))
    # bumpers (dark) and tail lights, standing proud of the body: no two visible faces share a plane (lavapipe
    # resolves z-fighting differently from frame to frame, which would make renders irreproducible)
    bump_h = min(0.18, 0.12 * H)
    for sx in (1.0, -1.0):
        parts.append(_box((sx * (L / 2 + 0.02), 0.0, z0 - 0.01 + bump_h / 2), (0.08, 1.02 * W, bump_h),
                          same(np.array(BUMPER_COLOR))))
    lz = z0 + bump_h + 0.06 * H
    for side in (1.0, -1.0):
        parts.append(_box((-L / 2 - 0.02, side * 0.38 * W, lz), (0.03, 0.16 * W, 0.07 * H),
                          same(np.array(TAIL_LIGHT_COLOR))))
    body = merge(parts)
    centres = np.array([(sx * float(spec.wheelbase), sy * float(spec.track), ground_z + R)
                        for sx in (0.5, -0.5) for sy in (0.5, -0.5)])
    wheels = [_tire((0.0, 0.0, 0.0), R, TW) for _ in centres]
    v, n, c, i = merge([body] + wheels)
    wheel = np.concatenate([np.full(len(body[0]), -1)] + [np.full(len(w[0]), k) for k, w in enumerate(wheels)])
    return VehicleMesh(v, n, c, i, wheel, centres, centres[:, 0] < 0)
