"""Geometry and motion for exported scenes, host side (NumPy only): rock prototypes (motion/rockshapes.py, which
the renderer's flying rocks draw too), vehicle boxes and wheel cylinders, quaternions, per-id random numbers,
the follow camera.

Meshes are (points (P, 3) float32, face_vertex_counts (F,) int32, face_vertex_indices (I,) int32), faces
counter-clockwise seen from outside (USD's right-handed default).
"""

from __future__ import annotations


import numpy as np

from ..motion.rockshapes import rock_prototype

__all__ = ["rock_prototype", "box_mesh", "cylinder_mesh", "uniforms", "axis_angle", "quat_mul", "camera_matrix"]

def box_mesh(center, size):
    """An axis-aligned box: 8 points, 6 quads."""
    c, h = np.asarray(center, np.float64), np.asarray(size, np.float64) / 2.0
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], np.float64)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return ((c + corners * h).astype(np.float32), np.full(6, 4, np.int32), np.array(quads, np.int32).reshape(-1))


def cylinder_mesh(radius: float, width: float, segments: int = 16):
    """A cylinder about the y axis (a wheel on its axle), centred at the origin: tread quads and two caps."""
    th = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack([radius * np.cos(th), np.zeros(segments), radius * np.sin(th)], axis=1)
    left, right = ring + [0.0, width / 2, 0.0], ring + [0.0, -width / 2, 0.0]
    pts = np.concatenate([left, right])
    k = np.arange(segments)
    k2 = (k + 1) % segments
    tread = np.stack([k, k2, segments + k2, segments + k], axis=1)
    caps = [k[::-1], segments + k]  # +y cap seen from +y, -y cap seen from -y: both counter-clockwise
    counts = np.array([4] * segments + [segments, segments], np.int32)
    indices = np.concatenate([tread.reshape(-1), *caps]).astype(np.int32)
    return pts.astype(np.float32), counts, indices


# ------------------------------------------------------------------------------------------ per-id numbers
_M64 = np.uint64(0xFFFFFFFFFFFFFFFF)


def _splitmix64(x: np.ndarray) -> np.ndarray:
    x = (x + np.uint64(0x9E3779B97F4A7C15)) & _M64
    x = ((x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)) & _M64
    x = ((x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)) & _M64
    return x ^ (x >> np.uint64(31))


def uniforms(ids, stream: int) -> np.ndarray:
    """Uniform numbers in [0, 1), one per id, a function of (id, stream) only (reproducible anywhere)."""
    x = np.asarray(ids, np.int64).astype(np.uint64) * np.uint64(0x100000001B3) + np.uint64(stream)
    with np.errstate(over="ignore"):
        return (_splitmix64(_splitmix64(x)) >> np.uint64(11)).astype(np.float64) / float(1 << 53)


def axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternions (x, y, z, w) of rotations by ``angle`` (rad) about unit ``axis`` (K, 3)."""
    h = 0.5 * np.asarray(angle, np.float64)
    return np.concatenate([axis * np.sin(h)[:, None], np.cos(h)[:, None]], axis=1)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products a * b of quaternions (x, y, z, w): rotate by b, then by a."""
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b.T
    return np.stack([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz], axis=1)


# ------------------------------------------------------------------------------------------ camera
def camera_matrix(eye, target) -> np.ndarray:
    """The 4x4 transform (row vectors, as USD composes them) of a camera at ``eye`` looking at ``target``,
    Z up, no roll: rows right, up, back (the camera looks along its -Z), eye."""
    fwd = np.asarray(target, np.float64) - np.asarray(eye, np.float64)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-9:  # straight down or up
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3], m[3, :3] = right, up, -fwd, eye
    return m
