"""Rock shapes, host side (NumPy): the low-poly prototypes that stand for the simulation's spheres where rocks
are drawn as meshes, the export's instances (output/usd.py) and the renderer's flying rocks (render/tumbling.py).

A prototype is the unit icosahedron subdivided once (42 points, 80 triangles) with a smooth, low-frequency radial
relief (four squared dot products with random directions), a little noise, flattened along two axes and scaled
to mean radius 1; the same ``variant`` always gives the same rock. Meshes are (points (P, 3) float32,
face_vertex_counts (F,) int32, face_vertex_indices (I,) int32), faces counter-clockwise seen from outside.
"""

from __future__ import annotations

import numpy as np

__all__ = ["rock_prototype", "flat_triangles"]

_GOLDEN = (1.0 + 5.0 ** 0.5) / 2.0
_ICOSAHEDRON_FACES = np.array([
    [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
    [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
    [8, 6, 7], [9, 8, 1]])


def _icosphere() -> tuple[np.ndarray, np.ndarray]:
    """The unit icosahedron subdivided once: 42 points, 80 triangles."""
    g = _GOLDEN
    v = [(-1, g, 0), (1, g, 0), (-1, -g, 0), (1, -g, 0), (0, -1, g), (0, 1, g), (0, -1, -g), (0, 1, -g),
         (g, 0, -1), (g, 0, 1), (-g, 0, -1), (-g, 0, 1)]
    pts = [np.array(p, np.float64) / np.linalg.norm(p) for p in v]
    mid: dict = {}

    def middle(a, b):
        key = (min(a, b), max(a, b))
        if key not in mid:
            m = pts[a] + pts[b]
            pts.append(m / np.linalg.norm(m))
            mid[key] = len(pts) - 1
        return mid[key]

    faces = []
    for a, b, c in _ICOSAHEDRON_FACES:
        ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
        faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    return np.array(pts), np.array(faces)


def rock_prototype(variant: int):
    """An irregular rock of mean radius ~1 (a bumpy, slightly flattened icosphere), the same for the same
    ``variant``: scaled by a rock's radius it stands for the simulation's sphere."""
    pts, faces = _icosphere()
    rng = np.random.default_rng(9173 + int(variant))
    dirs = rng.normal(size=(4, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    bumps = (pts @ dirs.T) ** 2 @ rng.uniform(-0.35, 0.35, 4)  # smooth, low-frequency radial relief
    r = 1.0 + bumps + rng.uniform(-0.06, 0.06, len(pts))
    p = pts * r[:, None] * np.array([1.0, rng.uniform(0.8, 1.0), rng.uniform(0.6, 0.85)])
    p /= np.mean(np.linalg.norm(p, axis=1))
    return (p.astype(np.float32), np.full(len(faces), 3, np.int32), faces.reshape(-1).astype(np.int32))


def flat_triangles(variant: int):
    """Prototype ``variant`` as separate triangles for flat shading: (points (3F, 3), normals (3F, 3)) float32,
    three points per face in its order and each face's outward unit normal on its three points."""
    pts, counts, idx = rock_prototype(variant)
    tri = pts[idx.reshape(-1, 3)].astype(np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return tri.reshape(-1, 3).astype(np.float32), np.repeat(n, 3, axis=0).astype(np.float32)
