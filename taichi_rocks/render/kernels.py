"""The renderer's Taichi kernels: the background layer of a frame and the merge of GGUI's read-back over it.

A frame is made of two layers. The *background image* (W x H, row 0 at the bottom) holds the sky, the
ground and the *resting* rocks: :func:`rocks_pass` culls every rock to the view frustum and the draw distance
and splats the resting/sliding ones (:func:`_splat_sphere`: shaded spheres, depth-tested by an atomic min;
:func:`_splat_coverage`: sub-pixel rocks blended by coverage); :func:`paint_ground` then traces one ray per
pixel to the ground plane: a checker of ``render.ground_tile`` metre tiles anchored to *world* coordinates
(it scrolls as the vehicles drive; box-filtered, so no moire at the horizon), soft contact shadows under the
vehicles, the shadows of the vehicles and the rocks (:mod:`.shadows`; splatted by the rock pass), the
splatted rocks, haze. Everything GGUI draws (the second layer: vehicles, flying rocks as
oriented rock meshes, render/tumbling.py, or particles when small, overlays) lies above the ground plane, so
drawing the ground and what lies on it *behind* the 3D scene is exact (up to a rock touching a tire's contact
patch). :func:`to_u8` merges the two.

Lighting is GGUI's: colour * (ambient + sun * max(n . l, 0)). Kernel arguments are grouped in the structs
below (local f32 coordinates, the simulation's Z up); the buffers live in a :class:`Buffers`.
"""

import math

import taichi as ti

from ..config.streams import LOOK_THIN
from ..engine import drawing
from ..engine.trees import FieldTrees
from ..engine.world import FLYING
from .looks import KEY
from .rocklook import _rock_color, _unit, rock_color, rock_shape
from .shadows import SHADE_ONE, Shade, smooth01 as _smooth01, splat_shadow as _splat_shadow, \
    take_shade as _take_shade, vehicle_shadows as _vehicle_shadows
from .tiles import Visible, tile_in_view
from .tumbling import MESH_PX, put

__all__ = ["COVERAGE_ONE", "SHADE_ONE", "OPAQUE_PX", "SHAPED_PX", "CameraBasis", "Frustum", "Sizing", "Light", "Ground",
           "Palette", "Shade", "Buffers", "Bucket", "Visible", "rock_color", "rocks_pass", "clear_buffers", "paint_ground",
           "to_u8"]

COVERAGE_ONE = 1024.0  # fixed-point unit of splatted coverage: 2^21 / (pi * 1024) = 650 rocks a pixel
OPAQUE_PX = 1.0  # splatted rocks at least this many pixels in radius are opaque spheres, smaller ones coverage
ROW_PARTS = 8  # paint_ground's rows are painted in this many pieces, in parallel
TILE_STRIDE = 7919  # a prime: the rock pass's visible tiles in a spread order (rocks_pass)
SHAPED_PX = 4.0  # from this many pixels in radius, splatted rocks get irregular outlines and facets

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
    the splatted rocks (1 x 1 placeholders unless ``splat``), the rows they touch, the vehicles' shadows, and
    three counters (rocks compacted for GGUI particles and for meshes, pixels GGUI drew)."""

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


# ------------------------------------------------------------------------------------------------ splatting
@ti.func
def _empty_key():
    """The depth-buffer value of a pixel no rock covers."""
    return ti.cast(0x7FFFFFFF, ti.i64) << 32


@ti.func
def _key_rgb(key):
    """The colour packed in a depth-buffer value."""
    rgb = ti.cast(key & 0xFFFFFF, ti.i32)
    return ti.Vector([(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255]) * (1.0 / 255.0)


@ti.func
def _splat_coverage(buf, X, Y, pr, base, fwd, light):
    """A sub-pixel rock (pr < OPAQUE_PX): its shaded colour spread bilinearly over the 2 x 2 pixels around its
    centre with weight = its area in pixels, accumulated in fixed point (order independent, so
    deterministic); the ground pass blends it by coverage, which antialiases the far gravel."""
    W, H = buf.zbuf.shape
    lam = (2.0 / 3.0) * ti.max(-fwd.dot(light.sun), 0.0)  # mean of n . l over the visible disc
    c = ti.min(ti.max(base * (light.ambient + light.sun_color * lam), 0.0), 1.0)
    area = 3.14159265 * pr * pr
    fx = X - 0.5
    fy = Y - 0.5
    i0 = ti.cast(ti.floor(fx), ti.i32)
    j0 = ti.cast(ti.floor(fy), ti.i32)
    ax = fx - i0
    ay = fy - j0
    for di, dj in ti.static(ti.ndrange(2, 2)):
        ii = i0 + di
        jj = j0 + dj
        if 0 <= ii < W and 0 <= jj < H:
            wx = ax if di == 1 else 1.0 - ax
            wy = ay if dj == 1 else 1.0 - ay
            q = wx * wy * area * COVERAGE_ONE  # <= pi * COVERAGE_ONE per rock
            if q >= 1.0:
                # r, g, b premultiplied, 21 bits each, in one i64: one atomic instead of three
                rgb = ti.cast(c[0] * q + 0.5, ti.i64) | (ti.cast(c[1] * q + 0.5, ti.i64) << 21) | \
                    (ti.cast(c[2] * q + 0.5, ti.i64) << 42)
                buf.acc[ii, jj][0] += rgb
                buf.acc[ii, jj][1] += ti.cast(q + 0.5, ti.i64)
    ti.atomic_min(buf.rows[0], ti.max(j0, 0))
    ti.atomic_max(buf.rows[1], ti.min(j0 + 1, H - 1))


@ti.func
def _shade_rgb(base, nrm, light):
    """A rock's 8-bit colour, packed, for normal ``nrm``: GGUI's lighting, clamped."""
    col = ti.min(ti.max(base * (light.ambient + light.sun_color * ti.max(nrm.dot(light.sun), 0.0)), 0.0),
                 1.0) * 255.0 + 0.5
    return (ti.cast(col[0], ti.i32) << 16) | (ti.cast(col[1], ti.i32) << 8) | ti.cast(col[2], ti.i32)


@ti.func
def _depth_key(depth, rgb):
    return (ti.cast(ti.bit_cast(ti.max(depth, 1e-4), ti.i32), ti.i64) << 24) | ti.cast(rgb, ti.i64)


@ti.func
def _splat_sphere(buf, X, Y, pr, z, r, base, cam, light):
    """An opaque shaded sphere of radius pr pixels at view depth z, pixel by pixel, depth-tested through an
    atomic min on (depth, rgb) packed in an i64 (order independent, so deterministic)."""
    W, H = buf.zbuf.shape
    j_lo = ti.max(ti.cast(ti.floor(Y - pr), ti.i32), 0)
    j_hi = ti.min(ti.cast(ti.floor(Y + pr), ti.i32), H - 1)
    inv = 1.0 / pr
    for jj in range(j_lo, j_hi + 1):
        dy = (jj + 0.5 - Y) * inv
        half = 1.0 - dy * dy
        if half > 0.0:
            span = pr * ti.sqrt(half)  # the disc's half width on this row, pixels
            i_lo = ti.max(ti.cast(ti.ceil(X - span - 0.5), ti.i32), 0)
            i_hi = ti.min(ti.cast(ti.floor(X + span - 0.5), ti.i32), W - 1)
            for ii in range(i_lo, i_hi + 1):
                dx = (ii + 0.5 - X) * inv
                nz = ti.sqrt(ti.max(half - dx * dx, 0.0))
                rgb = _shade_rgb(base, cam.right * dx + cam.up * dy - cam.fwd * nz, light)
                ti.atomic_min(buf.zbuf[ii, jj], _depth_key(z - r * nz, rgb))
    if j_lo <= j_hi:
        ti.atomic_min(buf.rows[0], j_lo)
        ti.atomic_max(buf.rows[1], j_hi)


@ti.func
def _splat_pebble(buf, X, Y, pr, z, r, base, cam, light, shape):
    """An opaque rock of mean radius pr pixels: its outline the circle's radius times a sum of 2-, 3- and
    5-fold waves (``shape``: :func:`.rocklook.rock_shape`), shaded as a flattened sphere fitted to that
    outline whose normal leans by an angle-dependent tilt towards its rim (facets); depth-tested like
    :func:`_splat_sphere`. cos k phi and sin k phi come from the pixel's offset by the angle-addition formulas
    (no trigonometry)."""
    W, H = buf.zbuf.shape
    reach = pr * shape[8]
    j_lo = ti.max(ti.cast(ti.floor(Y - reach), ti.i32), 0)
    j_hi = ti.min(ti.cast(ti.floor(Y + reach), ti.i32), H - 1)
    inv = 1.0 / pr
    for jj in range(j_lo, j_hi + 1):
        dy = (jj + 0.5 - Y) * inv
        half = shape[8] * shape[8] - dy * dy
        if half > 0.0:
            span = pr * ti.sqrt(half)
            i_lo = ti.max(ti.cast(ti.ceil(X - span - 0.5), ti.i32), 0)
            i_hi = ti.min(ti.cast(ti.floor(X + span - 0.5), ti.i32), W - 1)
            for ii in range(i_lo, i_hi + 1):
                dx = (ii + 0.5 - X) * inv
                d = ti.sqrt(dx * dx + dy * dy) + 1e-6
                inv_d = 1.0 / d
                c1 = dx * inv_d
                s1 = dy * inv_d
                c2 = c1 * c1 - s1 * s1
                s2 = 2.0 * c1 * s1
                c3 = c1 * c2 - s1 * s2
                s3 = s1 * c2 + c1 * s2
                c5 = c2 * c3 - s2 * s3
                s5 = s2 * c3 + c2 * s3
                rho = shape[7] * (1.0 + shape[0] * c2 - shape[1] * s2 + shape[2] * c3 - shape[3] * s3
                                  + shape[4] * c5 - shape[5] * s5)
                if d < rho:
                    q = d / rho
                    lean = 0.5 * q * (1.0 + q)  # ~ q^1.5: flatter on top than a sphere, steeper at the rim
                    tilt = shape[6] * q * (shape[2] * c2 - shape[1] * s3 + shape[5] * c5)
                    nx = c1 * lean - s1 * tilt
                    ny = s1 * lean + c1 * tilt
                    nz = ti.sqrt(ti.max(1.0 - nx * nx - ny * ny, 0.02))  # (nx, ny, nz) is (about) a unit
                    rgb = _shade_rgb(base, cam.right * nx + cam.up * ny - cam.fwd * nz, light)
                    ti.atomic_min(buf.zbuf[ii, jj], _depth_key(z - r * nz, rgb))
    if j_lo <= j_hi:
        ti.atomic_min(buf.rows[0], j_lo)
        ti.atomic_max(buf.rows[1], j_hi)


@ti.func
def _splat_rock(buf, X, Y, pr, z, r, rid, phase, cam, light):
    """Draw one resting rock into the software buffers: centre (X, Y) in pixels (row 0 at the bottom),
    projected radius pr pixels, view depth z, radius r; its colour and (from SHAPED_PX pixels) its outline
    from its id."""
    base = _rock_color(rid, phase)
    if pr < OPAQUE_PX:
        _splat_coverage(buf, X, Y, pr, base, cam.fwd, light)
    elif pr < SHAPED_PX:
        _splat_sphere(buf, X, Y, pr, z, r, base, cam, light)
    else:
        _splat_pebble(buf, X, Y, pr, z, r, base, cam, light, rock_shape(rid))


@ti.func
def _compact(bucket, count, p, draw_r, col):
    """Append one rock to the bucket (the first ``count`` entries are valid; count may exceed the capacity)."""
    j = ti.atomic_add(count[None], 1)
    if j < bucket.cap:
        bucket.pos[j] = p
        bucket.rad[j] = draw_r
        bucket.col[j] = col


@ti.func
def _draw_rock(buf, bucket, meshes, p, r, quat, ph, rid, cam, fr, size, light, sh):
    """One rock of the rock pass (:func:`rocks_pass`): local centre ``p`` and radius ``r`` (f32), orientation
    ``quat``, phase ``ph``, id ``rid``; its shadows, then culled to the view and splatted or compacted (a flying
    rock of at least MESH_PX pixels into ``meshes``, render/tumbling.py)."""
    W = ti.cast(buf.zbuf.shape[0], ti.f32)
    H = ti.cast(buf.zbuf.shape[1], ti.f32)
    d = p - cam.eye
    if ti.static(buf.shadows):
        if ph == FLYING:
            hgt = ti.max(p[2] - sh.z, 0.0)
            c = ti.Vector([p[0], p[1]]) + sh.shift * hgt
            if (c[0] - cam.eye[0]) ** 2 + (c[1] - cam.eye[1]) ** 2 < fr.far * fr.far:
                _splat_shadow(buf, c, r, 0.3 * r + 0.01 * hgt, 0, cam, fr, sh)
    z = d.dot(cam.fwd)
    if z > fr.near - r and d.norm_sqr() < fr.far * fr.far:
        x = d.dot(cam.right)
        y = d.dot(cam.up)
        if ti.abs(x) < z * fr.tan_x + r * fr.sec_x and ti.abs(y) < z * fr.tan_y + r * fr.sec_y:
            if ti.static(buf.shadows):
                if ph != FLYING and r * fr.px_per_rad >= sh.contact_px * ti.max(z, fr.near):
                    c = ti.Vector([p[0], p[1]]) + sh.shift * ti.max(p[2] - sh.z, 0.0)
                    _splat_shadow(buf, c, r, 0.35 * r, 1, cam, fr, sh)
            splatted = False
            if ti.static(buf.splat):
                if ph != FLYING:
                    splatted = True
                    if z > fr.near:
                        zz = ti.max(z, fr.near)
                        _splat_rock(buf, (x / (zz * fr.tan_x) + 1.0) * 0.5 * W,
                                    (y / (zz * fr.tan_y) + 1.0) * 0.5 * H, r * fr.px_per_rad / zz, zz, r,
                                    rid, ph, cam, light)
            if ti.static(meshes.on):  # the simulation tumbles its rocks (engine/drawing.py has_orientations)
                if not splatted and ph == FLYING:
                    pr = r * fr.px_per_rad / ti.max(z, fr.near)
                    if pr >= MESH_PX:
                        put(meshes, buf.mesh_count, p, r, pr, quat, _rock_color(rid, ph), rid)
                        splatted = True
            if not splatted:
                keep = True
                draw_r = r
                if ph != FLYING and size.lod_px > 0:
                    pr = r * fr.px_per_rad / ti.max(z, fr.near)  # projected radius, pixels
                    if pr < size.lod_px:
                        q = pr / size.lod_px
                        if _unit(rid, LOOK_THIN.first) < q * q:  # keep a fraction q^2, drawn 1/q larger: same coverage
                            draw_r = r / q
                        else:
                            keep = False
                if keep:
                    _compact(bucket, buf.count, p, draw_r * size.radius_scale, _rock_color(rid, ph))


@ti.kernel
def rocks_pass(world: ti.template(), buf: ti.template(), bucket: ti.template(), meshes: ti.template(),
               cam: CameraBasis, fr: Frustum, size: Sizing, light: Light, sh: Shade, vis: ti.template(),
               tiles: _vec2):
    """Cull the rocks of ``world`` to the view frustum and the draw distance, as the engine offers them
    (engine/drawing.py): the listed rocks (every rock, or with active stepping the active list), then, if the
    resting rocks wait in tiles, the tiles in view (:mod:`.tiles`: the slots whose tile may be in view are
    listed in ``vis``; ``tiles`` is the floating origin's shift in tiles, ``Simulation.tile_shift()``). Then

    * flying rocks of at least MESH_PX pixels are compacted into ``meshes`` (atomic counter
      ``buf.mesh_count``; render/tumbling.py draws them as oriented rock meshes), smaller ones as below;
    * ``buf.splat``: resting and sliding rocks are drawn into the software buffers (:func:`_splat_rock`),
      flying rocks are compacted into ``bucket`` for GGUI;
    * otherwise every visible rock is compacted into ``bucket`` (atomic counter ``buf.count``; the first
      ``count`` entries are valid, count may exceed the bucket's capacity: then the caller re-runs with a bigger
      bucket), far resting rocks thinned (a fraction q^2 kept by a hash of rock_id and drawn 1/q larger,
      q = projected radius / lod_px);
    * ``buf.shadows``: every flying rock within the draw distance (in view or not) casts its shadow along the
      sun (:func:`_splat_shadow`, channel 0), and every visible resting rock of at least ``sh.contact_px``
      pixels its own, a contact shadow just beside it (channel 1).

    Every rock goes through :func:`_draw_rock`, and the buffers are order independent: the same rocks give the
    same image whether they are in the active list or the tiles.
    """
    buf.count[None] = 0
    buf.mesh_count[0] = 0
    buf.mesh_count[1] = 0
    if ti.static(buf.splat):
        buf.rows[0] = buf.zbuf.shape[1]
        buf.rows[1] = -1
    if ti.static(buf.shadows):
        buf.rows[2] = buf.shade.shape[1]
        buf.rows[3] = -1
    for i in range(drawing.listed_count(world)):
        p, r, ph, rid = drawing.listed_rock(world, i)
        _draw_rock(buf, bucket, meshes, p, r, drawing.listed_orientation(world, i), ph, rid, cam, fr, size, light,
                   sh)
    if ti.static(drawing.has_tiles(world)):
        vis.count[None] = 0
        for t in range(drawing.slot_count(world)):
            if drawing.slot_rocks(world, t) > 0:
                lo, s, ground, r_max = drawing.slot_bounds(world, t, tiles)
                if tile_in_view(lo, s, ground, r_max, cam, fr):
                    vis.slots[ti.atomic_add(vis.count[None], 1)] = t
        # visible tiles in a spread order (a permutation unless the prime divides the count): near tiles (big
        # splats) lie together in the list, and a CPU thread takes consecutive iterations (see spread_stride)
        n_vis = vis.count[None]
        for v, k in ti.ndrange(n_vis, drawing.slot_capacity(world)):
            t = vis.slots[ti.cast(ti.cast(v, ti.i64) * TILE_STRIDE % n_vis, ti.i32) if n_vis % TILE_STRIDE else v]
            if k < drawing.slot_rocks(world, t):
                p, r, ph, rid = drawing.slot_rock(world, t, k)  # at rest: never a mesh, no orientation read
                _draw_rock(buf, bucket, meshes, p, r, ti.Vector([0.0, 0.0, 0.0, 1.0]), ph, rid, cam, fr, size,
                           light, sh)


@ti.kernel
def clear_buffers(buf: ti.template()):
    for i, j in buf.zbuf:
        buf.zbuf[i, j] = _empty_key()
        buf.acc[i, j] = ti.Vector([0, 0], ti.i64)
    for i, j in buf.shade:
        buf.shade[i, j] = ti.Vector([0, 0], ti.i32)


# ------------------------------------------------------------------------------------------------ background
@ti.func
def _composite(col, buf, i, j):
    """Blend the splatted rocks of pixel (i, j) over ``col`` and reset the pixel's buffers."""
    a = buf.acc[i, j]
    if a[1] > 0:
        w = ti.cast(a[1], ti.f32) * (1.0 / COVERAGE_ONE)
        m = ti.cast(0x1FFFFF, ti.i64)
        rgb = ti.Vector([ti.cast(a[0] & m, ti.f32), ti.cast((a[0] >> 21) & m, ti.f32),
                         ti.cast((a[0] >> 42) & m, ti.f32)]) * (1.0 / COVERAGE_ONE)
        if w >= 1.0:
            col = rgb / w
        else:
            col = col * (1.0 - w) + rgb
        buf.acc[i, j] = ti.Vector([0, 0], ti.i64)
    key = buf.zbuf[i, j]
    if key != _empty_key():
        col = _key_rgb(key)
        buf.zbuf[i, j] = _empty_key()
    return col


@ti.func
def _to_rgba8(col):
    c = ti.min(ti.max(col, 0.0), 1.0) * 255.0 + 0.5
    return ti.Vector([ti.cast(c[0], ti.u8), ti.cast(c[1], ti.u8), ti.cast(c[2], ti.u8), ti.u8(255)])


@ti.func
def _checker(hx, hy, fx, fy, wrap, inv_tile):
    """The checker's share of its second colour at ground point (hx, hy) over a footprint fx x fy (m): box-
    filtered square waves (difference of the integrated triangle wave), so far tiles blend to the mean."""
    qx = (hx + wrap[0]) * inv_tile
    qy = (hy + wrap[1]) * inv_tile
    wx = fx * inv_tile + 1e-4
    wy = fy * inv_tile + 1e-4
    sa = (qx - 0.5 * wx) * 0.5
    sb = (qx + 0.5 * wx) * 0.5
    ta = (qy - 0.5 * wy) * 0.5
    tb = (qy + 0.5 * wy) * 0.5
    sx = 2.0 * (ti.abs(sa - ti.floor(sa) - 0.5) - ti.abs(sb - ti.floor(sb) - 0.5)) / wx  # in [-1, 1]
    sy = 2.0 * (ti.abs(ta - ti.floor(ta) - 0.5) - ti.abs(tb - ti.floor(tb) - 0.5)) / wy
    return 0.5 - 0.5 * sx * sy


@ti.func
def _ground_row(buf, j, i0, i1, dr, t, rocks, shaded, cam, fr, ground, pal, n_cars):
    """Columns i0 .. i1-1 of row j where the ground shows: ray ``dr`` through the row's centre line meets the
    plane at distance t (in units of dr). The pixel's ray is dr + right * u. With ``buf.shadows``, the light the
    sun gives is taken away in the shadows (the vehicles', and the flying rocks' splatted ones) from the ground
    and the resting rocks alike, in the resting rocks' contact shadows from the ground only."""
    W, H = buf.sky.shape
    inv_tile = 1.0 / ground.tile
    right = cam.right
    # pixel footprint on the plane: d(hit)/d(column) = t * du (du horizontal),
    # d(hit)/d(row) = t * (dv - d * dv_z / dz), d = dr + right * u
    gu = right * (2.0 * fr.tan_x / W * t)
    gv0 = t * (cam.up * (2.0 * fr.tan_y / H) - dr * (cam.up[2] * (2.0 * fr.tan_y / H) / dr[2]))
    gv1 = -t * right * (cam.up[2] * (2.0 * fr.tan_y / H) / dr[2])  # times u
    bx0 = cam.eye[0] + t * dr[0]
    by0 = cam.eye[1] + t * dr[1]
    r2 = dr.norm_sqr()
    for i in range(i0, i1):
        u = ((i + 0.5) / W * 2.0 - 1.0) * fr.tan_x
        hx = bx0 + t * u * right[0]
        hy = by0 + t * u * right[1]
        g = ti.Vector([0.0, 0.0, 0.0])
        dark = False  # in a shadow
        lit = ti.Vector([1.0, 1.0, 1.0])  # the share of the light left, for everything on the ground
        lit_ground = lit  # for the ground itself
        vs = _vehicle_shadows(hx, hy, buf.cars, n_cars, ground.shift, buf.shadows)
        if ti.static(buf.shadows):
            sv = ti.Vector([0.0, 0.0])
            if shaded:
                sv = _take_shade(buf, i, j)
            s0 = ti.max(sv[0], vs[1])
            if s0 > 0.0 or sv[1] > 0.0:
                dark = True
                lit = 1.0 + (pal.umbra - 1.0) * s0
                lit_ground = 1.0 + (pal.umbra - 1.0) * ti.max(s0, sv[1])
        covered = False
        if ti.static(buf.splat):
            if rocks:
                key = buf.zbuf[i, j]
                if key != _empty_key():  # an opaque rock: no ground to compute under it
                    covered = True
                    buf.zbuf[i, j] = _empty_key()
                    buf.acc[i, j] = ti.Vector([0, 0], ti.i64)
                    g = _key_rgb(key)
                    if dark:
                        g *= lit
        if not covered:
            fx = ti.abs(gu[0]) + ti.abs(gv0[0] + gv1[0] * u)
            fy = ti.abs(gu[1]) + ti.abs(gv0[1] + gv1[1] * u)
            chk = _checker(hx, hy, fx, fy, ground.wrap, inv_tile)
            g = (pal.ground_a + (pal.ground_b - pal.ground_a) * chk) * pal.light
            g *= vs[0]
            if dark:
                g *= lit_ground / lit  # the ground's own shadows; the common ones after the rocks are blended in
            if ti.static(buf.splat):
                if rocks:
                    g = _composite(g, buf, i, j)
            if dark:
                g *= lit
        x = t * ti.sqrt(r2 + u * u) / ground.haze_dist  # distance / haze distance (right is a unit normal to dr)
        fog = 1.0 - 1.0 / (1.0 + x * (1.0 + 0.5 * x))  # ~ 1 - exp(-x), cheaper
        buf.sky[i, j] = _to_rgba8(g + (pal.horizon - g) * fog)


@ti.func
def _sky_row(buf, j, i0, i1, dr, rocks, shaded, pal):
    """Columns i0 .. i1-1 of row j above the horizon: one colour (elevation of the row's centre), rocks only
    when the camera is lower than they are. (A shadow splatted across the horizon is reset here.)"""
    elev = dr[2] / ti.sqrt(dr.norm_sqr())
    col = pal.horizon + (pal.sky - pal.horizon) * _smooth01(elev * (1.0 / 0.12))
    px = _to_rgba8(col)
    if ti.static(buf.shadows):
        if shaded:
            for i in range(i0, i1):
                buf.shade[i, j] = ti.Vector([0, 0], ti.i32)
    if ti.static(buf.splat):
        if rocks:
            for i in range(i0, i1):
                buf.sky[i, j] = _to_rgba8(_composite(col, buf, i, j))
        else:
            for i in range(i0, i1):
                buf.sky[i, j] = px
    else:
        for i in range(i0, i1):
            buf.sky[i, j] = px


@ti.kernel
def paint_ground(buf: ti.template(), cam: CameraBasis, fr: Frustum, ground: Ground, pal: Palette, n_cars: ti.i32):
    """Sky, ground and (``buf.splat``) the splatted resting rocks, one ray per pixel, into the background
    image ``buf.sky`` (W, H), row 0 at the bottom.

    Ground: the plane z = ground.z, a checker of ``ground.tile`` metre squares whose parity is that of the
    *world* tile (``ground.wrap`` = origin mod 2 tiles), box-filtered over the pixel's footprint (no moire: far
    tiles blend to the mean colour), lit like GGUI lights a mesh facing up (``pal.light`` = ambient + sun *
    cos), darkened under the first ``n_cars`` vehicles of ``buf.cars`` (soft contact shadows) and
    (``buf.shadows``) in the shadows (:func:`_ground_row`), then the rocks blended in (:func:`_composite`), then
    hazed towards ``pal.horizon`` with distance. Sky: ``pal.sky`` above, lightening to ``pal.horizon`` at the
    horizon. Everything GGUI draws afterwards lies above the plane, so painting the ground behind the 3D scene
    is exact; resting rocks lie on it (a rock just in front of a tire's contact patch is the only thing that
    can come out behind instead of in front). Parallel over pieces of rows (ROW_PARTS a row, rows in a
    spread order: :func:`spread_stride`): the camera has no roll (its right vector is horizontal), so a row's
    rays share their height and distance to the plane. Each pixel is painted once, so the image does not depend
    on the order.
    """
    W, H = buf.sky.shape
    h = cam.eye[2] - ground.z
    for q, part in ti.ndrange(H, ti.static(ROW_PARTS)):
        j = (q * ti.static(spread_stride(buf.sky.shape[1]))) % H  # rows spread: see spread_stride
        i0 = part * W // ROW_PARTS
        i1 = (part + 1) * W // ROW_PARTS
        v = ((j + 0.5) / H * 2.0 - 1.0) * fr.tan_y
        dr = cam.fwd + cam.up * v  # ray through the row's centre line
        dz = dr[2]  # right is horizontal (no roll), so the whole row shares dz and the plane distance t
        rocks = False
        shaded = False
        if ti.static(buf.splat):
            rocks = buf.rows[0] <= j <= buf.rows[1]
        if ti.static(buf.shadows):
            shaded = buf.rows[2] <= j <= buf.rows[3]
        if dz < 0.0 and h > 0.0:
            _ground_row(buf, j, i0, i1, dr, h / -dz, rocks, shaded, cam, fr, ground, pal, n_cars)
        else:
            _sky_row(buf, j, i0, i1, dr, rocks, shaded, pal)


@ti.kernel
def to_u8(raw: ti.types.ndarray(dtype=ti.f32, ndim=3), out: ti.types.ndarray(dtype=ti.u8, ndim=3),
          buf: ti.template()):
    """GGUI's read-back (W, H, 4) float, y up -> upright (H, W, 3) uint8 (np.rot90 plus the cast), with the
    background image ``buf.sky`` (W, H) wherever GGUI left its clear colour :data:`KEY` (nothing drawn there).

    Merging here instead of ``canvas.set_image`` saves lavapipe a full-screen textured quad and GGUI a
    staging copy (~25 ms of CPU a frame at 720p). GGUI draws without antialiasing, so a pixel is either
    cleared (exactly the key, k/255 floats) or drawn. Works in 32 x 32 tiles so that both the reads and the
    transposed writes stay in cache. ``buf.drawn_px`` counts the pixels GGUI drew.
    """
    H = out.shape[0]
    W = out.shape[1]
    buf.drawn_px[None] = 0
    for by, bx in ti.ndrange((H + 31) // 32, (W + 31) // 32):
        n = 0
        for ex, ey in ti.ndrange(32, 32):
            x = bx * 32 + ex
            yy = by * 32 + ey  # row of the read-back (0 = bottom)
            if x < W and yy < H:
                r = ti.cast(raw[x, yy, 0] * 255.0 + 0.5, ti.i32)
                g = ti.cast(raw[x, yy, 1] * 255.0 + 0.5, ti.i32)
                b = ti.cast(raw[x, yy, 2] * 255.0 + 0.5, ti.i32)
                if r == KEY[0] and g == KEY[1] and b == KEY[2]:
                    px = buf.sky[x, yy]
                    out[H - 1 - yy, x, 0] = px[0]
                    out[H - 1 - yy, x, 1] = px[1]
                    out[H - 1 - yy, x, 2] = px[2]
                else:
                    n += 1
                    out[H - 1 - yy, x, 0] = ti.cast(ti.min(ti.max(r, 0), 255), ti.u8)
                    out[H - 1 - yy, x, 1] = ti.cast(ti.min(ti.max(g, 0), 255), ti.u8)
                    out[H - 1 - yy, x, 2] = ti.cast(ti.min(ti.max(b, 0), 255), ti.u8)
        buf.drawn_px[None] += n
