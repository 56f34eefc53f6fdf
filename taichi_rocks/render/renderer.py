"""Offscreen rendering of a :class:`~taichi_rocks.engine.simulation.Simulation` with Taichi GGUI.

GGUI draws through Vulkan; on a machine without a GPU, Mesa's software driver (lavapipe) does the work.
Every frame is declared from scratch (GGUI is immediate mode), drawn into a hidden window and read back.
A frame is made of two layers:

1. the background image (W x H, filled by Taichi kernels, merged under GGUI's output in the read-back):
   sky, ground and the *resting* rocks. :func:`_rocks_pass` culls every rock to the view frustum and the
   draw distance and splats the resting/sliding ones (:func:`_splat_rock`: shaded spheres, depth-tested by an
   atomic min; sub-pixel rocks blended by coverage); :func:`_paint_ground` then traces one ray per pixel to
   the ground plane: a checker of ``render.ground_tile`` metre tiles anchored to *world* coordinates (it
   scrolls as the vehicles drive; box-filtered, so no moire at the horizon), soft contact shadows under the
   vehicles, the splatted rocks, haze. Everything GGUI draws lies above the ground plane, so drawing the
   ground and what lies on it *behind* the 3D scene is exact (up to a rock touching a tire's contact patch).
2. the GGUI 3D scene: vehicles (body, cabin or cargo box, bumpers, lights, four tire cylinders each, one
   mesh instance), the *flying* rocks as ``scene.particles`` from compact f32 fields (atomic-counter
   compaction in the same pass, ``index_count`` = the count, power-of-two buckets), debug overlays
   (``render.bed_edge``, ``render.tire_rays``, ``render.hash_cells``) as ``scene.lines``.

Why: lavapipe shades GGUI particles at ~2 us per particle plus ~0.2 us per covered pixel, so the ~40-60k
visible rocks of a 200k-rock bed cost 150-200 ms a frame at 720p as particles, and a full-screen ground mesh
~45 ms; the two-layer frame costs ~100 ms in total. ``rocks="particles"`` keeps every rock a GGUI particle
(far resting rocks thinned by a hash of rock_id to ``lod_pixels``), for comparison.

Coordinate convention (the one place it is decided): we draw in the simulation's *local* frame
(world = ``sim.origin`` + local, Z up) without any axis swap, and set the GGUI camera's ``up`` to +Z
(:data:`GL_UP`). :func:`to_gl` is therefore the identity on the axes and only subtracts the floating origin;
every host-side world position goes through it, so GGUI's f32 stays precise far from (0, 0, 0).

GGUI 1.7.4 quirks handled here:

* particles come out ``width / height`` times too large (Particles_vk.vert scales the sprite by the vertical
  fov, then its y again by the aspect ratio): radii are multiplied by height / width;
* ``mesh_instance`` lights the *untransformed* mesh (Mesh_vk.vert forwards the model-space position and
  normal to the lighting), so a yawed vehicle would keep the shading of an unrotated one: vehicles are one
  mesh whose vertices and normals are transformed on the host each frame;
* yet a plain ``scene.mesh`` now and then vanishes from a frame, and often again when drawn again:
  Mesh_vk.vert takes model = I * (1 - a) + M * a with a = 0 and M read from a buffer GGUI never fills without
  transforms, and NaN or Inf left in that memory survives the ``* 0``. So the vehicles' mesh is a
  ``mesh_instance`` with one explicit identity matrix (``_v_model``);
* (``/work/shared/TAICHI-NOTES.md``) never ``window.show()`` on a hidden window (segfault); the image comes
  back (W, H, 4) float and y-flipped (:func:`_to_u8`); capture exactly once per frame; a 3D scene leaks
  ~0.3 MB per captured frame on lavapipe: the window is recreated every ``window_every`` frames (the camera
  state lives in :class:`CameraRig` and carries over).
"""

import math
import os
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import taichi as ti

from ..engine.randomness import mix32

__all__ = ["render_scene", "Renderer", "CameraRig", "to_gl", "GL_UP", "VULKAN_HINT", "DEFAULT_LOD_PIXELS", "ROCK_MODES",
           "rock_color", "check_resolution", "vehicle_mesh", "vehicle_kind"]

GL_UP = (0.0, 0.0, 1.0)  # GGUI camera up: the simulation's +Z (no axis swap anywhere)
VULKAN_HINT = ("GGUI needs Vulkan: install Mesa's software driver with "
               "`apt-get install -y mesa-vulkan-drivers libvulkan1`")
DEFAULT_LOD_PIXELS = 0.7  # resting rocks whose projected radius is below this many pixels are thinned
ROCK_MODES = ("splat", "particles")
WINDOW_EVERY = 100  # frames between window re-creations (lavapipe leaks ~0.3 MB per captured frame)

# Looks (linear RGB as GGUI shades it: colour * (ambient + sum of Lambert terms)).
AMBIENT = (0.40, 0.42, 0.46)
SUN_COLOR = (0.68, 0.66, 0.60)
SUN_DIR_CAMERA = (-0.45, 0.55, 1.0)  # sun direction in the camera-heading frame (x fwd, y left, z up)
GROUND_A = (0.56, 0.53, 0.44)
GROUND_B = (0.49, 0.46, 0.38)
HAZE = 2.5  # draw distances: e-folding distance of the ground's haze
TIRE_COLOR = (0.09, 0.09, 0.10)
HUB_COLOR = (0.62, 0.62, 0.64)
GLASS_COLOR = (0.16, 0.20, 0.26)
TAIL_LIGHT_COLOR = (1.0, 0.55, 0.35)
BUMPER_COLOR = (0.13, 0.13, 0.14)
BED_EDGE_COLOR = (1.0, 0.85, 0.1)
RAY_COLOR = (1.0, 0.1, 0.1)
CELL_COLOR = (0.1, 0.9, 1.0)
MAX_RAYS = 256
MAX_CELLS = 4096
MIN_BUCKET = 4096
GLITCH_DROP = 0.3  # a frame whose GGUI pixels fall below this fraction of the last frame's is drawn again
GLITCH_RETRIES = 3  # at most this many extra draws of one frame
LOST_COVERAGE = 0.15  # a vehicle in view drawing less than this share of its screen box was lost
KEY = (3, 251, 5)  # GGUI's clear colour, 8-bit: where the read-back has it, the background image shows
COVERAGE_ONE = 1024.0  # fixed-point unit of splatted coverage: 2^21 / (pi * 1024) = 650 rocks a pixel
OPAQUE_PX = 1.0  # splatted rocks at least this many pixels in radius are opaque spheres, smaller ones coverage


def to_gl(p_world, origin) -> np.ndarray:
    """World (Z up, float64) -> what GGUI gets: local coordinates (``p - origin``) as f32, axes unchanged.

    Together with ``camera.up = GL_UP`` this is the whole Z-up/Y-up conversion.
    """
    return (np.asarray(p_world, np.float64) - np.asarray(origin, np.float64)).astype(np.float32)


# ------------------------------------------------------------------------------------------------ kernels
@ti.func
def _hash_u32(x):
    """lowbias32 integer hash (the engine's randomness.mix32), on u32."""
    return mix32(ti.cast(x, ti.u32))


@ti.func
def _unit(rid, salt):
    """A number in [0, 1) from a rock id and a salt: stable across frames and memory re-orderings."""
    h = _hash_u32(ti.cast(rid, ti.u32) * ti.u32(0x9E3779B9) + ti.cast(salt, ti.u32) * ti.u32(0x85EBCA6B))
    return ti.cast(h >> ti.u32(8), ti.f32) * (1.0 / 16777216.0)


@ti.func
def _rock_color(rid, phase):
    a = _unit(rid, 1)
    b = _unit(rid, 2)
    c = _unit(rid, 3)
    grey = ti.Vector([0.60, 0.59, 0.57])
    brown = ti.Vector([0.62, 0.50, 0.37])
    dark = ti.Vector([0.36, 0.34, 0.32])
    col = grey + (brown - grey) * (a * a)
    col = col + (dark - col) * (0.55 * c * c)
    col = col * (0.72 + 0.45 * b)
    if phase == 1:  # flying: warmer and lighter so the splash reads
        col = ti.min(col * ti.Vector([1.30, 1.12, 0.85]) + 0.06, 1.0)
    return col


def rock_color(rock_id: int, phase: int = 0) -> np.ndarray:
    """Host mirror of the kernel's rock colour (for tests and documentation)."""
    def h(x):
        x &= 0xFFFFFFFF
        x ^= x >> 16
        x = (x * 0x7FEB352D) & 0xFFFFFFFF
        x ^= x >> 15
        x = (x * 0x846CA68B) & 0xFFFFFFFF
        x ^= x >> 16
        return x

    def unit(rid, salt):
        return (h((rid * 0x9E3779B9 + salt * 0x85EBCA6B) & 0xFFFFFFFF) >> 8) / 16777216.0

    a, b, c = unit(rock_id, 1), unit(rock_id, 2), unit(rock_id, 3)
    grey, brown, dark = np.array([0.60, 0.59, 0.57]), np.array([0.62, 0.50, 0.37]), np.array([0.36, 0.34, 0.32])
    col = grey + (brown - grey) * a * a
    col = col + (dark - col) * 0.55 * c * c
    col = col * (0.72 + 0.45 * b)
    if phase == 1:
        col = np.minimum(col * np.array([1.30, 1.12, 0.85]) + 0.06, 1.0)
    return col


@ti.func
def _smooth01(x):
    s = ti.min(ti.max(x, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


@ti.func
def _empty_key():
    """The depth-buffer value of a pixel no rock covers."""
    return ti.cast(0x7FFFFFFF, ti.i64) << 32


@ti.func
def _splat_rock(zbuf, acc, rows, X, Y, pr, z, r, base, fwd, right, up, sun, amb, sunc):
    """Draw one resting rock into the software buffers: centre (X, Y) in pixels (row 0 at the bottom),
    projected radius pr pixels, view depth z.

    pr >= 1: an opaque shaded sphere, pixel by pixel, depth-tested through an atomic min on (depth, rgb)
    packed in an i64 (order independent, so deterministic). pr < 1: its shaded colour spread bilinearly over
    the 2 x 2 pixels around its centre with weight = its area in pixels, accumulated in fixed point (again
    order independent); the ground pass blends it by coverage, which antialiases the far gravel.
    Lighting is GGUI's: colour * (ambient + sun * max(n . l, 0)).
    """
    W, H = zbuf.shape
    if pr < OPAQUE_PX:
        lam = (2.0 / 3.0) * ti.max(-fwd.dot(sun), 0.0)  # mean of n . l over the visible disc
        c = ti.min(ti.max(base * (amb + sunc * lam), 0.0), 1.0)
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
                    acc[ii, jj][0] += rgb
                    acc[ii, jj][1] += ti.cast(q + 0.5, ti.i64)
        ti.atomic_min(rows[0], ti.max(j0, 0))
        ti.atomic_max(rows[1], ti.min(j0 + 1, H - 1))
    else:
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
                    nrm = right * dx + up * dy - fwd * nz
                    col = ti.min(ti.max(base * (amb + sunc * ti.max(nrm.dot(sun), 0.0)), 0.0), 1.0) * 255.0 + 0.5
                    depth = ti.max(z - r * nz, 1e-4)
                    key = (ti.cast(ti.bit_cast(depth, ti.i32), ti.i64) << 24) | ti.cast(
                        (ti.cast(col[0], ti.i32) << 16) | (ti.cast(col[1], ti.i32) << 8) | ti.cast(col[2], ti.i32),
                        ti.i64)
                    ti.atomic_min(zbuf[ii, jj], key)
        if j_lo <= j_hi:
            ti.atomic_min(rows[0], j_lo)
            ti.atomic_max(rows[1], j_hi)


@ti.kernel
def _rocks_pass(pos: ti.template(), radius: ti.template(), rock_id: ti.template(), phase: ti.template(),
                n: ti.i32, out_pos: ti.template(), out_rad: ti.template(), out_col: ti.template(),
                count: ti.template(), cap: ti.i32, zbuf: ti.template(), acc: ti.template(), rows: ti.template(),
                eye: ti.types.vector(3, ti.f32), fwd: ti.types.vector(3, ti.f32),
                right: ti.types.vector(3, ti.f32), up: ti.types.vector(3, ti.f32), tan_x: ti.f32, tan_y: ti.f32,
                sec_x: ti.f32, sec_y: ti.f32, near: ti.f32, far: ti.f32, px_per_rad: ti.f32, lod_px: ti.f32,
                radius_scale: ti.f32, sun: ti.types.vector(3, ti.f32), amb: ti.types.vector(3, ti.f32),
                sunc: ti.types.vector(3, ti.f32), splat: ti.template()):
    """Cull the rocks to the view frustum and the draw distance, then

    * ``splat``: resting and sliding rocks are drawn into the software buffers (:func:`_splat_rock`), flying
      rocks are compacted into out_* for GGUI;
    * otherwise every visible rock is compacted into out_* (atomic counter; the first ``count`` entries are
      valid, count may exceed cap: then the caller re-runs with a bigger bucket), far resting rocks thinned
      (a fraction q^2 kept by a hash of rock_id and drawn 1/q larger, q = projected radius / lod_px).
    """
    count[None] = 0
    if ti.static(splat):
        rows[0] = zbuf.shape[1]
        rows[1] = -1
    W = ti.cast(zbuf.shape[0], ti.f32)
    H = ti.cast(zbuf.shape[1], ti.f32)
    for i in range(n):
        p = ti.cast(pos[i], ti.f32)
        r = ti.cast(radius[i], ti.f32)
        d = p - eye
        z = d.dot(fwd)
        if z > near - r and d.norm_sqr() < far * far:
            x = d.dot(right)
            y = d.dot(up)
            if ti.abs(x) < z * tan_x + r * sec_x and ti.abs(y) < z * tan_y + r * sec_y:
                ph = phase[i]
                rid = rock_id[i]
                if ti.static(splat):
                    if ph != 1:
                        if z > near:
                            zz = ti.max(z, near)
                            _splat_rock(zbuf, acc, rows, (x / (zz * tan_x) + 1.0) * 0.5 * W,
                                        (y / (zz * tan_y) + 1.0) * 0.5 * H, r * px_per_rad / zz, zz, r,
                                        _rock_color(rid, ph), fwd, right, up, sun, amb, sunc)
                        continue
                keep = True
                draw_r = r
                if ph != 1 and lod_px > 0:
                    pr = r * px_per_rad / ti.max(z, near)  # projected radius, pixels
                    if pr < lod_px:
                        q = pr / lod_px
                        if _unit(rid, 7) < q * q:  # keep a fraction q^2, drawn 1/q larger: same coverage
                            draw_r = r / q
                        else:
                            keep = False
                if keep:
                    j = ti.atomic_add(count[None], 1)
                    if j < cap:
                        out_pos[j] = p
                        out_rad[j] = draw_r * radius_scale
                        out_col[j] = _rock_color(rid, ph)


@ti.kernel
def _clear_buffers(zbuf: ti.template(), acc: ti.template()):
    for i, j in zbuf:
        zbuf[i, j] = _empty_key()
        acc[i, j] = ti.Vector([0, 0], ti.i64)


@ti.func
def _composite(col, zbuf, acc, i, j):
    """Blend the splatted rocks of pixel (i, j) over ``col`` and reset the pixel's buffers."""
    a = acc[i, j]
    if a[1] > 0:
        w = ti.cast(a[1], ti.f32) * (1.0 / COVERAGE_ONE)
        m = ti.cast(0x1FFFFF, ti.i64)
        rgb = ti.Vector([ti.cast(a[0] & m, ti.f32), ti.cast((a[0] >> 21) & m, ti.f32),
                         ti.cast((a[0] >> 42) & m, ti.f32)]) * (1.0 / COVERAGE_ONE)
        if w >= 1.0:
            col = rgb / w
        else:
            col = col * (1.0 - w) + rgb
        acc[i, j] = ti.Vector([0, 0], ti.i64)
    key = zbuf[i, j]
    if key != _empty_key():
        rgb = ti.cast(key & 0xFFFFFF, ti.i32)
        col = ti.Vector([(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255]) * (1.0 / 255.0)
        zbuf[i, j] = _empty_key()
    return col


@ti.func
def _to_rgba8(col):
    c = ti.min(ti.max(col, 0.0), 1.0) * 255.0 + 0.5
    return ti.Vector([ti.cast(c[0], ti.u8), ti.cast(c[1], ti.u8), ti.cast(c[2], ti.u8), ti.u8(255)])


@ti.kernel
def _paint_ground(img: ti.template(), eye: ti.types.vector(3, ti.f32), fwd: ti.types.vector(3, ti.f32),
                  right: ti.types.vector(3, ti.f32), up: ti.types.vector(3, ti.f32), tan_x: ti.f32, tan_y: ti.f32,
                  ground_z: ti.f32, wrap: ti.types.vector(2, ti.f32), tile: ti.f32,
                  ca: ti.types.vector(3, ti.f32), cb: ti.types.vector(3, ti.f32), light: ti.types.vector(3, ti.f32),
                  sky: ti.types.vector(3, ti.f32), horizon: ti.types.vector(3, ti.f32), haze_dist: ti.f32,
                  cars: ti.template(), n_cars: ti.i32, zbuf: ti.template(), acc: ti.template(),
                  rows: ti.template(), splat: ti.template()):
    """Sky, ground and (``splat``) the splatted resting rocks, one ray per pixel, into the background image
    (W, H), row 0 at the bottom.

    Ground: the plane z = ground_z, a checker of ``tile`` metre squares whose parity is that of the *world*
    tile (``wrap`` = origin mod 2 tiles), box-filtered over the pixel's footprint (no moire: far tiles blend
    to the mean colour), lit like GGUI lights a mesh facing up (``light`` = ambient + sun * cos), darkened
    under the vehicles (soft contact shadows), then the rocks blended in (:func:`_composite`), then hazed
    towards ``horizon`` with distance. Sky: ``sky`` above, lightening to ``horizon`` at the horizon.
    Everything GGUI draws afterwards lies above the plane, so painting the ground behind the 3D scene is
    exact; resting rocks lie on it (a rock just in front of a tire's contact patch is the only thing that can
    come out behind instead of in front). Parallel over rows: the camera has no roll (its right vector is
    horizontal), so a row's rays share their height and distance to the plane.
    """
    W, H = img.shape
    h = eye[2] - ground_z
    inv_tile = 1.0 / tile
    for j in range(H):
        v = ((j + 0.5) / H * 2.0 - 1.0) * tan_y
        dr = fwd + up * v  # ray through the row's centre line; the pixel's ray is dr + right * u
        dz = dr[2]  # right is horizontal (no roll), so the whole row shares dz and the plane distance t
        rocks = False
        if ti.static(splat):
            rocks = rows[0] <= j <= rows[1]
        if dz < 0.0 and h > 0.0:
            t = h / -dz
            # pixel footprint on the plane: d(hit)/d(column) = t * du (du horizontal),
            # d(hit)/d(row) = t * (dv - d * dv_z / dz), d = dr + right * u
            gu = right * (2.0 * tan_x / W * t)
            gv0 = t * (up * (2.0 * tan_y / H) - dr * (up[2] * (2.0 * tan_y / H) / dz))
            gv1 = -t * right * (up[2] * (2.0 * tan_y / H) / dz)  # times u
            bx0 = eye[0] + t * dr[0]
            by0 = eye[1] + t * dr[1]
            r2 = dr.norm_sqr()
            for i in range(W):
                u = ((i + 0.5) / W * 2.0 - 1.0) * tan_x
                g = ti.Vector([0.0, 0.0, 0.0])
                covered = False
                if ti.static(splat):
                    if rocks:
                        key = zbuf[i, j]
                        if key != _empty_key():  # an opaque rock: no ground to compute under it
                            covered = True
                            zbuf[i, j] = _empty_key()
                            acc[i, j] = ti.Vector([0, 0], ti.i64)
                            rgb = ti.cast(key & 0xFFFFFF, ti.i32)
                            g = ti.Vector([(rgb >> 16) & 255, (rgb >> 8) & 255, rgb & 255]) * (1.0 / 255.0)
                if not covered:
                    hx = bx0 + t * u * right[0]
                    hy = by0 + t * u * right[1]
                    fx = ti.abs(gu[0]) + ti.abs(gv0[0] + gv1[0] * u)
                    fy = ti.abs(gu[1]) + ti.abs(gv0[1] + gv1[1] * u)
                    qx = (hx + wrap[0]) * inv_tile
                    qy = (hy + wrap[1]) * inv_tile
                    wx = fx * inv_tile + 1e-4
                    wy = fy * inv_tile + 1e-4
                    # box-filtered square waves (difference of the integrated triangle wave), in [-1, 1]
                    sa = (qx - 0.5 * wx) * 0.5
                    sb = (qx + 0.5 * wx) * 0.5
                    ta = (qy - 0.5 * wy) * 0.5
                    tb = (qy + 0.5 * wy) * 0.5
                    sx = 2.0 * (ti.abs(sa - ti.floor(sa) - 0.5) - ti.abs(sb - ti.floor(sb) - 0.5)) / wx
                    sy = 2.0 * (ti.abs(ta - ti.floor(ta) - 0.5) - ti.abs(tb - ti.floor(tb) - 0.5)) / wy
                    chk = 0.5 - 0.5 * sx * sy
                    g = (ca + (cb - ca) * chk) * light
                    for k in range(n_cars):
                        c = cars[k]  # x, y, cos, sin, half length, half width, shadow softness (local, m)
                        rx = hx - c[0]
                        ry = hy - c[1]
                        ox = ti.abs(rx * c[2] + ry * c[3]) - c[4]
                        oy = ti.abs(-rx * c[3] + ry * c[2]) - c[5]
                        if ox < c[6] and oy < c[6]:
                            dd = ti.sqrt(ti.max(ox, 0.0) ** 2 + ti.max(oy, 0.0) ** 2)
                            g *= 0.5 + 0.5 * _smooth01(dd / c[6])
                    if ti.static(splat):
                        if rocks:
                            g = _composite(g, zbuf, acc, i, j)
                x = t * ti.sqrt(r2 + u * u) / haze_dist  # distance / haze distance (right is a unit normal to dr)
                fog = 1.0 - 1.0 / (1.0 + x * (1.0 + 0.5 * x))  # ~ 1 - exp(-x), cheaper
                img[i, j] = _to_rgba8(g + (horizon - g) * fog)
        else:  # sky: one colour per row (elevation of the row's centre)
            elev = dz / ti.sqrt(dr.norm_sqr())
            col = horizon + (sky - horizon) * _smooth01(elev * (1.0 / 0.12))
            px = _to_rgba8(col)
            if ti.static(splat):
                if rocks:  # only when the camera is lower than the rocks
                    for i in range(W):
                        img[i, j] = _to_rgba8(_composite(col, zbuf, acc, i, j))
                else:
                    for i in range(W):
                        img[i, j] = px
            else:
                for i in range(W):
                    img[i, j] = px


@ti.kernel
def _to_u8(raw: ti.types.ndarray(dtype=ti.f32, ndim=3), out: ti.types.ndarray(dtype=ti.u8, ndim=3),
           back: ti.template(), drawn: ti.template()):
    """GGUI's read-back (W, H, 4) float, y up -> upright (H, W, 3) uint8 (np.rot90 plus the cast), with the
    background image ``back`` (W, H) wherever GGUI left its clear colour :data:`KEY` (nothing drawn there).

    Merging here instead of ``canvas.set_image`` saves lavapipe a full-screen textured quad and GGUI a
    staging copy (~25 ms of CPU a frame at 720p). GGUI draws without antialiasing, so a pixel is either
    cleared (exactly the key, k/255 floats) or drawn. Works in 32 x 32 tiles so that both the reads and the
    transposed writes stay in cache. ``drawn`` counts the pixels GGUI drew.
    """
    H = out.shape[0]
    W = out.shape[1]
    drawn[None] = 0
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
                    px = back[x, yy]
                    out[H - 1 - yy, x, 0] = px[0]
                    out[H - 1 - yy, x, 1] = px[1]
                    out[H - 1 - yy, x, 2] = px[2]
                else:
                    n += 1
                    out[H - 1 - yy, x, 0] = ti.cast(ti.min(ti.max(r, 0), 255), ti.u8)
                    out[H - 1 - yy, x, 1] = ti.cast(ti.min(ti.max(g, 0), 255), ti.u8)
                    out[H - 1 - yy, x, 2] = ti.cast(ti.min(ti.max(b, 0), 255), ti.u8)
        drawn[None] += n


# ------------------------------------------------------------------------------------------------ geometry
def _quad_faces(corners, normal, color):
    """One flat quad (4 corners CCW seen from the normal side)."""
    v = np.asarray(corners, np.float64)
    return v, np.tile(normal, (4, 1)), np.tile(color, (4, 1)), np.array([0, 1, 2, 0, 2, 3])


def _box(center, size, colors):
    """Axis-aligned box: 24 vertices (flat faces). colors: dict face -> rgb for '+x','-x','+y','-y','+z','-z'."""
    cx, cy, cz = center
    hx, hy, hz = (s / 2 for s in size)
    x0, x1, y0, y1, z0, z1 = cx - hx, cx + hx, cy - hy, cy + hy, cz - hz, cz + hz
    faces = {
        "+x": ([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (1, 0, 0)),
        "-x": ([(x0, y1, z0), (x0, y0, z0), (x0, y0, z1), (x0, y1, z1)], (-1, 0, 0)),
        "+y": ([(x1, y1, z0), (x0, y1, z0), (x0, y1, z1), (x1, y1, z1)], (0, 1, 0)),
        "-y": ([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, -1, 0)),
        "+z": ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, 1)),
        "-z": ([(x0, y1, z0), (x1, y1, z0), (x1, y0, z0), (x0, y0, z0)], (0, 0, -1)),
    }
    return _merge([_quad_faces(c, n, colors[k]) for k, (c, n) in faces.items()])


def _tire(center, radius, width, seg=20):
    """Cylinder with its axis along y: dark tread and sidewalls, light hub discs."""
    cx, cy, cz = center
    th = np.linspace(0.0, 2.0 * np.pi, seg, endpoint=False)
    c, s = np.cos(th), np.sin(th)
    parts = []
    # tread: 2 rings, smooth normals
    ring = lambda y, rr: np.stack([cx + rr * c, np.full(seg, y), cz + rr * s], 1)
    y0, y1 = cy - width / 2, cy + width / 2
    v = np.concatenate([ring(y0, radius), ring(y1, radius)])
    nrm = np.concatenate([np.stack([c, 0 * c, s], 1)] * 2)
    idx = []
    for k in range(seg):
        k2 = (k + 1) % seg
        idx += [k, k2, seg + k2, k, seg + k2, seg + k]
    parts.append((v, nrm, np.tile(TIRE_COLOR, (2 * seg, 1)), np.array(idx)))
    # sidewalls (annulus) and hubs (disc), both sides
    for y, ny in ((y1, 1.0), (y0, -1.0)):
        outer, inner = ring(y, radius), ring(y, 0.55 * radius)
        v = np.concatenate([outer, inner])
        idx = []
        for k in range(seg):
            k2 = (k + 1) % seg
            a = [k, k2, seg + k2, k, seg + k2, seg + k]
            idx += a if ny < 0 else [a[0], a[2], a[1], a[3], a[5], a[4]]
        parts.append((v, np.tile((0, ny, 0), (2 * seg, 1)), np.tile(TIRE_COLOR, (2 * seg, 1)), np.array(idx)))
        hub = np.concatenate([inner, [(cx, y + 0.002 * ny, cz)]])
        idx = []
        for k in range(seg):
            k2 = (k + 1) % seg
            idx += [seg, k2, k] if ny < 0 else [seg, k, k2]
        parts.append((hub, np.tile((0, ny, 0), (seg + 1, 1)), np.tile(HUB_COLOR, (seg + 1, 1)), np.array(idx)))
    return _merge(parts)


def _merge(parts):
    vs, ns, cs, ids, off = [], [], [], [], 0
    for v, n, c, i in parts:
        vs.append(np.asarray(v, np.float64))
        ns.append(np.asarray(n, np.float64))
        cs.append(np.asarray(c, np.float64))
        ids.append(np.asarray(i, np.int64) + off)
        off += len(v)
    return np.concatenate(vs), np.concatenate(ns), np.concatenate(cs), np.concatenate(ids)


def vehicle_kind(spec) -> str:
    """"truck", "van" or "car", from the proportions (the scene format has no vehicle type)."""
    L, H = float(spec.length), float(spec.height)
    if H >= 2.6 or L >= 6.5:
        return "truck"
    if H >= 1.75:
        return "van"
    return "car"


def vehicle_mesh(spec, ground_z: float = 0.0):
    """Body-frame mesh of one vehicle (x forward, y left, z up; origin at the body centre on the ground).

    Returns (vertices, normals, colours, indices). Tires (dark tread, light hubs) at (+-wheelbase/2,
    +-track/2), centre height tire_radius. The body (length x width, from 0.8 tire radius up to that plus
    ``height``) is shaped by :func:`vehicle_kind`: a car has a lower body and a glazed cabin with a roof in the
    body colour, a van a tall body glazed at the front, a truck a cab at the front and a cargo box behind.
    """
    col = np.clip(np.asarray(spec.color, np.float64), 0, 1)
    glass = np.array(GLASS_COLOR)
    dark = col * 0.8
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    R, TW = float(spec.tire_radius), float(spec.tire_width)
    z0 = ground_z + 0.8 * R
    same = lambda c: {k: c for k in ("+x", "-x", "+y", "-y", "+z", "-z")}
    kind = vehicle_kind(spec)
    parts = []
    if kind == "car":
        lower_h = 0.5 * H
        parts.append(_box((0.0, 0.0, z0 + lower_h / 2), (L, W, lower_h), same(col)))
        cab = {k: glass for k in ("+x", "-x", "+y", "-y", "-z")}
        cab["+z"] = col * 0.92
        cab_h = H - lower_h
        parts.append(_box((-0.06 * L, 0.0, z0 + lower_h + cab_h / 2), (0.52 * L, 0.88 * W, cab_h), cab))
    elif kind == "van":
        lower_h = 0.55 * H
        parts.append(_box((0.0, 0.0, z0 + lower_h / 2), (L, W, lower_h), same(col)))
        up_h = H - lower_h
        xf1 = L / 2 - 0.04 * L  # the upper body: glazed front part [xf0, xf1], closed rear part [-L/2, xf0]
        xf0 = xf1 - 0.3 * L
        wind = same(col * 0.95)
        wind.update({"+x": glass, "+y": glass, "-y": glass})
        parts.append(_box(((xf0 + xf1) / 2, 0.0, z0 + lower_h + up_h / 2), (xf1 - xf0, 0.97 * W, up_h), wind))
        rear = same(col * 0.95)
        rear["-x"] = glass  # rear window
        parts.append(_box(((xf0 - L / 2) / 2, 0.0, z0 + lower_h + up_h / 2), (xf0 + L / 2, 0.97 * W, up_h), rear))
    else:  # truck: chassis, cab at the front, cargo box behind
        chassis_h = 0.22 * H
        parts.append(_box((0.0, 0.0, z0 + chassis_h / 2), (L, 0.9 * W, chassis_h), same(np.array(TIRE_COLOR) * 2)))
        cab_l = min(2.2, 0.3 * L)
        cab_h = 0.78 * H - chassis_h
        low_h = 0.5 * cab_h
        parts.append(_box((L / 2 - cab_l / 2, 0.0, z0 + chassis_h + low_h / 2), (cab_l, W, low_h), same(col)))
        cab = same(col)
        cab.update({"+x": glass, "+y": glass, "-y": glass})  # windscreen and side windows
        up_h = cab_h - low_h
        parts.append(_box((L / 2 - cab_l / 2, 0.0, z0 + chassis_h + low_h + up_h / 2), (cab_l, W, up_h), cab))
        box_l = L - cab_l - 0.15
        box_h = H - chassis_h
        cargo = same(np.clip(col * 1.08 + 0.04, 0, 1))
        cargo["-x"] = dark
        parts.append(_box((-L / 2 + box_l / 2, 0.0, z0 + chassis_h + box_h / 2), (box_l, W, box_h), cargo))
    # bumpers (dark) and tail lights, standing proud of the body: no two visible faces share a plane (lavapipe
    # resolves z-fighting differently from frame to frame, which would make renders irreproducible)
    bump_h = min(0.18, 0.12 * H)
    for sx in (1.0, -1.0):
        parts.append(_box((sx * (L / 2 + 0.02), 0.0, z0 - 0.01 + bump_h / 2), (0.08, 1.02 * W, bump_h),
                          same(np.array(BUMPER_COLOR))))
    lz = z0 + bump_h + 0.06 * H
    for side in (1.0, -1.0):
        parts.append(_box((-L / 2 - 0.02, side * 0.38 * W, lz), (0.03, 0.16 * W, 0.07 * H),
                          same(np.array(TAIL_LIGHT_COLOR))))
    for sx in (0.5, -0.5):
        for sy in (0.5, -0.5):
            parts.append(_tire((sx * float(spec.wheelbase), sy * float(spec.track), ground_z + R), R, TW))
    return _merge(parts)


# ------------------------------------------------------------------------------------------------ camera
class CameraRig:
    """Chase camera: eye at ``offset`` in the followed vehicle's frame, looking ``look_ahead`` metres ahead.

    The frame's heading is smoothed exponentially with time constant ``smoothing`` seconds (a first-order
    low-pass, frame-rate independent: alpha = 1 - exp(-dt / smoothing)); positions are not lagged, so the
    vehicle stays framed at any speed, and the camera swings round late in turns. The first update snaps.
    """

    def __init__(self, offset, look_ahead: float, smoothing: float):
        self.offset = np.asarray(offset, np.float64)
        self.look_ahead = float(look_ahead)
        self.smoothing = float(smoothing)
        self.heading = None  # smoothed heading, rad
        self.t = None

    def update(self, position, heading: float, t: float):
        """Return (eye, target, smoothed heading), world float64."""
        if self.heading is None or self.smoothing <= 0.0:
            self.heading = float(heading)
        else:
            dt = max(0.0, float(t) - self.t)
            alpha = 1.0 - math.exp(-dt / self.smoothing)
            dh = math.remainder(float(heading) - self.heading, 2.0 * math.pi)
            self.heading += alpha * dh
        self.t = float(t)
        c, s = math.cos(self.heading), math.sin(self.heading)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        p = np.asarray(position, np.float64)
        eye = p + rot @ self.offset
        target = p + rot @ np.array([self.look_ahead, 0.0, 0.0])
        if np.linalg.norm(target - eye) < 1e-6:  # degenerate set-up: look forward
            target = eye + rot @ np.array([1.0, 0.0, 0.0])
        return eye, target, self.heading


def _rgb(c) -> tuple:
    if isinstance(c, str):
        c = tuple(int(c[i:i + 2], 16) / 255 for i in (1, 3, 5))
    return tuple(float(x) for x in c)


# ------------------------------------------------------------------------------------------------ renderer
MAX_CARS = 32  # vehicles casting a contact shadow


class Renderer:
    """Draws ``sim`` into a hidden GGUI window; :meth:`render_frame` returns the image (H, W, 3) uint8.

    ``resolution`` (even sides) and ``fps`` default to the scene's [render] table. ``rocks``: "splat" (resting
    rocks splatted into the background image by a Taichi kernel, flying rocks GGUI particles; the default)
    or "particles" (every visible rock a GGUI particle). ``lod_pixels`` ("particles" only): resting rocks whose
    projected radius is below this many pixels are thinned (a fraction q^2 kept, chosen by a hash of
    rock_id, drawn 1/q larger, q = projected radius / lod_pixels); 0 disables it. ``window_every``: frames
    between window re-creations (0: never). ``timings`` accumulates seconds in ``cull`` (the rock pass:
    culling, splatting, compaction) and ``draw`` (camera, sky and ground, vehicles, overlays, GGUI drawing and
    the read-back). ``last_count``: rocks GGUI drew in the last frame.
    """

    def __init__(self, sim, resolution=None, fps=None, *, rocks: str = "splat",
                 lod_pixels: float = DEFAULT_LOD_PIXELS, window_every: int = WINDOW_EVERY):
        self.sim = sim
        sc = sim.scene
        rs = sc.render
        self.resolution = check_resolution(resolution if resolution is not None else rs.resolution)
        w, h = self.resolution
        self.fps = float(fps if fps is not None else rs.fps)
        if not self.fps > 0:
            raise ValueError(f"fps must be > 0, got {fps!r}")
        self.background = _rgb(rs.background)
        self.horizon = tuple(float(c + (1.0 - c) * 0.45) for c in self.background)
        self.draw_distance = float(rs.draw_distance)
        self.tile = float(rs.ground_tile)
        if rocks not in ROCK_MODES:
            raise ValueError(f"rocks must be one of {', '.join(ROCK_MODES)}, got {rocks!r}")
        self.rocks = rocks
        self.lod_pixels = float(lod_pixels)
        self.window_every = int(window_every)
        self.flags = SimpleNamespace(bed_edge=bool(rs.bed_edge), tire_rays=bool(rs.tire_rays),
                                     hash_cells=bool(rs.hash_cells))
        cam = sc.camera
        names = [v.name for v in sc.vehicles]
        follow = cam.follow or getattr(sc.bed, "follow", None) or names[0]
        if follow not in names:
            raise ValueError(f"camera.follow: no vehicle named {follow!r} (vehicles: {', '.join(names)})")
        self.follow = names.index(follow)
        self.fov = float(cam.fov)
        self.tan_y = math.tan(math.radians(self.fov) / 2)
        self.tan_x = self.tan_y * w / h
        self.px_per_rad = (h / 2) / self.tan_y  # pixels per metre at 1 m depth
        self.rig = CameraRig(cam.offset, cam.look_ahead, cam.smoothing)
        self.ground_z = float(sc.world.ground_z)
        self.frames_drawn = 0
        self.last_count = 0
        self.timings = {"cull": 0.0, "draw": 0.0}

        self._camera = _ggui(ti.ui.Camera)
        self._camera.up(*GL_UP)
        self._camera.fov(self.fov)
        self._camera.z_near(0.05)
        self._camera.z_far(max(1000.0, 3.0 * self.draw_distance))

        # rocks: compact buckets (power-of-two capacities), allocated when first needed
        self.n_rocks = int(sim.n_rocks)
        self._buckets = {}
        self._count = ti.field(ti.i32, shape=())
        self._drawn = None

        # sky and ground: the background image; contact shadows of the vehicles
        self._sky = ti.Vector.field(4, ti.u8)
        ti.root.dense(ti.j, h).dense(ti.i, w).place(self._sky)  # rows contiguous: written row by row
        # software buffers of the splatted rocks (1 x 1 placeholders in "particles" mode)
        bw, bh = (w, h) if rocks == "splat" else (1, 1)
        self._zbuf = ti.field(ti.i64)
        self._acc = ti.Vector.field(2, ti.i64)  # packed premultiplied rgb, weight (COVERAGE_ONE = 1 pixel)
        # a tree of their own: next to 32-bit fields Vulkan can misalign 64-bit ones (see world._Trees); here
        # the buffers landed at 4 mod 8 after the sky, and zbuf[0] overwrote the sky's last pixel each frame
        buffers = ti.FieldsBuilder()
        buffers.dense(ti.j, bh).dense(ti.i, bw).place(self._zbuf, self._acc)
        buffers.finalize()
        self._rows = ti.field(ti.i32, shape=2)
        _clear_buffers(self._zbuf, self._acc)
        self._cars = ti.Vector.field(7, ti.f32, shape=MAX_CARS)
        self._out = np.empty((h, w, 3), np.uint8)
        self._drawn_px = ti.field(ti.i32, shape=())
        self._prev_drawn = 0
        self.redraws = 0  # extra draws of the 3D layer (see render_frame)

        # vehicles: one merged mesh, transformed on the host each frame
        meshes = [vehicle_mesh(v, 0.0) for v in sc.vehicles]
        self._v_sizes = [len(m[0]) for m in meshes]
        vs, ns, cs, ids = _merge(meshes)
        self._v_local = (vs, ns)
        self._v_frame = None  # this frame's vertices (local frame), for the lost-mesh check
        self._raw = None
        self._v_verts = ti.Vector.field(3, ti.f32, len(vs))
        self._v_norms = ti.Vector.field(3, ti.f32, len(vs))
        self._v_cols = ti.Vector.field(3, ti.f32, len(vs))
        self._v_cols.from_numpy(cs.astype(np.float32))
        self._v_idx = ti.field(ti.i32, len(ids))
        self._v_idx.from_numpy(ids.astype(np.int32))
        # one instance with an identity model matrix, not a plain mesh (see "GGUI 1.7.4 quirks" above)
        self._v_model = ti.Matrix.field(4, 4, ti.f32, shape=1)
        self._v_model.from_numpy(np.eye(4, dtype=np.float32)[None])

        # debug overlays
        self._bed_lines = self._ray_lines = self._cell_lines = None
        if self.flags.bed_edge:
            self._bed_lines = ti.Vector.field(3, ti.f32, 256)
        if self.flags.tire_rays:
            self._ray_lines = ti.Vector.field(3, ti.f32, 2 * MAX_RAYS)
        if self.flags.hash_cells:
            self._cell_lines = ti.Vector.field(3, ti.f32, 24 * MAX_CELLS)

        self._window = self._canvas = self._scene = None
        # GGUI's Dear ImGui layer saves its window settings to ./imgui.ini every few seconds: remove that file
        # on close if it was not there before
        self._imgui_ini = Path.cwd() / "imgui.ini"
        self._imgui_ini_existed = self._imgui_ini.exists()
        self._open_window()  # now, so that a machine without Vulkan fails before any frame is simulated

    # -------------------------------------------------------------------------------------------- window
    def _open_window(self) -> None:
        """Open this renderer's hidden window. GGUI keeps one window at a time safely (destroying a window
        after others were created and destroyed since segfaults), so any other renderer's window is closed
        first; that renderer reopens one on its next frame."""
        other = _LIVE[0]
        if other is not None and other is not self:
            other._close_window()
        self._window = _ggui(ti.ui.Window, "taichi-rocks", self.resolution, show_window=False, vsync=False)
        self._canvas = self._window.get_canvas()
        self._scene = self._window.get_scene()
        _LIVE[0] = self
        _trim_heap()

    def _close_window(self) -> None:
        if self._window is not None:
            try:
                self._window.destroy()
            except Exception:  # already gone
                pass
        self._window = self._canvas = self._scene = None
        if _LIVE[0] is self:
            _LIVE[0] = None

    def close(self) -> None:
        """Release the window (the fields stay until Taichi is reset) and the imgui.ini GGUI left behind."""
        self._close_window()
        if not self._imgui_ini_existed:
            try:
                self._imgui_ini.unlink()
            except OSError:
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -------------------------------------------------------------------------------------------- frame
    def view(self):
        """Advance the chase camera to ``sim.time``; return the view in local f32 coordinates:
        (eye, target, forward, right, up, heading). Calling it twice at the same time changes nothing."""
        sim = self.sim
        pose = sim.vehicle_poses()[self.follow]
        eye_w, target_w, heading = self.rig.update(pose.position, pose.heading, sim.time)
        origin = np.asarray(sim.origin, np.float64)
        eye, target = to_gl(eye_w, origin), to_gl(target_w, origin)
        fwd = (target - eye).astype(np.float64)
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, GL_UP)
        if np.linalg.norm(right) < 1e-6:  # looking straight down or up
            right = np.array([math.sin(heading), -math.cos(heading), 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        return eye, target, fwd.astype(np.float32), right.astype(np.float32), up.astype(np.float32), heading

    @staticmethod
    def sun_direction(heading: float) -> np.ndarray:
        """Unit vector towards the sun: fixed in the camera's heading frame (behind, left, high), so the lit
        side of every rock faces the camera whatever the direction of travel."""
        c, s = math.cos(heading), math.sin(heading)
        sd = np.array(SUN_DIR_CAMERA, np.float64)
        sd = np.array([c * sd[0] - s * sd[1], s * sd[0] + c * sd[1], sd[2]])
        return sd / np.linalg.norm(sd)

    def _bucket(self, need: int):
        cap = MIN_BUCKET
        while cap < need:
            cap *= 2
        cap = min(cap, max(self.n_rocks, 1))
        if cap not in self._buckets:
            self._buckets[cap] = (ti.Vector.field(3, ti.f32, cap), ti.field(ti.f32, cap),
                                  ti.Vector.field(3, ti.f32, cap))
        return cap, self._buckets[cap]

    def cull(self, eye, fwd, right, up, sun) -> int:
        """Cull the rocks; splat the resting ones ("splat" mode) and compact those GGUI draws into a bucket.
        Return how many GGUI draws (also ``self.last_count``)."""
        sim, n = self.sim, self.n_rocks
        self._drawn = None
        if n == 0:
            self.last_count = 0
            return 0
        w, h = self.resolution
        args = (self._zbuf, self._acc, self._rows, _vec(eye), _vec(fwd), _vec(right), _vec(up), self.tan_x,
                self.tan_y, math.sqrt(1 + self.tan_x ** 2), math.sqrt(1 + self.tan_y ** 2), 0.05,
                self.draw_distance, self.px_per_rad, self.lod_pixels,
                h / w,  # GGUI 1.7.4 draws particles w/h times too large
                _vec(sun), ti.Vector(AMBIENT), ti.Vector(SUN_COLOR), self.rocks == "splat")
        need = max(int(self.last_count * 1.25), 1)
        while True:
            cap, (bp, br, bc) = self._bucket(need)
            _rocks_pass(sim.world.pos, sim.world.radius, sim.world.rock_id, sim.world.phase, n, bp, br, bc,
                        self._count, cap, *args)
            count = int(self._count[None])
            if count <= cap:
                break
            need = count
            if self.rocks == "splat":  # the splats are in the buffers already: clear them before re-running
                _clear_buffers(self._zbuf, self._acc)
        self.last_count = count
        self._drawn = (bp, br, bc, count)
        return count

    def render_frame(self) -> np.ndarray:
        """Draw the simulation's current state; return the upright image, (H, W, 3) uint8.

        The returned array is reused by the next call: copy it to keep it.
        """
        t0 = time.perf_counter()
        sim = self.sim
        origin = np.asarray(sim.origin, np.float64)
        eye, target, fwd, right, up, heading = self.view()
        sd = self.sun_direction(heading)
        t1 = time.perf_counter()
        self.cull(eye, fwd, right, up, sd)
        t2 = time.perf_counter()

        poses = sim.vehicle_poses()
        self._paint_sky_and_ground(eye, fwd, right, up, origin, poses, sd)

        drawn = self._draw_ggui(eye, target, sd, origin, poses)
        for _ in range(GLITCH_RETRIES):
            # a safety net: a renderable GGUI lost (the one cause seen, the mesh's unfilled model matrix, is
            # avoided: see the module docstring) shows as a collapse of the pixels GGUI drew, or a vehicle in
            # view that hardly covers its screen box (_vehicle_lost): draw the 3D layer again
            if drawn >= GLITCH_DROP * self._prev_drawn and not self._vehicle_lost(eye, fwd, right, up):
                break
            self.redraws += 1
            drawn = self._draw_ggui(eye, target, sd, origin, poses)
        self._prev_drawn = drawn
        self.frames_drawn += 1
        if self.window_every > 0 and self.frames_drawn % self.window_every == 0:
            self._close_window()
            self._open_window()
        t3 = time.perf_counter()
        self.timings["cull"] += t2 - t1
        self.timings["draw"] += (t1 - t0) + (t3 - t2)
        return self._out

    def _draw_ggui(self, eye, target, sd, origin, poses) -> int:
        """Declare the 3D layer, draw it, read it back over the background into ``self._out``; return how many
        pixels GGUI drew."""
        if self._window is None:  # closed (or another renderer took over GGUI): reopen
            self._open_window()
        self._canvas.set_background_color(tuple(k / 255.0 for k in KEY))  # replaced by _sky in _to_u8
        scene = self._scene
        cam = self._camera
        cam.position(*(float(x) for x in eye))
        cam.lookat(*(float(x) for x in target))
        cam.up(*GL_UP)
        scene.set_camera(cam)
        scene.ambient_light(AMBIENT)
        scene.point_light(tuple(float(x) for x in eye + 2000.0 * sd), SUN_COLOR)
        self._draw_vehicles(scene, origin, poses)
        if self._drawn is not None and self._drawn[3] > 0:
            bp, br, bc, count = self._drawn
            scene.particles(bp, 0.03, per_vertex_color=bc, per_vertex_radius=br, index_count=count)
        self._draw_overlays(scene, origin)
        self._canvas.scene(scene)
        raw = self._window.get_image_buffer_as_numpy()  # (W, H, 4) float32, y up; consumes the frame
        _to_u8(raw, self._out, self._sky, self._drawn_px)
        self._raw = raw
        return int(self._drawn_px[None])

    def _vehicle_lost(self, eye, fwd, right, up) -> bool:
        """True if a vehicle in full view (in front of the camera, its screen box at least 3 x 3 pixels and
        inside the image) has almost no pixel drawn by GGUI inside its screen box: its mesh was lost. (A
        vehicle covers most of its box; flying rocks in front of it only a few pixels: below
        LOST_COVERAGE of the box counts as lost.)"""
        if self._v_frame is None or self.flags.tire_rays or self.flags.hash_cells:  # wireframes: see-through
            return False
        W, H = self.resolution
        key = np.array(KEY, np.float32) / 255.0
        start = 0
        for nv in self._v_sizes:
            d = self._v_frame[start:start + nv].astype(np.float64) - eye
            start += nv
            z = d @ fwd
            if z.min() < 0.5 or z.min() > self.draw_distance:
                continue
            sx = (d @ right / (z * self.tan_x) + 1.0) * 0.5 * W
            sy = (d @ up / (z * self.tan_y) + 1.0) * 0.5 * H  # rows of the read-back: 0 = bottom
            x0, x1, y0, y1 = (int(math.floor(v)) for v in (sx.min(), sx.max(), sy.min(), sy.max()))
            if x0 < 0 or y0 < 0 or x1 >= W or y1 >= H or x1 - x0 < 3 or y1 - y0 < 3:
                continue
            box = self._raw[x0 + 1:x1, y0 + 1:y1, :3]
            drawn = np.any(np.abs(box - key) >= 0.5 / 255.0, axis=2)
            if drawn.mean() < LOST_COVERAGE:
                return True
        return False

    # -------------------------------------------------------------------------------------------- parts
    def _paint_sky_and_ground(self, eye, fwd, right, up, origin, poses, sun_dir) -> None:
        period = 2.0 * self.tile
        wrap = (float(np.mod(origin[0], period)), float(np.mod(origin[1], period)))
        light = tuple(a + l * max(float(sun_dir[2]), 0.0) for a, l in zip(AMBIENT, SUN_COLOR))
        cars = np.zeros((MAX_CARS, 7), np.float32)
        specs = self.sim.scene.vehicles
        k = 0
        for p, v in zip(poses, specs):
            if k == MAX_CARS:
                break
            loc = np.asarray(p.position, np.float64) - origin
            cars[k] = (loc[0], loc[1], math.cos(p.heading), math.sin(p.heading), 0.5 * v.length, 0.5 * v.width,
                       0.35 + 0.4 * v.width)
            k += 1
        self._cars.from_numpy(cars)
        _paint_ground(self._sky, _vec(eye), _vec(fwd), _vec(right), _vec(up), self.tan_x, self.tan_y,
                      self.ground_z - float(origin[2]), ti.Vector(wrap), self.tile, ti.Vector(GROUND_A),
                      ti.Vector(GROUND_B), ti.Vector(light), ti.Vector(self.background), ti.Vector(self.horizon),
                      HAZE * self.draw_distance, self._cars, k, self._zbuf, self._acc, self._rows,
                      self.rocks == "splat")

    def _draw_vehicles(self, scene, origin, poses) -> None:
        vs, ns = self._v_local
        out_v = np.empty_like(vs)
        out_n = np.empty_like(ns)
        start = 0
        for p, nv in zip(poses, self._v_sizes):
            c, s = math.cos(p.heading), math.sin(p.heading)
            rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            sl = slice(start, start + nv)
            out_v[sl] = vs[sl] @ rot.T + (np.asarray(p.position, np.float64) - origin)
            out_n[sl] = ns[sl] @ rot.T
            start += nv
        self._v_frame = out_v
        self._v_verts.from_numpy(out_v.astype(np.float32))
        self._v_norms.from_numpy(out_n.astype(np.float32))
        # with the tire-ray or hash-cell overlay on, vehicles are wireframes so that what is under them shows
        scene.mesh_instance(self._v_verts, indices=self._v_idx, normals=self._v_norms, per_vertex_color=self._v_cols,
                            transforms=self._v_model, show_wireframe=self.flags.tire_rays or self.flags.hash_cells)

    def _draw_overlays(self, scene, origin) -> None:
        sim = self.sim
        lift = 0.02  # m above the ground
        if self._bed_lines is not None:
            c = np.asarray(sim.bed_center, np.float64) - origin
            th = np.linspace(0, 2 * np.pi, 129)
            rad = float(sim.scene.bed.radius)
            ring = np.stack([c[0] + rad * np.cos(th), c[1] + rad * np.sin(th),
                             np.full(129, self.ground_z - origin[2] + lift)], 1)
            self._bed_lines.from_numpy(np.stack([ring[:-1], ring[1:]], 1).reshape(-1, 3).astype(np.float32))
            scene.lines(self._bed_lines, 3.0, color=BED_EDGE_COLOR)
        if self._ray_lines is not None:
            rays = np.asarray(sim.tire_rays(), np.float64).reshape(-1, 2, 3)[:MAX_RAYS]
            if len(rays):
                buf = np.zeros((2 * MAX_RAYS, 3), np.float32)
                buf[:2 * len(rays)] = (rays - origin).reshape(-1, 3)
                self._ray_lines.from_numpy(buf)
                scene.lines(self._ray_lines, 4.0, color=RAY_COLOR, vertex_count=2 * len(rays))
        if self._cell_lines is not None:
            cells = np.asarray(sim.queried_cells(), np.int64).reshape(-1, 3)[:MAX_CELLS]
            if len(cells):
                size = float(sim.cell_size)
                corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], np.float64)
                edges = np.array([(a, b) for a in range(8) for b in range(a + 1, 8)
                                  if bin(a ^ b).count("1") == 1]).reshape(-1)
                pts = (cells[:, None, :].astype(np.float64) + corners[edges][None]) * size  # (K, 24, 3) local
                buf = np.zeros((24 * MAX_CELLS, 3), np.float32)
                buf[:24 * len(cells)] = pts.reshape(-1, 3)
                self._cell_lines.from_numpy(buf)
                scene.lines(self._cell_lines, 1.5, color=CELL_COLOR, vertex_count=24 * len(cells))


_LIBC = []
_LIVE = [None]  # the Renderer whose GGUI window is open (one at a time)


def _trim_heap() -> None:
    """Give freed heap memory back to the OS (glibc ``malloc_trim``). A destroyed GGUI window frees its
    Vulkan memory, but into a fragmented heap (a float read-back buffer per frame, lavapipe's JIT): without
    this, RSS still climbs by ~50 MB steps every few window re-creations; with it, ~5 MB per 100 frames."""
    if not _LIBC:
        try:
            import ctypes

            libc = ctypes.CDLL("libc.so.6")
            _LIBC.append(libc.malloc_trim)
        except (OSError, AttributeError):  # not glibc
            _LIBC.append(None)
    if _LIBC[0] is not None:
        _LIBC[0](0)


def _ggui(make, *args, **kwargs):
    """Create a GGUI object; a missing Vulkan driver becomes one RuntimeError line saying what to install."""
    try:
        return make(*args, **kwargs)
    except Exception as e:  # RuntimeError("Vulkan must be available for GGUI"), GGUINotAvailableException
        if "vulkan" in str(e).lower() or "ggui" in str(e).lower():
            raise RuntimeError(VULKAN_HINT) from None
        raise


def _vec(a):
    return ti.Vector([float(x) for x in a])


def check_resolution(res) -> tuple[int, int]:
    """(width, height) as even ints >= 16, or ValueError with a clear message."""
    try:
        w, h = (int(x) for x in res)
    except Exception:
        raise ValueError(f"resolution must be [width, height], got {res!r}") from None
    if w < 16 or h < 16 or w % 2 or h % 2:
        raise ValueError(f"resolution must be two even integers >= 16 (H.264 in yuv420p needs even sides), "
                         f"got {w}x{h}")
    return w, h


# ------------------------------------------------------------------------------------------------ render_scene
def _existing_outputs(paths: dict) -> list:
    """Files of a previous render that this one would replace."""
    found = []
    video = paths["video"]
    if video is not None and video.exists():
        found.append(video)
    frames = paths["frames"]
    if frames.is_dir():
        found += sorted(frames.glob("frame_*.png"))
    return found


def render_scene(scene_or_path, out_dir=None, frames=None, resolution=None, fps=None, fmt="mp4", arch="cpu",
                 overwrite=False, progress=True, profile=False, *, resume=False, rocks="splat",
                 window_every=WINDOW_EVERY, on_frame=None, checkpoint_every=None) -> dict:
    """Simulate a scene and render it offscreen to PNG frames plus an MP4 or GIF (``fmt="png"``: frames only).

    ``scene_or_path``: a scene file (TOML) or a validated :class:`~taichi_rocks.config.scene.Scene`. Frame k shows the
    simulation at t = k / fps; ``frames`` defaults to round(duration * fps). ``resolution`` and ``fps`` override
    the scene's [render] table. Outputs go to ``out_dir`` (default ``renders/<scene name>/``): ``frames/``
    and ``<scene name>.<fmt>``; existing outputs raise FileExistsError unless ``overwrite`` (which removes the
    old frames and video first). An odd resolution raises ValueError; a machine without Vulkan raises
    RuntimeError naming the packages to install. ``rocks``: "splat" (resting rocks drawn by a Taichi kernel
    behind the GGUI scene, flying ones as GGUI particles; fast) or "particles" (every rock a GGUI particle).
    ``resume``: keep the frames a previous (interrupted) render finished, frame_00000.png ... without a gap,
    restore the newest simulation state it saved before the first missing frame (every ``checkpoint_every``
    frames, default 30, in ``out_dir/.resume/``; see resume.py), advance the simulation and the camera from
    there to the first missing frame without drawing, re-encode the kept frames into the video and render the
    rest (the result equals an uninterrupted render: the simulation is deterministic); the frames must have
    the requested resolution, and the scene, fps and rock mode must be the interrupted render's.
    ``progress``: a tqdm bar on stderr; None shows it only on a terminal.
    ``on_frame(k, image)``, if given, sees every frame drawn (tests).

    Returns {"scene", "out_dir", "frames_dir", "video", "frames", "resumed_from" (first frame drawn),
    "replayed_from" (first frame simulated without drawing, after a restored state), "resolution", "video_fps",
    "seconds", "frames_per_second" (frames drawn / seconds of the frame loop; also "fps_measured"), "redraws"}
    and with ``profile`` a "profile" dict of seconds: "simulation", "culling" (rock
    culling and splatting), "drawing" (camera, sky and ground, GGUI drawing and the read-back), "encoding"
    (time the render loop waited on the frame writer, including the final flush) and "encoding_busy" (the
    writer thread's own time, which overlaps the others), "other" (the rest of the frame loop), "setup"
    (before the first frame: scene, simulation and window set-up) and "first_frame" (the first frame alone,
    mostly kernel compilation; included in the others)."""
    from tqdm import tqdm

    from ..output.resume import CHECKPOINT_EVERY, RenderCheckpoints, fingerprint
    from ..engine.runtime import init_taichi
    from ..config.scene import load_scene
    from ..engine.simulation import Simulation
    from ..output.video import FrameWriter, existing_size, finished_frames, frame_name, output_paths

    t_start = time.perf_counter()
    if resolution is not None:
        resolution = check_resolution(resolution)
    if fps is not None and not (isinstance(fps, (int, float)) and fps > 0):
        raise ValueError(f"fps must be a number > 0, got {fps!r}")
    if frames is not None and (not isinstance(frames, int) or isinstance(frames, bool) or frames < 1):
        raise ValueError(f"frames must be an int >= 1, got {frames!r}")
    if rocks not in ROCK_MODES:
        raise ValueError(f"rocks must be one of {', '.join(ROCK_MODES)}, got {rocks!r}")
    scene = load_scene(scene_or_path) if isinstance(scene_or_path, (str, os.PathLike)) else scene_or_path
    out_dir = Path(out_dir) if out_dir is not None else Path("renders") / scene.name
    paths = output_paths(out_dir, scene.name, fmt)  # ValueError on an unknown format
    video_fps = float(fps if fps is not None else scene.render.fps)
    n_frames = frames if frames is not None else max(1, int(round(scene.duration * video_fps)))
    old = _existing_outputs(paths)
    start = 0
    if resume:
        start = min(finished_frames(paths["frames"]), n_frames)
        size = existing_size(paths["frames"]) if start else None
        want = resolution or tuple(int(x) for x in scene.render.resolution)
        if size is not None and tuple(size) != tuple(want):
            raise ValueError(f"cannot resume: {paths['frames']} holds {size[0]}x{size[1]} frames, "
                             f"this render is {want[0]}x{want[1]}")
        keep = {paths["frames"] / frame_name(i) for i in range(start)}
        old = [f for f in old if f not in keep]
    elif old and not overwrite:
        what = paths["video"] if paths["video"] in old else paths["frames"]
        raise FileExistsError(f"{what} already exists (pass overwrite=True or --overwrite to replace it)")

    init_taichi(arch)
    sim = Simulation(scene, arch=arch)
    renderer = Renderer(sim, resolution=resolution, fps=video_fps, rocks=rocks, window_every=window_every)
    every = CHECKPOINT_EVERY if checkpoint_every is None else int(checkpoint_every)
    checkpoints = RenderCheckpoints(out_dir, fingerprint(scene, video_fps, renderer.resolution, rocks), every)
    if resume:
        try:
            checkpoints.check_same_render()
        except ValueError:
            renderer.close()
            raise
    for f in old:  # only now: a failure above leaves the previous render untouched
        f.unlink()
    checkpoints.start(resume, start)
    writer = FrameWriter(out_dir, scene.name, video_fps, fmt, start=start)
    t_sim = 0.0
    t_first = 0.0
    ok = False
    t0 = time.perf_counter()
    replay_from = 0
    try:
        if start:  # resuming: restore the newest saved state, replay simulation and camera, draw nothing
            saved = checkpoints.latest_before(start)
            if saved is not None:
                replay_from = checkpoints.restore(saved, sim, renderer.rig) + 1
        for k in range(replay_from, start):
            sim.advance_to(k / video_fps)
            renderer.view()
        t_replay = time.perf_counter() - t0
    except BaseException:
        renderer.close()
        writer.close(ok=False)
        raise
    bar = tqdm(total=n_frames, initial=start, unit="frame", desc=scene.name, file=sys.stderr,
               disable=None if progress is None else not progress, dynamic_ncols=True)
    t_loop = time.perf_counter()
    try:
        for k in range(start, n_frames):
            t0 = time.perf_counter()
            sim.advance_to(k / video_fps)
            t_sim += time.perf_counter() - t0
            img = renderer.render_frame()
            if on_frame is not None:
                on_frame(k, img)
            writer.write(img)
            if checkpoints.due(k, n_frames):
                checkpoints.save(k, sim, renderer.rig)
            bar.update(1)
            if k == start:
                t_first = time.perf_counter() - t_loop
        ok = True
    finally:
        bar.close()
        renderer.close()
        video = writer.close(ok=ok)
    checkpoints.finish()  # complete: nothing to resume
    seconds = time.perf_counter() - t_start
    loop = time.perf_counter() - t_loop
    out = {
        "scene": scene.name,
        "out_dir": str(out_dir),
        "frames_dir": str(paths["frames"]),
        "video": str(video) if video is not None else None,
        "frames": n_frames,
        "resumed_from": start,
        "replayed_from": replay_from if start else None,
        "resolution": tuple(renderer.resolution),
        "video_fps": video_fps,
        "seconds": seconds,
        "frames_per_second": (n_frames - start) / loop if loop > 0 else 0.0,
        "redraws": renderer.redraws,  # frames whose GGUI layer had to be drawn twice (GGUI glitch guard)
    }
    out["fps_measured"] = out["frames_per_second"]
    if profile:
        prof = {"simulation": t_sim, "culling": renderer.timings["cull"], "drawing": renderer.timings["draw"],
                "encoding": writer.timings["encode"], "encoding_busy": writer.timings["encode_busy"]}
        prof["other"] = max(0.0, loop - t_sim - prof["culling"] - prof["drawing"] - prof["encoding"])
        prof["setup"] = t_loop - t_start - t_replay
        prof["resume_replay"] = t_replay  # simulating the frames kept from an interrupted render
        prof["first_frame"] = t_first  # included above; mostly kernel compilation (cached on later runs)
        out["profile"] = prof
    return out
