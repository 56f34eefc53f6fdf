"""What a rock looks like, from its id alone (stable across frames and memory re-orderings): its colour
(:func:`_rock_color`, host twin :func:`rock_color`) and the outline and facets of a splatted resting rock
(:func:`rock_shape`, drawn by :func:`.splat._splat_pebble`).
"""

import math

import numpy as np
import taichi as ti

from ..config.streams import LOOK_COLOUR, LOOK_SHAPE
from ..engine.randomness import mix32, mix32_np
from ..engine.world import FLYING

__all__ = ["rock_color", "rock_shape", "rock_shape_np", "outline", "ELONGATION", "TRIANGULARITY", "CORNERS", "FACETS"]

ELONGATION = (0.06, 0.26)  # amplitude of the outline's 2-fold wave (relative to the radius)
TRIANGULARITY = (0.02, 0.12)  # amplitude of its 3-fold wave
CORNERS = (0.0, 0.06)  # amplitude of its 5-fold wave
FACETS = (0.8, 2.0)  # how far the normal leans round the rim, times the waves

_GOLDEN = 0x9E3779B9
_SALT = 0x85EBCA6B


@ti.func
def _unit(rid, salt):
    """A number in [0, 1) from a rock id and a salt: stable across frames and memory re-orderings."""
    h = mix32(ti.cast(ti.cast(rid, ti.u32) * ti.u32(_GOLDEN) + ti.cast(salt, ti.u32) * ti.u32(_SALT), ti.u32))
    return ti.cast(h >> ti.u32(8), ti.f32) * (1.0 / 16777216.0)


def _unit_np(rid, salt) -> np.ndarray:
    """:func:`_unit` on the host."""
    x = (np.asarray(rid, np.int64).astype(np.uint64) * np.uint64(_GOLDEN)
         + np.asarray(salt, np.int64).astype(np.uint64) * np.uint64(_SALT))
    return (mix32_np(x) >> np.uint32(8)) / 16777216.0


_GREY = (0.60, 0.59, 0.57)
_BROWN = (0.62, 0.50, 0.37)
_DARK = (0.36, 0.34, 0.32)
_WARM = (1.30, 1.12, 0.85)  # flying rocks: warmer and lighter, so the splash reads
_LIFT = 0.06


@ti.func
def _rock_color(rid, phase):
    a = _unit(rid, LOOK_COLOUR.first)
    b = _unit(rid, LOOK_COLOUR.first + 1)
    c = _unit(rid, LOOK_COLOUR.first + 2)
    grey = ti.Vector(_GREY)
    brown = ti.Vector(_BROWN)
    dark = ti.Vector(_DARK)
    col = grey + (brown - grey) * (a * a)
    col = col + (dark - col) * (0.55 * c * c)
    col = col * (0.72 + 0.45 * b)
    if phase == FLYING:
        col = ti.min(col * ti.Vector(_WARM) + _LIFT, 1.0)
    return col


def rock_color(rock_id, phase: int = 0) -> np.ndarray:
    """Host twin of the kernels' rock colour (float64; equal to the kernels' to f32 round-off)."""
    a, b, c = (float(_unit_np(rock_id, salt)) for salt in LOOK_COLOUR.ids)
    grey, brown, dark = np.array(_GREY), np.array(_BROWN), np.array(_DARK)
    col = grey + (brown - grey) * a * a
    col = col + (dark - col) * 0.55 * c * c
    col = col * (0.72 + 0.45 * b)
    if phase == FLYING:
        col = np.minimum(col * np.array(_WARM) + _LIFT, 1.0)
    return col


@ti.func
def rock_shape(rid):
    """A rock's outline and facets: (A2, B2, A3, B3, A5, B5, tilt, k, outer): the outline at angle phi is
    k (1 + A2 cos 2phi - B2 sin 2phi + A3 cos 3phi - B3 sin 3phi + A5 cos 5phi - B5 sin 5phi) radii, with
    amplitudes drawn in ELONGATION, TRIANGULARITY and CORNERS and phases uniform (the rock's orientation);
    k keeps the rock's area that of its circle (the mean of the outline squared is 1 + the sum of the squared
    amplitudes / 2); ``outer`` bounds the outline."""
    s = ti.static(LOOK_SHAPE.first)  # + 0 A2, 1 A3, 2 phase 2, 3 phase 3, 4 tilt, 5 A5, 6 phase 5
    a2 = ELONGATION[0] + (ELONGATION[1] - ELONGATION[0]) * _unit(rid, s)
    a3 = TRIANGULARITY[0] + (TRIANGULARITY[1] - TRIANGULARITY[0]) * _unit(rid, s + 1)
    a5 = CORNERS[0] + (CORNERS[1] - CORNERS[0]) * _unit(rid, s + 5)
    p2 = 2.0 * math.pi * _unit(rid, s + 2)
    p3 = 2.0 * math.pi * _unit(rid, s + 3)
    p5 = 2.0 * math.pi * _unit(rid, s + 6)
    tilt = FACETS[0] + (FACETS[1] - FACETS[0]) * _unit(rid, s + 4)
    k = 1.0 / ti.sqrt(1.0 + 0.5 * (a2 * a2 + a3 * a3 + a5 * a5))
    return ti.Vector([a2 * ti.cos(p2), a2 * ti.sin(p2), a3 * ti.cos(p3), a3 * ti.sin(p3), a5 * ti.cos(p5),
                      a5 * ti.sin(p5), tilt, k, k * (1.0 + a2 + a3 + a5)])


def rock_shape_np(rock_id) -> np.ndarray:
    """Host twin of :func:`rock_shape` (float64)."""
    u = [float(_unit_np(rock_id, salt)) for salt in LOOK_SHAPE.ids]  # in rock_shape's order
    a2 = ELONGATION[0] + (ELONGATION[1] - ELONGATION[0]) * u[0]
    a3 = TRIANGULARITY[0] + (TRIANGULARITY[1] - TRIANGULARITY[0]) * u[1]
    a5 = CORNERS[0] + (CORNERS[1] - CORNERS[0]) * u[5]
    p2, p3, p5 = (2.0 * math.pi * u[k] for k in (2, 3, 6))
    k = 1.0 / math.sqrt(1.0 + 0.5 * (a2 * a2 + a3 * a3 + a5 * a5))
    return np.array([a2 * math.cos(p2), a2 * math.sin(p2), a3 * math.cos(p3), a3 * math.sin(p3),
                     a5 * math.cos(p5), a5 * math.sin(p5), FACETS[0] + (FACETS[1] - FACETS[0]) * u[4], k,
                     k * (1.0 + a2 + a3 + a5)])


def outline(shape, phi) -> np.ndarray:
    """The outline of a rock of ``shape`` (:func:`rock_shape_np`) at angles ``phi`` (rad, counter-clockwise
    from the image's right, y up), in radii."""
    phi = np.asarray(phi, np.float64)
    return shape[7] * (1.0 + shape[0] * np.cos(2 * phi) - shape[1] * np.sin(2 * phi) + shape[2] * np.cos(3 * phi)
                       - shape[3] * np.sin(3 * phi) + shape[4] * np.cos(5 * phi) - shape[5] * np.sin(5 * phi))
