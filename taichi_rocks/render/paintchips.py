"""Paint chips, host side (NumPy): the flake of paint a chip or a crack knocks off the bonnet or the front, made once
per hit.

A chip or a crack on the bonnet or the front (part "bonnet", "front_bumper": render/marks.py PAINTED) chips the
paint (:func:`paint_chip`): an irregular flake of radius PAINT_R (chip class 4 -> 10 mm, crack class 10 -> 25 mm,
by its severity s, render/marks.py ``severity``), on the body face the stone hit (motion/bodies.py: the part's
face whose outward normal is closest to the contact normal and whose plane passes nearest the contact point,
:func:`face_of`), clipped to that face PAINT_MARGIN inside its edges, PAINT_GAP off it: 7-9 corners round the
hit at 0.55-1 of its radius, drawn from a hash of (rock, step) (render/marks.py ``mark_rng``), so the same in every
run. A chip is a fan of triangles in the body frame with its face's normal: the renderer poses it with its
vehicle each frame (render/markmesh.py) and lights it as the face it lies on.
"""

from __future__ import annotations

import math

import numpy as np

from ..motion.bodies import FACE_CORNERS, body_parts, hexahedron_planes
from .marks import CRACK, clip_convex, mark_rng

__all__ = ["body_faces", "face_of", "paint_chip", "PAINT_R", "PAINT_MARGIN", "PAINT_GAP"]

PAINT_R = ((0.004, 0.010), (0.010, 0.025))  # m: a paint chip's radius, (s = 0, s = 1) of the chip and crack class
PAINT_MARGIN = 0.004  # m: paint chips stop this far inside the face's edges
PAINT_GAP = 0.0015  # m between a paint chip and its face, outside


def body_faces(spec) -> list:
    """Every face of the body of vehicle ``spec`` (motion/bodies.py, body frame on the ground): (corners (4, 3),
    outward plane (n, d): n . x = d on it)."""
    out = []
    for part in body_parts(spec, 0.0).parts:
        c = part.corners()
        planes = hexahedron_planes(c)
        out += [(c[list(idx)], planes[f]) for f, idx in enumerate(FACE_CORNERS)]
    return out


def face_of(faces, point, normal):
    """The face of ``faces`` (:func:`body_faces`) a hit at ``point`` with outward ``normal`` is on: of the faces
    turned within 60 degrees of the normal, the one whose plane passes nearest the point."""
    p, n = np.asarray(point, np.float64), np.asarray(normal, np.float64)
    best, key = None, None
    for corners, plane in faces:
        if plane[:3] @ n < 0.5:
            continue
        q = (abs(float(plane[:3] @ p - plane[3])), -float(plane[:3] @ n))
        if key is None or q < key:
            best, key = (corners, plane), q
    return best


def paint_chip(e, s: float, faces) -> tuple:
    """The paint chip of event ``e`` (body frame) of severity ``s`` on the face of ``faces`` it hit
    (:func:`face_of`): triangles (K, 3, 3), body frame, PAINT_GAP outside the face and clipped to it
    PAINT_MARGIN inside its edges (none if the hit lies outside that), and the face's outward normal (3,). An
    irregular flake: 7-9 corners round the hit at 0.55-1 of its radius, drawn from a hash of (rock, step)."""
    found = face_of(faces, e["point"], e["normal"])
    if found is None:
        return np.empty((0, 3, 3)), np.array(e["normal"], np.float64)
    corners, plane = found
    n = plane[:3]
    u = np.cross(n, (0.0, 0.0, 1.0))
    if np.linalg.norm(u) < 1e-6:  # a top or bottom face
        u = np.cross(n, (0.0, 1.0, 0.0))
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    c = np.asarray(e["point"], np.float64)
    c = c - (n @ c - plane[3]) * n  # on the face
    face = np.stack([(corners - c) @ u, (corners - c) @ v], 1)
    d0, d1 = face[1] - face[0], face[2] - face[1]
    if d0[0] * d1[1] - d0[1] * d1[0] < 0:  # clockwise: turn it round
        face = face[::-1]
    edges = []
    for k in range(len(face)):  # inward offsets of the (counter-clockwise) face's edges
        d = face[(k + 1) % len(face)] - face[k]
        out = np.array([d[1], -d[0]]) / np.linalg.norm(d)
        edges.append((out[0], out[1], float(out @ face[k]) - PAINT_MARGIN))
    if any(-cc > 0.0 for _, _, cc in edges):  # the hit itself lies outside the face's margin
        return np.empty((0, 3, 3)), n
    rng = mark_rng(e)
    lo, hi = PAINT_R[1 if int(e["damage"]) == CRACK else 0]
    r = lo + s * (hi - lo)
    k = int(rng.integers(7, 10))
    ang = rng.uniform(0, 2 * math.pi) + np.arange(k) * 2 * math.pi / k + rng.uniform(-0.25, 0.25, k)
    poly = r * rng.uniform(0.55, 1.0, k)[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
    poly = clip_convex(poly, edges)
    if len(poly) < 2:
        return np.empty((0, 3, 3)), n
    lift = c + PAINT_GAP * n
    pts = lift[None] + poly[:, :1] * u + poly[:, 1:] * v
    m = len(pts)
    tris = np.stack([np.repeat(lift[None], m, 0), pts, np.roll(pts, -1, 0)], 1)  # a fan from the hit
    return tris, n
