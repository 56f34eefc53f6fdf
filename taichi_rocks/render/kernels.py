"""The background layer's buffers: the kernels' argument structs, the fields of a frame's background
(:class:`Buffers`) and of the rocks compacted for GGUI (:class:`Bucket`), how the splat buffers pack a rock
(depth key, coverage), how a pixel of GGUI's read-back is read (:func:`raw_rgb`, :func:`is_key`), and the kernel
that clears the buffers.

A frame is made of two layers. The *background image* (W x H, row 0 at the bottom) holds the sky, the ground and
the *resting* rocks: the rock pass (render/splat.py :func:`.splat.rocks_pass`) culls every rock to the view
frustum and the draw distance and splats the resting/sliding ones into the buffers here (shaded spheres,
depth-tested by an atomic min on a depth key; sub-pixel rocks blended by coverage); the ground pass
(render/ground.py :func:`.ground.paint_ground`) then traces one ray per pixel to the ground plane: a checker of
``render.ground_tile`` metre tiles anchored to *world* coordinates (it scrolls as the vehicles drive;
box-filtered, so no moire at the horizon), soft contact shadows under the vehicles, the shadows of the vehicles
and the rocks (:mod:`.shadows`; splatted by the rock pass), the splatted rocks, haze. Everything GGUI draws (the
second layer: vehicles, flying rocks as oriented rock meshes, render/tumbling.py, or particles when small,
overlays) lies above the ground plane, so drawing the ground and what lies on it *behind* the 3D scene is exact
(up to a rock touching a tire's contact patch). Offscreen the ground pass paints straight into the frame,
under GGUI's read-back, only where GGUI drew nothing.

Lighting is GGUI's: colour * (ambient + sun * max(n . l, 0)). Kernel arguments are grouped in the structs
below (local f32 coordinates, the simulation's Z up); the buffers live in a :class:`Buffers`.
"""

import math

import taichi as ti

from ..engine.trees import FieldTrees
from .looks import KEY

__all__ = ["COVERAGE_ONE", "CameraBasis", "Frustum", "Sizing", "Light", "Ground", "Palette", "Buffers", "Bucket",
           "spread_stride", "empty_key", "key_rgb", "key_depth", "raw_rgb", "is_key", "depth_key", "clear_buffers",
           "cover_from"]

COVERAGE_ONE = 1024.0  # fixed-point unit of splatted coverage: 2^21 / (pi * 1024) = 650 rocks a pixel

_vec2 = ti.types.vector(2, ti.f32)
_vec3 = ti.types.vector(3, ti.f32)

#: the camera as the kernels see it: eye and unit basis (right is horizontal: no roll)
CameraBasis = ti.types.struct(eye=_vec3, fwd=_vec3, right=_vec3, up=_vec3)
#: the view volume: image half-extents at 1 m depth (tan_*), their secants (a sphere's margin), near and far
#: (the draw distance) planes, pixels per metre at 1 m depth
Frustum = ti.types.struct(tan_x=ti.f32, tan_y=ti.f32, sec_x=ti.f32, sec_y=ti.f32, near=ti.f32, far=ti.f32,
                          px_per_rad=ti.f32)
#: rocks drawn as GGUI particles: far resting rocks thinned below ``lod_px`` pixels (0: never), radii scaled
Sizing = ti.types.struct(lod_px=ti.f32, radius_scale=ti.f32)
#: the lights: unit vector towards the sun, ambient and sun colours
Light = ti.types.struct(sun=_vec3, ambient=_vec3, sun_color=_vec3)
#: the ground plane z, the world's checker phase (origin mod 2 tiles), the tile size, the haze distance, the
#: shift of a shadow per metre of height (-sun_xy / sun_z)
Ground = ti.types.struct(z=ti.f32, wrap=_vec2, tile=ti.f32, haze_dist=ti.f32, shift=_vec2)
#: the checker's two colours, the ground's light (ambient + sun * cos), the sky's colour and the horizon's,
#: the share of the light left in full shadow (ambient / light)
Palette = ti.types.struct(ground_a=_vec3, ground_b=_vec3, light=_vec3, sky=_vec3, horizon=_vec3, umbra=_vec3)


@ti.data_oriented
class Buffers:
    """The fields of the background layer, ``width`` x ``height``: the image (``sky``), the software buffers of
    the splatted rocks (1 x 1 placeholders unless ``splat``), the pixels GGUI drew over them (``cover``), the rows
    they touch, the vehicles' shadows, and three counters (rocks compacted for GGUI particles and for meshes,
    pixels GGUI drew)."""

    def __init__(self, width: int, height: int, splat: bool, max_cars: int, shadows: bool = False,
                 trees: FieldTrees = None):
        self.splat = bool(splat)  # read at compile time
        self.shadows = bool(shadows)  # read at compile time
        t = FieldTrees.given(trees, self)
        self.count = t.scalar(ti.i32)
        self.mesh_count = t.scalar(ti.i32, 2)  # flying rocks compacted for meshes, per level of detail
        # (render/tumbling.py)
        self.sky = t.image(width, height, (4, ti.u8))  # rows contiguous: written row by row
        bw, bh = (width, height) if splat else (1, 1)
        # a tree of their own: next to 32-bit fields Vulkan can misalign 64-bit ones (see engine/trees.py); here
        # the buffers landed at 4 mod 8 after the sky, and zbuf[0] overwrote the sky's last pixel each frame
        # zbuf: (depth bits << 24) | rgb8 of the nearest opaque rock; acc: packed premultiplied rgb, weight
        # (COVERAGE_ONE = 1 pixel)
        self.zbuf, self.acc = t.image(bw, bh, (1, ti.i64), (2, ti.i64))
        # shadows cast on the ground, SHADE_ONE = full: by flying rocks (on everything), by resting rocks (on the
        # ground only: a rock does not shade itself)
        sw, sh = (width, height) if shadows else (1, 1)
        self.shade = t.image(sw, sh, (2, ti.i32))
        # the pixels GGUI drew, offscreen (cover_from): the rock pass splats nothing there (splat.py Pass)
        cw, ch = (width, height) if splat or shadows else (1, 1)
        self.cover = t.image(cw, ch, (1, ti.u8))
        self.rows = t.scalar(ti.i32, 4)  # lowest and highest row a splat touched, and a shadow
        clear_buffers(self)
        # x, y, cos, sin, half length, half width, contact shadow softness, height of the top, and the centre
        # (x, y) and squared radius of a circle holding the sun's shadow (local, m)
        self.cars = t.vector(11, ti.f32, max_cars)
        self.drawn_px = t.scalar(ti.i32)


@ti.data_oriented
class Bucket:
    """Compacted rocks for GGUI particles: positions, radii and colours of at most ``cap`` rocks."""

    def __init__(self, cap: int, trees: FieldTrees = None):
        self.cap = int(cap)  # read at compile time
        t = FieldTrees.given(trees, self)
        self.pos = t.vector(3, ti.f32, cap)
        self.rad = t.scalar(ti.f32, cap)
        self.col = t.vector(3, ti.f32, cap)


def spread_stride(n: int) -> int:
    """A stride coprime with ``n`` near n / golden ratio: ``(q * stride) % n`` visits 0 .. n-1 once each, and
    any run of consecutive q lands all over the range.

    Taichi 1.7.4's CPU threads take chunks of consecutive iterations, and when the costly ones lay together at
    the start of the range (the ground rows at the bottom of the image) one thread did nearly all of them: on 2
    cores a loop whose first half is costly took 1.0 cores' time, spread 0.6."""
    stride = max(1, round(n * 0.6180339887))
    while math.gcd(stride, n) != 1:
        stride += 1
    return stride


# ------------------------------------------------------------------------------------------------ packing
@ti.func
def empty_key():
    """The depth-buffer value of a pixel no rock covers."""
    return ti.cast(0x7FFFFFFF, ti.i64) << 32


@ti.func
def key_rgb(key):
    """The colour packed in a depth-buffer value."""
    rgb = ti.cast(key & 0xFFFFFF, ti.i32)
    return ti.Vector([(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255]) * (1.0 / 255.0)


@ti.func
def key_depth(key):
    """The depth packed in a depth-buffer value (:func:`depth_key`; the empty key's is not a depth)."""
    return ti.bit_cast(ti.cast(key >> 24, ti.i32), ti.f32)


@ti.func
def raw_rgb(raw: ti.template(), x, y):
    """Pixel (x, y) of GGUI's read-back (floats in [0, 1]) as three 8-bit integers, rounded."""
    return (ti.cast(raw[x, y, 0] * 255.0 + 0.5, ti.i32), ti.cast(raw[x, y, 1] * 255.0 + 0.5, ti.i32),
            ti.cast(raw[x, y, 2] * 255.0 + 0.5, ti.i32))


@ti.func
def is_key(r, g, b):
    """Is this read-back colour GGUI's clear colour :data:`KEY` (nothing of the 3D layer drawn there)?"""
    return r == KEY[0] and g == KEY[1] and b == KEY[2]


@ti.func
def depth_key(depth, rgb):
    """A depth-buffer value: the depth's f32 bits (positive, so they order as the depths do) over an rgb8."""
    return (ti.cast(ti.bit_cast(ti.max(depth, 1e-4), ti.i32), ti.i64) << 24) | ti.cast(rgb, ti.i64)


@ti.kernel
def clear_buffers(buf: ti.template()):
    for i, j in buf.zbuf:
        buf.zbuf[i, j] = empty_key()
        buf.acc[i, j] = ti.Vector([0, 0], ti.i64)
    for i, j in buf.shade:
        buf.shade[i, j] = ti.Vector([0, 0], ti.i32)


@ti.kernel
def cover_from(raw: ti.types.ndarray(dtype=ti.f32, ndim=3), buf: ti.template()):
    """``buf.cover``: 1 where GGUI's read-back ``raw`` ((W, H, 4) floats, row 0 at the bottom) has a pixel drawn,
    0 where it left its clear colour."""
    for x, y in ti.ndrange(buf.cover.shape[0], buf.cover.shape[1]):
        r, g, b = raw_rgb(raw, x, y)
        buf.cover[x, y] = ti.u8(0) if is_key(r, g, b) else ti.u8(1)
