"""The sun's light and shadows on the background layer, host side: what the kernels of :mod:`.shadows` and the
ground pass (render/ground.py) are given each frame.

The shadow of a point at height z above the ground falls at its foot plus ``shift`` * z, shift = -s_xy / s_z
(s: the unit vector towards the sun, its z at least 0.05: a sun just above the horizon casts shadows 20 times
as long as the things are high, no longer). A sphere's shadow is 1 / sin(elevation) longer along ``away``, the
horizontal direction away from the sun. The vehicles cast theirs as boxes from the ground to their top
(:func:`shadow_casters`); the ground's light is GGUI's for a face turned up, ambient + sun * max(s_z, 0), and
what is left in full shadow the ambient light (``umbra`` = ambient / light).
"""

from __future__ import annotations

import math

import numpy as np
import taichi as ti

from . import kernels as K
from .buffers import MAX_CARS
from .ground import paint_ground
from .looks import AMBIENT, GROUND_A, GROUND_B, HAZE, SUN_COLOR
from .shadows import Shade

__all__ = ["CONTACT_PX", "shadow_shift", "shade_of", "shadow_casters", "paint_sky_and_ground"]

CONTACT_PX = 3.0  # resting rocks at least this many pixels in radius darken the ground beside them (smaller
# ones are many, and their contact shadows hardly show)


def shadow_shift(sun) -> tuple:
    """Where a point's shadow falls, per metre of its height above the ground: -sun_xy / sun_z."""
    sz = max(float(sun[2]), 0.05)
    return (-float(sun[0]) / sz, -float(sun[1]) / sz)


def shade_of(sun, ground_local: float) -> Shade:
    """The shadows' geometry for a sun direction (unit, towards the sun) over the ground at z = ``ground_local``
    (the local frame's): see :class:`.shadows.Shade`."""
    sz = max(float(sun[2]), 0.05)  # the sun just above the horizon at the lowest: shadows 20 x as long
    horiz = math.hypot(float(sun[0]), float(sun[1]))
    away = (-float(sun[0]) / horiz, -float(sun[1]) / horiz) if horiz > 1e-9 else (1.0, 0.0)
    return Shade(z=ground_local, shift=ti.Vector(shadow_shift(sun)), away=ti.Vector(away),
                 sin_el=sz / math.hypot(sz, horiz), contact_px=CONTACT_PX)


def shadow_casters(cars, poses, vehicles, origin, sun_dir) -> int:
    """Upload the footprints and heights (local frame) of the vehicles at ``poses`` (``vehicles``: their specs)
    into ``cars`` (:class:`.kernels.Buffers` ``cars``) for their shadows; return how many (at most MAX_CARS)."""
    rows = np.zeros((MAX_CARS, 11), np.float32)
    shift = np.array(shadow_shift(sun_dir))
    k = 0
    for p, v in zip(poses, vehicles):
        if k == MAX_CARS:
            break
        loc = np.asarray(p.position, np.float64) - origin
        top = 0.8 * v.tire_radius + v.height
        soft = 0.35 + 0.4 * v.width  # of the contact shadow
        mid = loc[:2] + 0.5 * top * shift  # the sun shadow's middle, and a circle round both shadows
        reach = 0.5 * math.hypot(v.length, v.width) + 0.5 * top * float(np.hypot(*shift)) + max(soft, 0.5)
        rows[k] = (loc[0], loc[1], math.cos(p.heading), math.sin(p.heading), 0.5 * v.length, 0.5 * v.width,
                   soft, top, mid[0], mid[1], reach * reach)
        k += 1
    cars.from_numpy(rows)
    return k


_NONE = (np.zeros((1, 1, 4), np.float32), np.zeros((1, 1, 3), np.uint8))  # paint_ground's arrays, not merging


def paint_sky_and_ground(buf, cam, frustum, settings, ground_z: float, vehicles, poses, origin, sun_dir,
                         merge=None) -> None:
    """The background image of a frame (render/ground.py :func:`.ground.paint_ground`): the sky, the ground at
    ``ground_z`` (world) lit by the sun ``sun_dir`` with the shadows of the ``vehicles`` at ``poses``, the
    splatted rocks; ``cam`` and ``frustum`` the kernels' view, ``settings`` the renderer's (render/settings.py).
    ``merge`` = (GGUI's read-back, the frame): painted into the frame under GGUI's image instead."""
    period = 2.0 * settings.tile
    wrap = (float(np.mod(origin[0], period)), float(np.mod(origin[1], period)))
    light = tuple(a + l * max(float(sun_dir[2]), 0.0) for a, l in zip(AMBIENT, SUN_COLOR))
    n_cars = shadow_casters(buf.cars, poses, vehicles, origin, sun_dir)
    ground = K.Ground(z=ground_z - float(origin[2]), wrap=ti.Vector(wrap), tile=settings.tile,
                      haze_dist=HAZE * settings.draw_distance, shift=ti.Vector(shadow_shift(sun_dir)))
    umbra = tuple(a / l for a, l in zip(AMBIENT, light))
    palette = K.Palette(ground_a=ti.Vector(GROUND_A), ground_b=ti.Vector(GROUND_B), light=ti.Vector(light),
                        sky=ti.Vector(settings.background), horizon=ti.Vector(settings.horizon),
                        umbra=ti.Vector(umbra))
    paint_ground(buf, cam, frustum, ground, palette, n_cars, *(merge or _NONE), merge is not None)
