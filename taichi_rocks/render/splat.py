"""The rock pass (a Taichi kernel): every rock culled to the view frustum and the draw distance, the resting
ones splatted into the background layer's buffers (render/kernels.py :class:`.kernels.Buffers`), the flying ones
compacted for GGUI (particles, or oriented meshes: render/tumbling.py), their shadows splatted (:mod:`.shadows`).

Offscreen the pass runs in two parts (:data:`COMPACT`, :data:`SPLAT`; :data:`ALL` at once in a shown window or
with dust): before GGUI's scene is declared, the flying rocks it draws are compacted (the listed rocks only: the
tiles hold none); after GGUI drew it, the resting rocks and the shadows are splatted, but not into the pixels GGUI
drew (``buf.cover``, render/kernels.py ``cover_from``: the ground pass shows GGUI's colour there, so nothing
there could change the frame).

Splats: :func:`_splat_sphere`, shaded spheres depth-tested by an atomic min on (depth, rgb) packed in an i64;
:func:`_splat_pebble`, the same with an irregular outline and facets from SHAPED_PX pixels (render/rocklook.py);
:func:`_splat_coverage`, sub-pixel rocks blended by coverage in fixed point. Every buffer is order independent,
so the image is deterministic whatever the threads do. Lighting is GGUI's: colour * (ambient + sun * max(n . l,
0)).
"""

import taichi as ti

from ..config.streams import LOOK_THIN
from ..engine import drawing
from ..engine.world import FLYING
from .kernels import COVERAGE_ONE, CameraBasis, Frustum, Light, Sizing, depth_key
from .rocklook import _rock_color, _unit, rock_shape
from .shadows import Shade, splat_shadow as _splat_shadow
from .tiles import tile_in_view
from .tumbling import MESH_PX, put

__all__ = ["OPAQUE_PX", "SHAPED_PX", "TILE_STRIDE", "ALL", "COMPACT", "SPLAT", "Pass", "rocks_pass"]

OPAQUE_PX = 1.0  # splatted rocks at least this many pixels in radius are opaque spheres, smaller ones coverage
TILE_STRIDE = 7919  # a prime: the rock pass's visible tiles in a spread order (rocks_pass)
SHAPED_PX = 4.0  # from this many pixels in radius, splatted rocks get irregular outlines and facets

ALL, COMPACT, SPLAT = 0, 1, 2  # the parts of the rock pass (module docstring)

_vec2 = ti.types.vector(2, ti.f32)
#: the floating origin's shift in tiles (``Simulation.tile_shift()``), the part of the pass (ALL, COMPACT, SPLAT)
Pass = ti.types.struct(tiles=_vec2, part=ti.i32)


@ti.func
def _hidden(buf, i, j, skip):
    """Does GGUI draw pixel (i, j) (``skip``: the SPLAT part, after it drew)?"""
    return skip and buf.cover[i, j] != 0


@ti.func
def _splat_coverage(buf, X, Y, pr, base, fwd, light, skip):
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
        if 0 <= ii < W and 0 <= jj < H and not _hidden(buf, ii, jj, skip):
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
def _splat_sphere(buf, X, Y, pr, z, r, base, cam, light, skip):
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
                if not _hidden(buf, ii, jj, skip):
                    dx = (ii + 0.5 - X) * inv
                    nz = ti.sqrt(ti.max(half - dx * dx, 0.0))
                    rgb = _shade_rgb(base, cam.right * dx + cam.up * dy - cam.fwd * nz, light)
                    ti.atomic_min(buf.zbuf[ii, jj], depth_key(z - r * nz, rgb))
    if j_lo <= j_hi:
        ti.atomic_min(buf.rows[0], j_lo)
        ti.atomic_max(buf.rows[1], j_hi)


@ti.func
def _splat_pebble(buf, X, Y, pr, z, r, base, cam, light, shape, skip):
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
                if d < rho and not _hidden(buf, ii, jj, skip):
                    q = d / rho
                    lean = 0.5 * q * (1.0 + q)  # ~ q^1.5: flatter on top than a sphere, steeper at the rim
                    tilt = shape[6] * q * (shape[2] * c2 - shape[1] * s3 + shape[5] * c5)
                    nx = c1 * lean - s1 * tilt
                    ny = s1 * lean + c1 * tilt
                    nz = ti.sqrt(ti.max(1.0 - nx * nx - ny * ny, 0.02))  # (nx, ny, nz) is (about) a unit
                    rgb = _shade_rgb(base, cam.right * nx + cam.up * ny - cam.fwd * nz, light)
                    ti.atomic_min(buf.zbuf[ii, jj], depth_key(z - r * nz, rgb))
    if j_lo <= j_hi:
        ti.atomic_min(buf.rows[0], j_lo)
        ti.atomic_max(buf.rows[1], j_hi)


@ti.func
def _splat_rock(buf, X, Y, pr, z, r, rid, phase, cam, light, skip):
    """Draw one resting rock into the software buffers: centre (X, Y) in pixels (row 0 at the bottom),
    projected radius pr pixels, view depth z, radius r; its colour and (from SHAPED_PX pixels) its outline
    from its id; ``skip``: not into the pixels GGUI drew."""
    base = _rock_color(rid, phase)
    if pr < OPAQUE_PX:
        _splat_coverage(buf, X, Y, pr, base, cam.fwd, light, skip)
    elif pr < SHAPED_PX:
        _splat_sphere(buf, X, Y, pr, z, r, base, cam, light, skip)
    else:
        _splat_pebble(buf, X, Y, pr, z, r, base, cam, light, rock_shape(rid), skip)


@ti.func
def _compact(bucket, count, p, draw_r, col):
    """Append one rock to the bucket (the first ``count`` entries are valid; count may exceed the capacity)."""
    j = ti.atomic_add(count[None], 1)
    if j < bucket.cap:
        bucket.pos[j] = p
        bucket.rad[j] = draw_r
        bucket.col[j] = col


@ti.func
def _draw_rock(buf, bucket, meshes, p, r, quat, ph, rid, cam, fr, size, light, sh, part):
    """One rock of the rock pass (:func:`rocks_pass`): local centre ``p`` and radius ``r`` (f32), orientation
    ``quat``, phase ``ph``, id ``rid``; its shadows, then culled to the view and splatted or compacted (a flying
    rock of at least MESH_PX pixels into ``meshes``, render/tumbling.py); of ``part`` (ALL, COMPACT, SPLAT) only
    the compaction, or only the splats (not into the pixels GGUI drew)."""
    W = ti.cast(buf.zbuf.shape[0], ti.f32)
    H = ti.cast(buf.zbuf.shape[1], ti.f32)
    skip = part == SPLAT
    d = p - cam.eye
    if ti.static(buf.shadows):
        if ph == FLYING and part != COMPACT:
            hgt = ti.max(p[2] - sh.z, 0.0)
            c = ti.Vector([p[0], p[1]]) + sh.shift * hgt
            if (c[0] - cam.eye[0]) ** 2 + (c[1] - cam.eye[1]) ** 2 < fr.far * fr.far:
                _splat_shadow(buf, c, r, 0.3 * r + 0.01 * hgt, 0, cam, fr, sh, skip)
    z = d.dot(cam.fwd)
    if z > fr.near - r and d.norm_sqr() < fr.far * fr.far:
        x = d.dot(cam.right)
        y = d.dot(cam.up)
        if ti.abs(x) < z * fr.tan_x + r * fr.sec_x and ti.abs(y) < z * fr.tan_y + r * fr.sec_y:
            if ti.static(buf.shadows):
                if ph != FLYING and part != COMPACT and r * fr.px_per_rad >= sh.contact_px * ti.max(z, fr.near):
                    c = ti.Vector([p[0], p[1]]) + sh.shift * ti.max(p[2] - sh.z, 0.0)
                    _splat_shadow(buf, c, r, 0.35 * r, 1, cam, fr, sh, skip)
            splatted = False
            if ti.static(buf.splat):
                if ph != FLYING:
                    splatted = True
                    if z > fr.near and part != COMPACT:
                        zz = ti.max(z, fr.near)
                        _splat_rock(buf, (x / (zz * fr.tan_x) + 1.0) * 0.5 * W,
                                    (y / (zz * fr.tan_y) + 1.0) * 0.5 * H, r * fr.px_per_rad / zz, zz, r,
                                    rid, ph, cam, light, skip)
            if part != SPLAT:
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
                            if _unit(rid, LOOK_THIN.first) < q * q:  # keep a fraction q^2, drawn 1/q larger
                                draw_r = r / q
                            else:
                                keep = False
                    if keep:
                        _compact(bucket, buf.count, p, draw_r * size.radius_scale, _rock_color(rid, ph))


@drawing.world_kernel(param="world")
def rocks_pass(world: ti.template(), buf: ti.template(), bucket: ti.template(), meshes: ti.template(),
               cam: CameraBasis, fr: Frustum, size: Sizing, light: Light, sh: Shade, vis: ti.template(), step: Pass):
    """Cull the rocks of ``world`` to the view frustum and the draw distance, as the engine offers them
    (engine/drawing.py): the listed rocks (every rock, or with active stepping the active list), then, if the
    resting rocks wait in tiles, the tiles in view (:mod:`.tiles`: the slots whose tile may be in view are
    listed in ``vis``; ``step.tiles`` is the floating origin's shift in tiles, ``Simulation.tile_shift()``). Then

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

    ``step.part``: ALL of that, or only the compaction (COMPACT: the listed rocks; splat mode), or only the
    splats and shadows (SPLAT), none into a pixel ``buf.cover`` marks (module docstring). Every rock goes through
    :func:`_draw_rock`, and the buffers are order independent: the same rocks give the same image whether they
    are in the active list or the tiles.
    """
    if step.part != SPLAT:
        buf.count[None] = 0
        buf.mesh_count[0] = 0
        buf.mesh_count[1] = 0
    if step.part != COMPACT:
        if ti.static(buf.splat):
            buf.rows[0] = buf.zbuf.shape[1]
            buf.rows[1] = -1
        if ti.static(buf.shadows):
            buf.rows[2] = buf.shade.shape[1]
            buf.rows[3] = -1
    for i in range(drawing.listed_count(world)):
        p, r, ph, rid = drawing.listed_rock(world, i)
        _draw_rock(buf, bucket, meshes, p, r, drawing.listed_orientation(world, i), ph, rid, cam, fr, size, light,
                   sh, step.part)
    if ti.static(drawing.has_tiles(world)):
        if step.part != COMPACT:  # the tiles hold resting rocks only: splatted, never compacted
            vis.count[None] = 0
            for t in range(drawing.slot_count(world)):
                if drawing.slot_rocks(world, t) > 0:
                    lo, s, ground, r_max = drawing.slot_bounds(world, t, step.tiles)
                    if tile_in_view(lo, s, ground, r_max, cam, fr):
                        vis.slots[ti.atomic_add(vis.count[None], 1)] = t
            # visible tiles in a spread order (a permutation unless the prime divides the count): near tiles (big
            # splats) lie together in the list, and a CPU thread takes consecutive iterations (see spread_stride)
            n_vis = vis.count[None]
            for v, k in ti.ndrange(n_vis, drawing.slot_capacity(world)):
                t = vis.slots[ti.cast(ti.cast(v, ti.i64) * TILE_STRIDE % n_vis, ti.i32) if n_vis % TILE_STRIDE
                              else v]
                if k < drawing.slot_rocks(world, t):
                    p, r, ph, rid = drawing.slot_rock(world, t, k)  # at rest: never a mesh, no orientation read
                    _draw_rock(buf, bucket, meshes, p, r, ti.Vector([0.0, 0.0, 0.0, 1.0]), ph, rid, cam, fr, size,
                               light, sh, step.part)
