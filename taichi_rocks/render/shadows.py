"""Shadows on the ground, for the background layer (:mod:`.splat`, :mod:`.ground`; Taichi functions).

The sun (unit vector s towards it) puts the shadow of a point at height z above the ground at its foot plus
``shift`` * z, shift = -s_xy / s_z. Three kinds of shadow darken the ground, each taking away the light the
sun gives there (what is left is the ambient light: ``Palette.umbra`` = ambient / (ambient + sun * cos)):

* flying rocks, every one within the draw distance, in view or not (:func:`splat_shadow`): the shadow of a
  sphere of radius r is an ellipse of half axes r across the sun's azimuth and r / sin(elevation) along it,
  drawn through the projection's local affine map (a rock's shadow is small against its distance) into a
  screen-space buffer in fixed point (atomic adds: order independent, so deterministic); it darkens the
  resting rocks too;
* resting rocks of at least a few pixels: their own shadow, just beside them (a contact shadow), in a
  second channel that darkens the ground only (a rock does not shade itself);
* vehicles, per pixel (:func:`vehicle_shadows`): the box of each, from the ground to its top, projected
  along the sun (a hexagon), with the soft contact shadow (ambient occlusion) under its footprint.
"""

import taichi as ti

__all__ = ["SHADE_ONE", "MAX_SHADOW_PX", "Shade", "smooth01", "splat_shadow", "contact_shadow", "box_shadow",
           "vehicle_shadows", "take_shade"]

SHADE_ONE = 4096  # fixed-point unit of a pixel's shadow (full shadow); summed shadows are clamped to it
MAX_SHADOW_PX = 96  # a rock's shadow is clipped to this many pixels from its centre (rocks at the lens)

_vec2 = ti.types.vector(2, ti.f32)
#: shadows on the ground: its z, the shift of a shadow per metre of height (-sun_xy / sun_z), the unit
#: horizontal direction away from the sun (the long axis of a sphere's shadow) and sin(elevation) (the shadow
#: is 1 / sin(elevation) longer along it), the smallest projected radius (px) of a resting rock that darkens
#: the ground around it
Shade = ti.types.struct(z=ti.f32, shift=_vec2, away=_vec2, sin_el=ti.f32, contact_px=ti.f32)


@ti.func
def smooth01(x):
    s = ti.min(ti.max(x, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@ti.func
def splat_shadow(buf, c, r, soft, ch, cam, fr, sh, skip):
    """A sphere's shadow on the ground, added to shadow channel ``ch``: an ellipse centred at ground point
    ``c`` (x, y), of radius ``r`` across the sun's azimuth and r / sin(elevation) along it, with soft edges
    ``soft`` m wide (at least a pixel). Drawn through the projection's local affine map at ``c`` (a rock's
    shadow is small against its distance); below a pixel, its area is added to the pixel under its centre.
    ``skip``: not into the pixels GGUI drew (``buf.cover``: render/splat.py)."""
    W, H = buf.shade.shape
    d = ti.Vector([c[0], c[1], sh.z]) - cam.eye
    z = d.dot(cam.fwd)
    if z > fr.near:
        X = d.dot(cam.right)
        Y = d.dot(cam.up)
        k = fr.px_per_rad / z
        SX = (X / (z * fr.tan_x) + 1.0) * 0.5 * W
        SY = (Y / (z * fr.tan_y) + 1.0) * 0.5 * H
        gx = (cam.right - cam.fwd * (X / z)) * k  # d(SX) / d(point): pixels per metre
        gy = (cam.up - cam.fwd * (Y / z)) * k
        jac = ti.Matrix([[gx[0], gx[1]], [gy[0], gy[1]]])  # ground (x, y) -> pixels
        soft = ti.max(soft, 1.0 / k)
        a = sh.away
        b = ti.Vector([-a[1], a[0]])
        ua = jac @ (a * (r / sh.sin_el + soft))  # the half axes on the screen
        ub = jac @ (b * (r + soft))
        hx = ti.min(ti.sqrt(ua[0] * ua[0] + ub[0] * ub[0]), MAX_SHADOW_PX)
        hy = ti.min(ti.sqrt(ua[1] * ua[1] + ub[1] * ub[1]), MAX_SHADOW_PX)
        det = jac.determinant()
        if hx < 1.0 and hy < 1.0:
            ii = ti.cast(ti.floor(SX), ti.i32)
            jj = ti.cast(ti.floor(SY), ti.i32)
            if 0 <= ii < W and 0 <= jj < H and not (skip and buf.cover[ii, jj] != 0):
                area = 3.14159265 * r * r / sh.sin_el * ti.abs(det)  # pixels
                ti.atomic_add(buf.shade[ii, jj][ch], ti.cast(ti.min(area, 1.0) * SHADE_ONE, ti.i32))
                ti.atomic_min(buf.rows[2], jj)
                ti.atomic_max(buf.rows[3], jj)
        elif ti.abs(det) > 1e-12:
            inv = jac.inverse()
            i_lo = ti.max(ti.cast(ti.floor(SX - hx), ti.i32), 0)
            i_hi = ti.min(ti.cast(ti.floor(SX + hx), ti.i32), W - 1)
            j_lo = ti.max(ti.cast(ti.floor(SY - hy), ti.i32), 0)
            j_hi = ti.min(ti.cast(ti.floor(SY + hy), ti.i32), H - 1)
            for jj in range(j_lo, j_hi + 1):
                for ii in range(i_lo, i_hi + 1):
                    g = inv @ ti.Vector([ii + 0.5 - SX, jj + 0.5 - SY])  # ground offset from the centre, m
                    ga = g.dot(a) * sh.sin_el
                    gb = g.dot(b)
                    cov = 1.0 - smooth01((ti.sqrt(ga * ga + gb * gb) - r) / soft + 0.5)
                    if cov > 0.0 and not (skip and buf.cover[ii, jj] != 0):
                        ti.atomic_add(buf.shade[ii, jj][ch], ti.cast(cov * SHADE_ONE, ti.i32))
            if j_lo <= j_hi and i_lo <= i_hi:
                ti.atomic_min(buf.rows[2], j_lo)
                ti.atomic_max(buf.rows[3], j_hi)


@ti.func
def contact_shadow(hx, hy, c):
    """The share of the light left at ground point (hx, hy) under vehicle ``c``: soft-edged rectangles of
    its footprint (ambient occlusion), down to 0.5."""
    rx = hx - c[0]
    ry = hy - c[1]
    ox = ti.abs(rx * c[2] + ry * c[3]) - c[4]
    oy = ti.abs(-rx * c[3] + ry * c[2]) - c[5]
    f = 1.0
    if ox < c[6] and oy < c[6]:
        dd = ti.sqrt(ti.max(ox, 0.0) ** 2 + ti.max(oy, 0.0) ** 2)
        f = 0.5 + 0.5 * smooth01(dd / c[6])
    return f


@ti.func
def vehicle_shadows(hx, hy, cars, n_cars, shift, sun: ti.template()):
    """The vehicles on ground point (hx, hy): (the share of the light their contact shadows leave, how much
    of the sun their boxes hide (``sun``: else 0)). Only vehicles whose bounding circle of both (``c[8:11]``:
    centre, squared radius) holds the point are looked at."""
    ao = 1.0
    s = 0.0
    for k in range(n_cars):
        if (hx - cars[k][8]) ** 2 + (hy - cars[k][9]) ** 2 < cars[k][10]:
            c = cars[k]  # x, y, cos, sin, half length, half width, contact softness, top, circle (local, m)
            ao *= contact_shadow(hx, hy, c)
            if ti.static(sun):
                s = ti.max(s, box_shadow(hx, hy, c, shift))
    return ti.Vector([ao, s])


@ti.func
def box_shadow(hx, hy, c, shift):
    """How much of the sun vehicle ``c`` hides at ground point (hx, hy), in [0, 1]: its box (its footprint,
    from the ground to its top) projected along the sun is the footprint swept by ``shift`` * z for z in
    [0, top], a convex hexagon; its signed distance is (close to) the largest over its edge normals of the
    point's distance past that edge (the box's axes, and the normal of the sweep), soft over ~15 cm."""
    rx = hx - c[0]
    ry = hy - c[1]
    qu = rx * c[2] + ry * c[3]  # in the vehicle's frame
    qv = -rx * c[3] + ry * c[2]
    du = (shift[0] * c[2] + shift[1] * c[3]) * c[7]  # the sweep of the top, vehicle frame
    dv = (-shift[0] * c[3] + shift[1] * c[2]) * c[7]
    dist = ti.max(ti.max(qu - c[4] - ti.max(du, 0.0), -c[4] + ti.min(du, 0.0) - qu),
                  ti.max(qv - c[5] - ti.max(dv, 0.0), -c[5] + ti.min(dv, 0.0) - qv))
    ln = ti.sqrt(du * du + dv * dv)
    if ln > 1e-6:
        mu = -dv / ln
        mv = du / ln
        dist = ti.max(dist, ti.abs((qu - 0.5 * du) * mu + (qv - 0.5 * dv) * mv)
                      - (c[4] * ti.abs(mu) + c[5] * ti.abs(mv)))
    soft = 0.12 + 0.02 * c[7]
    return 1.0 - smooth01(dist / soft + 0.5)


@ti.func
def take_shade(buf, i, j):
    """The shadows splatted on pixel (i, j), each in [0, 1] (flying rocks', resting rocks'), reset."""
    sv = buf.shade[i, j]
    out = ti.Vector([0.0, 0.0])
    if sv[0] != 0 or sv[1] != 0:
        out = ti.min(ti.cast(sv, ti.f32) * (1.0 / SHADE_ONE), 1.0)
        buf.shade[i, j] = ti.Vector([0, 0], ti.i32)
    return out
