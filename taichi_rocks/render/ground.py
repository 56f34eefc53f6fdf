"""The ground pass (a Taichi kernel): sky, ground and the splatted resting rocks, one ray per pixel, into the
background image (render/kernels.py :class:`.kernels.Buffers` ``sky``), or (offscreen, ``merge``) under GGUI's
image straight into the frame: a pixel GGUI drew is GGUI's, and no ground is computed under it.

Ground: a plane, a box-filtered checker of world-anchored tiles (:func:`_checker`: the integrated square wave,
so far tiles blend to the mean), lit as GGUI lights a mesh facing up, darkened in the vehicles' soft contact
shadows and in the shadows of :mod:`.shadows`, the splatted rocks blended in (:func:`_composite`), hazed with
distance (1 - 1 / (1 + x (1 + x / 2)) ~ 1 - exp(-x), x = distance / haze distance). Sky: a gradient from the
horizon up. The camera has no roll, so a row of pixels shares its ray's height and its distance to the plane.
"""

import taichi as ti

from .kernels import COVERAGE_ONE, CameraBasis, Frustum, Ground, Palette, empty_key, is_key, key_rgb, raw_rgb, \
    spread_stride
from .shadows import smooth01 as _smooth01, take_shade as _take_shade, vehicle_shadows as _vehicle_shadows

__all__ = ["ROW_PARTS", "paint_ground"]

ROW_PARTS = 8  # paint_ground's rows are painted in this many pieces, in parallel


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
    if key != empty_key():
        col = key_rgb(key)
        buf.zbuf[i, j] = empty_key()
    return col


@ti.func
def _to_rgba8(col):
    c = ti.min(ti.max(col, 0.0), 1.0) * 255.0 + 0.5
    return ti.Vector([ti.cast(c[0], ti.u8), ti.cast(c[1], ti.u8), ti.cast(c[2], ti.u8), ti.u8(255)])


@ti.func
def _emit(buf, out: ti.template(), i, j, px, merge: ti.template()):
    """Pixel (i, j) (row 0 at the bottom) of colour ``px`` (rgba8): into the background image, or (``merge``)
    into the upright frame ``out`` (H, W, 3)."""
    if ti.static(merge):
        H = out.shape[0]
        for c in ti.static(range(3)):
            out[H - 1 - j, i, c] = px[c]
    else:
        buf.sky[i, j] = px


@ti.func
def _drawn(buf, raw: ti.template(), out: ti.template(), i, j, rocks, shaded, merge: ti.template()):
    """``merge``: did GGUI draw pixel (i, j) (``raw``: its read-back, (W, H, 4) floats, row 0 at the bottom; a
    pixel it left has its clear colour, render/looks.py KEY)? Then its colour goes to ``out`` and the splat
    buffers there are reset, as painting it would have."""
    drawn = False
    if ti.static(merge):
        r, g, b = raw_rgb(raw, i, j)
        if not is_key(r, g, b):
            drawn = True
            _emit(buf, out, i, j, ti.Vector([ti.cast(ti.min(ti.max(c, 0), 255), ti.u8) for c in (r, g, b)]), merge)
            if ti.static(buf.splat):
                if rocks:
                    buf.zbuf[i, j] = empty_key()
                    buf.acc[i, j] = ti.Vector([0, 0], ti.i64)
            if ti.static(buf.shadows):
                if shaded:
                    buf.shade[i, j] = ti.Vector([0, 0], ti.i32)
    return drawn


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
def _ground_row(buf, j, i0, i1, dr, t, rocks, shaded, cam, fr, ground, pal, n_cars, raw: ti.template(),
                out: ti.template(), merge: ti.template()):
    """Columns i0 .. i1-1 of row j where the ground shows: ray ``dr`` through the row's centre line meets the
    plane at distance t (in units of dr). The pixel's ray is dr + right * u. With ``buf.shadows``, the light the
    sun gives is taken away in the shadows (the vehicles', and the flying rocks' splatted ones) from the ground
    and the resting rocks alike, in the resting rocks' contact shadows from the ground only. ``merge``: the
    pixels GGUI drew are its (:func:`_drawn`); returns how many."""
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
    n_drawn = 0
    for i in range(i0, i1):
        if _drawn(buf, raw, out, i, j, rocks, shaded, merge):
            n_drawn += 1
            continue
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
                if key != empty_key():  # an opaque rock: no ground to compute under it
                    covered = True
                    buf.zbuf[i, j] = empty_key()
                    buf.acc[i, j] = ti.Vector([0, 0], ti.i64)
                    g = key_rgb(key)
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
        _emit(buf, out, i, j, _to_rgba8(g + (pal.horizon - g) * fog), merge)
    return n_drawn


@ti.func
def _sky_row(buf, j, i0, i1, dr, rocks, shaded, pal, raw: ti.template(), out: ti.template(), merge: ti.template()):
    """Columns i0 .. i1-1 of row j above the horizon: one colour (elevation of the row's centre), rocks only
    when the camera is lower than they are. (A shadow splatted across the horizon is reset here.) ``merge``: the
    pixels GGUI drew are its (:func:`_drawn`); returns how many."""
    elev = dr[2] / ti.sqrt(dr.norm_sqr())
    col = pal.horizon + (pal.sky - pal.horizon) * _smooth01(elev * (1.0 / 0.12))
    px = _to_rgba8(col)
    n_drawn = 0
    for i in range(i0, i1):
        if _drawn(buf, raw, out, i, j, rocks, shaded, merge):
            n_drawn += 1
            continue
        if ti.static(buf.shadows):
            if shaded:
                buf.shade[i, j] = ti.Vector([0, 0], ti.i32)
        c = px
        if ti.static(buf.splat):
            if rocks:
                c = _to_rgba8(_composite(col, buf, i, j))
        _emit(buf, out, i, j, c, merge)
    return n_drawn


@ti.kernel
def paint_ground(buf: ti.template(), cam: CameraBasis, fr: Frustum, ground: Ground, pal: Palette, n_cars: ti.i32,
                 raw: ti.types.ndarray(dtype=ti.f32, ndim=3), out: ti.types.ndarray(dtype=ti.u8, ndim=3),
                 merge: ti.template()):
    """Sky, ground and (``buf.splat``) the splatted resting rocks, one ray per pixel, into the background
    image ``buf.sky`` (W, H), row 0 at the bottom; or (``merge``) into the upright frame ``out`` (H, W, 3)
    wherever GGUI's read-back ``raw`` ((W, H, 4) floats in [0, 1], row 0 at the bottom) has its clear colour,
    GGUI's pixels elsewhere (``buf.drawn_px`` counts them): the same frame as the background image merged under
    GGUI's (GGUI draws without antialiasing, so a pixel is either cleared, exactly the key, or drawn), without
    the ground under what GGUI drew. (Otherwise ``raw`` and ``out`` are not read: any arrays will do.)

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
    buf.drawn_px[None] = 0
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
        n_drawn = 0
        if dz < 0.0 and h > 0.0:
            n_drawn = _ground_row(buf, j, i0, i1, dr, h / -dz, rocks, shaded, cam, fr, ground, pal, n_cars, raw, out,
                                  merge)
        else:
            n_drawn = _sky_row(buf, j, i0, i1, dr, rocks, shaded, pal, raw, out, merge)
        if ti.static(merge):
            buf.drawn_px[None] += n_drawn

