"""Dust ([effects] dust; config/effects/dust.py DRAWS) drawn as soft, translucent puffs.

A particle of the dust model stands for a parcel of fines that turbulent diffusion spreads: it is drawn as a
puff of radius ``R = size + sqrt(2 K age)`` (K the [dust] ``diffusion``, the random walk's spread; the age
follows from the opacity, alpha = opacity exp(-age / fade)) whose opacity falls smoothly from its centre to
its rim, a(s) = alpha_p (1 - s^2)^2 (s = distance / R), with alpha_p = ``PUFF`` alpha: the cloud's look comes from
many overlapping puffs. Puffs are depth-tested against the resting rocks (the splat's depth buffer) as soft
particles (Lorach 2007, "Soft Particles", NVIDIA): a puff is a ball of depths [z - R, z + R], and a pixel shows
the fraction of it in front of the rock there, so a puff on the road is cut by it smoothly, not by a line;
against the vehicles, by the boxes of their bodies: a puff behind a vehicle is hidden where the vehicle is drawn.
Seen from a cabin (the driver's view), the vehicle ridden in is tested pixel by pixel: each pixel's ray is cast
at its body below the belt line (the bonnet, the doors) and at its windscreen's frame (the pillars, the header,
the roof's lining, the dashboard, the floor: render/interior.py ``frame_solids``), and the nearest gives the
pixel a depth that the puffs are tested against as softly as against the rocks; and no puff is drawn at all
over a pixel of the frame, which lies inside the glass where no dust is (tested again at the frame's full
resolution as it is blended).

Offscreen (``render``) the puffs are composited over the finished frame (:class:`SoftDust`): each covered pixel
of an image at half the frame's resolution sums the optical depth -ln(1 - a) of the puffs over it, in fixed point (integer sums: the same frame whatever
the order of the threads), twice (over the background, and over what GGUI draws, which has no depth), then
takes c = c T + c_dust (1 - T), T = exp(-sum) interpolated bilinearly to the frame's pixels. The order of the puffs does not
matter, since they all have one colour. In a shown window (``view``) GGUI draws the frame on the screen, so there
is no finished frame to composite over: the dust is GGUI particles there (:class:`DustLayer`), each coloured
towards what lies behind it by its opacity (GGUI's particles have no alpha) and smaller as it fades.
"""

import math

import numpy as np
import taichi as ti

from ..engine.trees import FieldTrees
from ..motion.cabin import cabin_of
from .camera import to_gl
from .interior import frame_solids
from .kernels import empty_key, is_key, key_depth, raw_rgb
from .looks import GROUND_A, GROUND_B, rgb

__all__ = ["DustLayer", "SoftDust", "draw_dust", "dust_looks", "puffs", "soft_dust"]

MIN_ALPHA = 0.03  # puffs fainter than this are not drawn
PUFF = 0.15  # a puff's opacity at its centre, per unit of the particle's opacity
MAX_PX = 48  # the largest radius a puff is drawn with, pixels (nearer puffs are drawn this large)
TAU_ONE = 1 << 16  # fixed point of the summed optical depth


def dust_looks(opacity, table, haze) -> tuple:
    """The window's GGUI particles: (colours (K, 3) f32, radii (K,) f32) of particles of ``opacity``: the colour
    blended by opacity towards what lies behind, taken as the mean of the haze and the ground's colour, the
    radius r = size (0.4 + 0.6 alpha)."""
    a = np.asarray(opacity, np.float32)[:, None]
    behind = (np.asarray(haze, np.float32) + 0.5 * (np.asarray(GROUND_A, np.float32) + GROUND_B)) / 2.0
    col = a * np.asarray(rgb(table.color), np.float32) + (1.0 - a) * behind
    rad = float(table.size) * (0.4 + 0.6 * a[:, 0])
    return col.astype(np.float32), rad.astype(np.float32)


def puff_radius(opacity, table) -> np.ndarray:
    """Drawn radius (m) of particles of ``opacity``: size + sqrt(2 K age), age = fade ln(opacity0 / alpha)."""
    a = np.clip(np.asarray(opacity, np.float64), 1e-6, None)
    age = float(table.fade) * np.maximum(np.log(float(table.opacity) / a), 0.0)
    return float(table.size) + np.sqrt(2.0 * float(table.diffusion) * age)


def _hidden_by_boxes(eye, d, dist, boxes) -> np.ndarray:
    """(K,) bool: does the segment eye -> eye + d dist (d unit rows) cross one of ``boxes`` (centre xy, heading,
    half length, half width, bottom z, top z; local frame) before its end? A box holding the eye (the cabin one
    rides in) hides nothing."""
    hidden = np.zeros(len(d), bool)
    for cx, cy, heading, hl, hw, z0, z1 in boxes:
        c, s = math.cos(heading), math.sin(heading)
        ex, ey = eye[0] - cx, eye[1] - cy
        o = np.array([c * ex + s * ey, -s * ex + c * ey, eye[2]])  # the eye in the box's frame
        lo, hi = np.array([-hl, -hw, z0]), np.array([hl, hw, z1])
        if np.all(o >= lo) and np.all(o <= hi):
            continue
        u = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]], axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (lo - o) / u, (hi - o) / u
        near = np.nanmax(np.where(np.isnan(t0), -np.inf, np.minimum(t0, t1)), axis=1)
        far = np.nanmin(np.where(np.isnan(t0), np.inf, np.maximum(t0, t1)), axis=1)
        hidden |= (near <= far) & (far > 0.0) & (near < dist)
    return hidden


def puffs(local, opacity, table, eye, fwd, right, up, lens, resolution, boxes=()) -> tuple:
    """The puffs in view: (rows (k, 4) f32 of x, y (pixels, y up), radius (pixels), depth (m, along ``fwd``);
    their centre opacity (k,) f32; their radius (k,) f32, m; hidden (k,) i32, 1 where a vehicle's box lies
    between the eye and the puff).
    ``local``: the particles' positions in the renderer's local frame; ``lens``: render/camera.py Lens."""
    W, H = resolution
    local = np.asarray(local, np.float64).reshape(-1, 3)
    alpha = PUFF * np.asarray(opacity, np.float64).reshape(-1)
    d = local - np.asarray(eye, np.float64)
    z = d @ np.asarray(fwd, np.float64)
    R = puff_radius(opacity, table)
    zz = np.maximum(z, 1e-3)
    pr = R * lens.px_per_rad / zz
    x = (d @ np.asarray(right, np.float64) / (zz * lens.tan_x) + 1.0) * 0.5 * W
    y = (d @ np.asarray(up, np.float64) / (zz * lens.tan_y) + 1.0) * 0.5 * H
    pr_drawn = np.minimum(pr, MAX_PX)
    keep = (alpha >= PUFF * MIN_ALPHA) & (z > R) & (pr_drawn >= 0.5) & (x > -pr_drawn) & (x < W + pr_drawn) & \
        (y > -pr_drawn) & (y < H + pr_drawn)
    idx = np.flatnonzero(keep)
    dist = np.linalg.norm(d[idx], axis=1)
    hidden = _hidden_by_boxes(np.asarray(eye, np.float64), d[idx] / np.maximum(dist, 1e-9)[:, None], dist, boxes)
    rows = np.stack([x[idx], y[idx], pr_drawn[idx], z[idx]], axis=1).astype(np.float32)
    return rows, alpha[idx].astype(np.float32), R[idx].astype(np.float32), hidden.astype(np.int32)


def vehicle_boxes(sim, poses, origin, ground_z) -> list:
    """Each vehicle's body as a box in the local frame: (centre x, y, heading, half length, half width, bottom z,
    top z)."""
    out = []
    for spec, pose in zip(sim.scene.vehicles, poses):
        p = np.asarray(pose.position, np.float64) - np.asarray(origin, np.float64)
        out.append((p[0], p[1], float(pose.heading), spec.length / 2, spec.width / 2, ground_z - origin[2],
                    ground_z - origin[2] + spec.height))
    return out


SOLID = 12  # a solid's row for the kernels: M (3 x 3, row-major), o (3): s(t) = o + t M (x tan_x, y tan_y, 1)


def cabin_solids(spec, pose, origin, eye, fwd, right, up) -> np.ndarray:
    """The windscreen's frame of vehicle ``spec`` at ``pose`` (render/interior.py ``frame_solids``), then its body
    below the belt line (a box from the ground), placed as its mesh is (body frame on the ground, turned by the
    heading, local frame), as rows of :data:`SOLID` for a camera at ``eye`` (:func:`solid_rows`)."""
    c, s = math.cos(pose.heading), math.sin(pose.heading)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    place = np.asarray(pose.position, np.float64) - np.asarray(origin, np.float64)
    cab = cabin_of(spec)
    body = np.array([(-cab.length / 2, -cab.width / 2, 0.0), (cab.length, 0, 0), (0, cab.width, 0), (0, 0, cab.belt)])
    solids = np.concatenate([frame_solids(cab), body[None]])
    placed = solids @ rot.T
    placed[:, 0] += place
    return solid_rows(placed, eye, fwd, right, up)


def solid_rows(solids, eye, fwd, right, up) -> np.ndarray:
    """Parallelepipeds ``solids`` ((K, 4, 3): a corner and three edges, local frame) as rows of :data:`SOLID` for
    a camera at ``eye`` looking along ``fwd``: a point of the ray through the pixel at (x, y) (-1 to 1 across the
    frame), at depth t along ``fwd``, lies in solid k when each coordinate of s(t) = o + t M (x tan_x, y tan_y,
    1) is in [0, 1]."""
    basis = np.column_stack([right, up, fwd]).astype(np.float64)  # camera (x, y, depth) -> local
    rows = []
    for corner, *edges in np.asarray(solids, np.float64):
        inv = np.linalg.inv(np.column_stack(edges))
        rows.append(np.concatenate([(inv @ basis).ravel(), inv @ (np.asarray(eye, np.float64) - corner)]))
    return np.array(rows, np.float32).reshape(-1, SOLID)


SQUARES = (4, 8, 16, 32, MAX_PX)  # the half sides of the squares puffs are drawn in, by their radius (pixels)


def _by_square(rows: np.ndarray) -> list:
    """The puffs' indices grouped by the smallest square of :data:`SQUARES` that holds each one's disc (its radius
    plus the pixel its centre falls in), with that square's half side."""
    need = np.ceil(rows[:, 2]).astype(np.int64) + 1
    side = np.searchsorted(np.asarray(SQUARES), np.minimum(need, MAX_PX))
    return [(half, np.flatnonzero(side == s)) for s, half in enumerate(SQUARES) if np.any(side == s)]


@ti.kernel
def _splat(tau: ti.template(), rows: ti.types.ndarray(dtype=ti.math.vec4, ndim=1),
           alpha: ti.types.ndarray(dtype=ti.f32, ndim=1), reach: ti.types.ndarray(dtype=ti.f32, ndim=1),
           hidden: ti.types.ndarray(dtype=ti.i32, ndim=1), zbuf: ti.template(), use_z: ti.template(),
           half: ti.template(), own: ti.template()):
    """Each puff's optical depth into the pixels it covers, twice: over the background (``tau[i, j][0]``: the
    part of the puff in front of the resting rock there, soft) and over what GGUI draws (``[1]``: unless a
    vehicle hides the puff, and in front of ``own``, the depth of the vehicle the eye rides in). One flat loop
    over (puff, pixel of its square of half side ``half``), no inner
    loop; integer sums (the same result in any order). Runs between the rock pass and the ground pass, which
    clears the depths."""
    W, H = tau.shape
    S = 2 * half + 1
    for k, q in ti.ndrange(rows.shape[0], S * S):
        p = rows[k]
        ii = ti.cast(ti.floor(p[0]), ti.i32) + q % S - half
        jj = ti.cast(ti.floor(p[1]), ti.i32) + q // S - half
        if 0 <= ii < W and 0 <= jj < H:
            dx, dy = ii + 0.5 - p[0], jj + 0.5 - p[1]
            s2 = (dx * dx + dy * dy) / (p[2] * p[2])
            if s2 < 1.0:
                a = ti.min(alpha[k] * (1.0 - s2) * (1.0 - s2), 0.99)
                front = 1.0
                if ti.static(use_z):  # the rock at the middle of the 2 x 2 full-resolution pixels of (ii, jj)
                    key = zbuf[ti.min(2 * ii + 1, zbuf.shape[0] - 1), ti.min(2 * jj + 1, zbuf.shape[1] - 1)]
                    if key != empty_key():
                        near = key_depth(key)
                        front = ti.min(ti.max((near - p[3] + reach[k]) / (2.0 * reach[k]), 0.0), 1.0)
                if front > 0.0:
                    ti.atomic_add(tau[ii, jj][0], ti.cast(-ti.log(1.0 - a * front) * TAU_ONE + 0.5, ti.i32))
                # the 3D layer: the part in front of the vehicle the eye rides in (FAR: all of it)
                mine = ti.min(ti.max((own[ii, jj] - p[3] + reach[k]) / (2.0 * reach[k]), 0.0), 1.0)
                if hidden[k] == 0 and mine > 0.0:
                    ti.atomic_add(tau[ii, jj][1], ti.cast(-ti.log(1.0 - a * mine) * TAU_ONE + 0.5, ti.i32))


@ti.func
def _transmittance(tau, u, v, c: ti.template()):
    """exp(-sum) of sums ``c`` (0: over the background, 1: over the 3D layer) at the half-resolution point (u, v)
    (pixel centres at k + 0.5), bilinear between the four nearest sums (clamped at the edges)."""
    W, H = tau.shape
    x, y = u - 0.5, v - 0.5
    i0, j0 = ti.cast(ti.floor(x), ti.i32), ti.cast(ti.floor(y), ti.i32)
    fx, fy = x - i0, y - j0
    T = 0.0
    for di, dj in ti.static(ti.ndrange(2, 2)):
        i = ti.min(ti.max(i0 + di, 0), W - 1)
        j = ti.min(ti.max(j0 + dj, 0), H - 1)
        w = (fx if di else 1.0 - fx) * (fy if dj else 1.0 - fy)
        T += w * ti.exp(-ti.cast(tau[i, j][c], ti.f32) / TAU_ONE)
    return T


FAR = 1.0e30  # a depth no puff is behind


@ti.func
def _nearest(solids: ti.template(), n, dx, dy):
    """The depth (along the view) at which the ray of camera direction (dx, dy, 1) enters the nearest of the
    first ``n`` solids (rows of SOLID) in front of the eye, or FAR. Slabs: each coordinate of s(t) = o + t v
    within [0, 1]."""
    depth = FAR
    for k in range(n):
        near, far = 0.0, FAR
        for a in ti.static(range(3)):
            o = solids[k, 9 + a]
            v = solids[k, 3 * a] * dx + solids[k, 3 * a + 1] * dy + solids[k, 3 * a + 2]
            if ti.abs(v) < 1.0e-12:
                if o < 0.0 or o > 1.0:
                    near = FAR  # parallel to this slab and outside it
            else:
                t0, t1 = -o / v, (1.0 - o) / v
                near = ti.max(near, ti.min(t0, t1))
                far = ti.min(far, ti.max(t0, t1))
        if near <= far:
            depth = ti.min(depth, near)
    return depth


@ti.kernel
def _own_depth(own: ti.template(), solids: ti.types.ndarray(dtype=ti.f32, ndim=2), n: ti.i32, tan_x: ti.f32,
               tan_y: ti.f32):
    """Each half-resolution pixel's depth of the vehicle the eye rides in (the nearest of the ``n`` solids its
    ray meets; FAR: none)."""
    W, H = own.shape
    for i, j in own:
        own[i, j] = _nearest(solids, n, ((i + 0.5) * 2.0 / W - 1.0) * tan_x, ((j + 0.5) * 2.0 / H - 1.0) * tan_y)


@ti.kernel
def _blend(tau: ti.template(), out: ti.types.ndarray(dtype=ti.u8, ndim=3), raw: ti.types.ndarray(dtype=ti.f32, ndim=3),
           color: ti.math.vec3, solids: ti.types.ndarray(dtype=ti.f32, ndim=2), n_solids: ti.i32, tan_x: ti.f32,
           tan_y: ti.f32):
    """c = c T + c_dust (1 - T) over the frame, T = exp(-sum) of the half-resolution sums, bilinear (the
    background's sums where GGUI left its clear colour, else the 3D layer's, but none over a pixel of the first
    ``n_solids`` solids: the windscreen's frame around the eye, inside the glass); then the sums cleared."""
    H, W = out.shape[0], out.shape[1]
    for i, j in ti.ndrange(W, H):
        u, v = (i + 0.5) * 0.5, (j + 0.5) * 0.5
        r, g, b = raw_rgb(raw, i, j)
        T = 1.0
        if is_key(r, g, b):
            T = _transmittance(tau, u, v, 0)
        elif _nearest(solids, n_solids, ((i + 0.5) * 2.0 / W - 1.0) * tan_x,
                      ((j + 0.5) * 2.0 / H - 1.0) * tan_y) >= FAR:
            T = _transmittance(tau, u, v, 1)
        if T < 0.999:
            for c in ti.static(range(3)):
                x = ti.cast(out[H - 1 - j, i, c], ti.f32) * T + color[c] * 255.0 * (1.0 - T)
                out[H - 1 - j, i, c] = ti.cast(ti.min(x + 0.5, 255.0), ti.u8)
    for i, j in tau:
        tau[i, j] = ti.Vector([0, 0])


class SoftDust:
    """The offscreen frame's dust (module docstring): the sums at half the frame's resolution (dust is soft:
    a quarter of the pixels to sum, blended back bilinearly; after Jansen & Bavoil, "High-Speed, Off-Screen
    Particles", GPU Gems 3, 2007). :meth:`splat` after the rock pass (it reads the rocks' depths),
    :meth:`blend` over the finished frame."""

    def __init__(self, width: int, height: int):
        self._trees = FieldTrees(owner=self)
        self.tau = self._trees.image((width + 1) // 2, (height + 1) // 2, (2, ti.i32))
        self.tau.fill(0)
        self.own = self._trees.image((width + 1) // 2, (height + 1) // 2, (1, ti.f32))  # see _own_depth
        self.own.fill(FAR)
        self.pending = False
        self.solids = np.zeros((1, SOLID), np.float32)  # the vehicle the eye rides in (cabin_solids)
        self.n_frame, self.tan, self.rides = 0, (1.0, 1.0), False

    def splat(self, buf, sim, settings, views, view, poses, origin, inside=None) -> int:
        """Sum ``sim``'s puffs into the pixels (``buf``: the background layer's buffers, its depths still in
        place); ``inside``: the vehicle whose cabin the camera looks out of, or None. Return the puffs."""
        d = sim.effect_arrays().get("dust")
        if d is None or not len(d["opacity"]):
            return 0
        eye, _, fwd, right, up = view[:5]
        boxes = vehicle_boxes(sim, poses, origin, views.ground_z)
        self.tan = (views.tan_x, views.tan_y)
        if inside is not None:
            self.solids = cabin_solids(sim.scene.vehicles[inside], poses[inside], origin, eye, fwd, right, up)
            _own_depth(self.own, self.solids, len(self.solids), *self.tan)
        elif self.rides:
            self.own.fill(FAR)
        self.rides, self.n_frame = inside is not None, (0 if inside is None else len(self.solids) - 1)
        rows, alpha, reach, hidden = puffs(to_gl(d["positions"], origin), d["opacity"], sim.scene.dust, eye, fwd,
                                           right, up, views, settings.resolution, boxes)
        rows = rows * np.array([0.5, 0.5, 0.5, 1.0], np.float32)  # half resolution: x, y, radius in its pixels
        for half, idx in _by_square(rows):  # small squares for the many far puffs: the work follows their area
            _splat(self.tau, rows[idx], alpha[idx], reach[idx], hidden[idx], buf.zbuf, buf.splat, half, self.own)
            self.pending = True
        return len(rows)

    def blend(self, out, raw, sim) -> None:
        """The summed puffs over the finished frame ``out`` ((H, W, 3) uint8; ``raw`` GGUI's read-back)."""
        if self.pending:
            _blend(self.tau, out, raw, ti.math.vec3(*rgb(sim.scene.dust.color)), self.solids, self.n_frame,
                   *self.tan)
            self.pending = False


def soft_dust(layer, sim, settings):
    """The offscreen renderer's dust layer (None without [effects] dust; made on first use)."""
    if "dust" not in sim.plan.effects:
        return None
    return layer if layer is not None else SoftDust(*settings.resolution)


class DustLayer:
    """The GGUI buffers of one window's dust (module docstring)."""

    def __init__(self, capacity: int):
        self.capacity = int(capacity)
        trees = FieldTrees(owner=self)
        self.pos = trees.vector(3, ti.f32, self.capacity)
        self.col = trees.vector(3, ti.f32, self.capacity)
        self.rad = trees.scalar(ti.f32, self.capacity)
        self._trees = trees

    def draw(self, scene, sim, origin, haze) -> int:
        """Declare ``sim``'s dust in the GGUI ``scene``; return the particles drawn."""
        d = sim.effect_arrays().get("dust")
        if d is None:
            return 0
        keep = np.flatnonzero(d["opacity"] >= MIN_ALPHA)[: self.capacity]
        if not len(keep):
            return 0
        col, rad = dust_looks(d["opacity"][keep], sim.scene.dust, haze)
        pos = np.zeros((self.capacity, 3), np.float32)
        pos[:len(keep)] = to_gl(d["positions"][keep], origin)
        cbuf = np.zeros((self.capacity, 3), np.float32)
        cbuf[:len(keep)] = col
        rbuf = np.zeros(self.capacity, np.float32)
        rbuf[:len(keep)] = rad
        self.pos.from_numpy(pos)
        self.col.from_numpy(cbuf)
        self.rad.from_numpy(rbuf)
        scene.particles(self.pos, float(sim.scene.dust.size), per_vertex_color=self.col, per_vertex_radius=self.rad,
                        index_count=len(keep))
        return len(keep)


def draw_dust(layer, scene, sim, origin, haze):
    """The window's one call: draw ``sim``'s dust (nothing without [effects] dust) into the GGUI ``scene`` with
    ``layer`` (None: made on first use); return the layer for the next frame."""
    if "dust" not in sim.plan.effects:
        return layer
    if layer is None:
        layer = DustLayer(sim.scene.dust.capacity)
    layer.draw(scene, sim, origin, haze)
    return layer
