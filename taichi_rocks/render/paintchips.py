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
from typing import NamedTuple

import numpy as np

from ..motion.bodies import FACE_CORNERS, body_parts, hexahedron_planes
from .marks import CRACK, clip_convex, mark_rng

__all__ = ["Face", "body_faces", "face_of", "paint_chip", "PAINT_R", "PAINT_MARGIN", "PAINT_GAP"]

PAINT_R = ((0.004, 0.010), (0.010, 0.025))  # m: a paint chip's radius, (s = 0, s = 1) of the chip and crack class
PAINT_MARGIN = 0.004  # m: paint chips stop this far inside the face's edges
PAINT_GAP = 0.0015  # m between a paint chip and its face, outside


class Face(NamedTuple):
    """A face of a body (:func:`body_faces`, body frame): its ``corners`` (4, 3), its outward plane (n, d: n . x
    = d on it), two unit axes ``u``, ``v`` in it (u horizontal unless the face is), its corners in (u, v),
    counter-clockwise (``flat``), and its edges' outward unit normals in (u, v) (``outs``, edge k from corner k)."""

    corners: np.ndarray
    plane: np.ndarray
    u: np.ndarray
    v: np.ndarray
    flat: np.ndarray
    outs: np.ndarray


def _face(corners, plane) -> Face:
    n = plane[:3]
    u = np.cross(n, (0.0, 0.0, 1.0))
    if np.linalg.norm(u) < 1e-6:  # a top or bottom face
        u = np.cross(n, (0.0, 1.0, 0.0))
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    flat = np.stack([corners @ u, corners @ v], 1)
    d0, d1 = flat[1] - flat[0], flat[2] - flat[1]
    if d0[0] * d1[1] - d0[1] * d1[0] < 0:  # clockwise: turn it round
        flat = flat[::-1]
    d = np.roll(flat, -1, axis=0) - flat
    outs = np.stack([d[:, 1], -d[:, 0]], 1) / np.linalg.norm(d, axis=1)[:, None]
    return Face(corners, plane, u, v, flat, outs)


def body_faces(spec) -> list:
    """Every face of the body of vehicle ``spec`` (motion/bodies.py, body frame on the ground): :class:`Face`."""
    out = []
    for part in body_parts(spec, 0.0).parts:
        c = part.corners()
        planes = hexahedron_planes(c)
        out += [_face(c[list(idx)], planes[f]) for f, idx in enumerate(FACE_CORNERS)]
    return out


def face_of(faces, point, normal):
    """The face of ``faces`` (:func:`body_faces`) a hit at ``point`` with outward ``normal`` is on: of the faces
    turned within 60 degrees of the normal, the one whose plane passes nearest the point (the first of equals)."""
    p, n = np.asarray(point, np.float64), np.asarray(normal, np.float64)
    planes = np.array([f.plane for f in faces])
    turn = planes[:, :3] @ n
    near = np.abs(planes[:, :3] @ p - planes[:, 3])
    ok = np.flatnonzero(turn >= 0.5)
    if not len(ok):
        return None
    return faces[ok[np.lexsort((-turn[ok], near[ok]))[0]]]


def paint_chip(e, s: float, faces) -> tuple:
    """The paint chip of event ``e`` (body frame) of severity ``s`` on the face of ``faces`` it hit
    (:func:`face_of`): triangles (K, 3, 3), body frame, PAINT_GAP outside the face and clipped to it
    PAINT_MARGIN inside its edges (none if the hit lies outside that), and the face's outward normal (3,). An
    irregular flake: 7-9 corners round the hit at 0.55-1 of its radius, drawn from a hash of (rock, step)."""
    face = face_of(faces, e["point"], e["normal"])
    if face is None:
        return np.empty((0, 3, 3)), np.array(e["normal"], np.float64)
    n, u, v = face.plane[:3], face.u, face.v
    c = np.asarray(e["point"], np.float64)
    c = c - (n @ c - face.plane[3]) * n  # on the face
    at = face.flat - np.array([c @ u, c @ v])  # its corners seen from the hit
    reach = np.einsum("kj,kj->k", face.outs, at) - PAINT_MARGIN  # inward offsets of its edges
    if np.any(reach < 0.0):  # the hit itself lies outside the face's margin
        return np.empty((0, 3, 3)), n
    edges = [(float(o[0]), float(o[1]), float(r)) for o, r in zip(face.outs, reach)]
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
