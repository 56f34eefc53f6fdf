"""The ground pass (a Taichi kernel): sky, ground and the splatted resting rocks, one ray per pixel, into the
background image (render/kernels.py :class:`.kernels.Buffers` ``sky``).

Ground: a plane, a box-filtered checker of world-anchored tiles (:func:`_checker`: the integrated square wave,
so far tiles blend to the mean), lit as GGUI lights a mesh facing up, darkened in the vehicles' soft contact
shadows and in the shadows of :mod:`.shadows`, the splatted rocks blended in (:func:`_composite`), hazed with
distance (1 - 1 / (1 + x (1 + x / 2)) ~ 1 - exp(-x), x = distance / haze distance). Sky: a gradient from the
horizon up. The camera has no roll, so a row of pixels shares its ray's height and its distance to the plane.
"""

import taichi as ti

from .kernels import COVERAGE_ONE, CameraBasis, Frustum, Ground, Palette, empty_key, \
    key_rgb, spread_stride
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

