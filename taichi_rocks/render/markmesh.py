"""The marks drawn (Taichi): the windscreen marks and paint chips of render/markstore.py copied to the device as
they are made, and posed with their vehicles each frame by one kernel into one GGUI mesh.

The device holds the store's two tables (``glass`` and ``chips``: float32 ndarrays, the store's rows; only the
rows made since the last frame are uploaded, :meth:`MarkMesh.upload`). Each frame :func:`pose_marks` writes the
marks shown (the first rows of each table, at most MAX_TRIANGLES triangles: past that the oldest are left out)
into a vertex buffer in GGUI's layout (render/vbo.py VBO_STRIDE: position, normal, texture coordinates,
colour), in the local frame, which GGUI draws as one mesh (:meth:`MarkMesh.draw`):

* a paint chip's triangle, p' = c + R(h) p and n' = R(h) n for its vehicle at c with heading h, lit as the face
  it lies on (PAINT_CHIP_COLOR);
* a windscreen segment, as a ribbon on the glass: the quad of half width w = width_px / 2 * d / px_per_rad about
  the segment (glass coordinates; d: the eye's distance from the segment's middle, so it is width_px pixels wide
  on the screen), clipped to the glass GLASS_EDGE inside its edges (Sutherland and Hodgman on the quad: at most
  8 corners), a fan from its first corner; in the body frame at p(y, v) +- GLASS_GAP n (render/glassmarks.py: on
  the camera's side of the glass), then posed as a chip is. Its normal is the sun's direction and its colour
  MARK_COLOR / (ambient + sun), so GGUI's lighting gives MARK_COLOR in any light (light scattered in the glass).

The kernel computes in float32 where the host code before it worked in float64 (rounded to float32 for GGUI):
a ribbon's edge can fall on the other side of a pixel's centre, so a frame with windscreen marks may differ from
the old one in a few pixels at their edges (6 of the 921,600 of the default scene's frames 286 and 291); the
paint chips, the flashes and every frame without marks are the same.

Why the vertices are posed here and not by GGUI's instance matrices: GGUI 1.7.4's ``mesh_instance`` lights the
untransformed mesh (render/vehicles.py), and a ribbon's width follows the view; the shapes are made once
(render/markstore.py), the kernel only places them: a parallel pass over what is shown, with nothing to upload.

Slots: chip triangle t takes vertices 3t .. 3t+2; after the chips, glass segment s takes two triangles (its quad,
or the first two of its clipped fan; a fan of fewer is padded with empty triangles); the rare third and further
triangles of fans clipped at the glass's edges follow all of those, in the segments' order (blocks of BLOCK
segments count theirs, a serial pass over the blocks adds the counts up: the same buffer however the threads
run; each segment's clipped ribbon is kept between the two passes). Vehicles out of view and marks seen from
behind their face (the body hides them) are left out (:meth:`MarkMesh._place`; for chips, empty triangles).
"""

from typing import NamedTuple

import numpy as np
import taichi as ti

from ..motion.bodies import body_parts
from .glassmarks import GLASS_EDGE, GLASS_FRAME, GLASS_GAP, glass_frame
from .looks import AMBIENT, SUN_COLOR
from .markstore import CHIP_ROW, GLASS_ROW
from .vbo import VBO_STRIDE, declare_mesh, host_buffer

__all__ = ["MarkMesh", "Sight", "pose_marks", "MARK_COLOR", "PAINT_CHIP_COLOR", "MARK_PX", "MAX_SEGMENTS",
           "MAX_CHIP_TRIANGLES", "BLOCK", "VEHICLE_ROW", "Look", "Span", "body_bounds"]

MARK_COLOR = (0.93, 0.95, 0.97)  # a crack or a chip scatters light: pale, nearly white
PAINT_CHIP_COLOR = (0.60, 0.60, 0.58)  # chipped paint: the grey primer and metal under it
MARK_PX = 2.0  # pixels: the width of a mark's ribbons (where the glass's margin allows)
MAX_SEGMENTS = 1 << 14  # windscreen segments drawn per vehicle at most: past this, its oldest are left out
MAX_CHIP_TRIANGLES = 1 << 15  # and paint chip triangles
BLOCK = 64  # glass segments per block of the clipped fans' count
HIDDEN = 3.0e7  # a vehicle's first rank drawn when none is: above every rank (float32 holds them exactly)
# per vehicle: its glass (render/glassmarks.py glass_frame), then its pose (cos, sin of the heading, position,
# local), the eye in its body frame, the marks' side of the glass (+-GLASS_GAP along its normal), the first rank
# drawn of its glass rows and its first slot, and the same of its chip rows
VEHICLE_ROW = GLASS_FRAME + ("cos", "sin", "px", "py", "pz", "eye_x", "eye_y", "eye_z", "side", "glass_first",
                             "glass_base", "chip_first", "chip_base")
_G = len(GLASS_FRAME)
_EYE, _SIDE, _GLASS, _CHIP = _G + 5, _G + 8, _G + 9, _G + 11

_vec3 = ti.types.vector(3, ti.f32)
#: half a ribbon's width per metre of distance (width_px / 2 / px_per_rad), the sun (unit, towards it), colours,
#: whether the vehicles are see-through (paint chips seen from behind drawn too)
Look = ti.types.struct(half_per_m=ti.f32, sun=_vec3, glass_rgb=_vec3, chip_rgb=_vec3, see_through=ti.i32)
#: the rows shown (the first ``ng`` glass and ``nc`` chip rows) and the slots drawn (segments, chip triangles)
Span = ti.types.struct(ng=ti.i32, nc=ti.i32, glass_slots=ti.i32, chip_slots=ti.i32)


class Sight(NamedTuple):
    """How the camera sees a frame: its eye and unit basis (local), its lens (the image's half extents at 1 m,
    pixels per radian), the vehicle whose cabin it looks out of (or None), the sun (unit, towards it), and
    whether the vehicles are drawn see-through (wireframes: nothing hides a mark)."""

    eye: np.ndarray
    fwd: np.ndarray
    right: np.ndarray
    up: np.ndarray
    tan_x: float
    tan_y: float
    px_per_rad: float
    inside: object = None
    sun: tuple = (0.0, 0.0, 1.0)
    see_through: bool = False


@ti.func
def _place(veh: ti.template(), i, p):
    """Body-frame point ``p`` of vehicle ``i`` in the local frame (``veh``: the VEHICLE_ROW table)."""
    c, s = veh[i, _G], veh[i, _G + 1]
    return ti.Vector([c * p[0] - s * p[1] + veh[i, _G + 2], s * p[0] + c * p[1] + veh[i, _G + 3],
                      p[2] + veh[i, _G + 4]])


@ti.func
def _turn(veh: ti.template(), i, n):
    c, s = veh[i, _G], veh[i, _G + 1]
    return ti.Vector([c * n[0] - s * n[1], s * n[0] + c * n[1], n[2]])


@ti.func
def _on_glass(veh: ti.template(), i, y, v):
    """Glass coordinates (y, v) of vehicle ``i``'s windscreen as a body-frame point on it."""
    return ti.Vector([veh[i, 0] + v * veh[i, 2], y, veh[i, 1] + v * veh[i, 3]])


@ti.func
def _put(vbo: ti.template(), row, p, n, rgb):
    """One vertex in GGUI's layout (rows past the buffer's end are dropped: the caller grows it and draws
    again)."""
    if row < vbo.shape[0]:
        for a in ti.static(range(3)):
            vbo[row, a] = p[a]
            vbo[row, 3 + a] = n[a]
            vbo[row, 8 + a] = rgb[a]
        vbo[row, 6] = 0.0
        vbo[row, 7] = 0.0
        vbo[row, 11] = 1.0


@ti.func
def _clip(poly, m, a, b, c):
    """Polygon ``poly`` (its first ``m`` rows) clipped to the half-plane a y + b v <= c (Sutherland and
    Hodgman, as render/marks.py ``clip_convex``)."""
    out = ti.Matrix.zero(ti.f32, 8, 2)
    k_out = 0
    for k in range(m):
        p = ti.Vector([poly[k, 0], poly[k, 1]])
        k1 = k + 1 if k + 1 < m else 0
        q = ti.Vector([poly[k1, 0], poly[k1, 1]])
        fp = a * p[0] + b * p[1] - c
        fq = a * q[0] + b * q[1] - c
        if fp <= 0.0 and k_out < 8:
            out[k_out, 0] = p[0]
            out[k_out, 1] = p[1]
            k_out += 1
        if (fp < 0.0) != (fq < 0.0) and fp != fq and k_out < 8:
            x = p + (q - p) * (fp / (fp - fq))
            out[k_out, 0] = x[0]
            out[k_out, 1] = x[1]
            k_out += 1
    return out, k_out


@ti.func
def _edge(veh: ti.template(), i, e):
    """Edge ``e`` (0-3: foot, top, left, right) of vehicle ``i``'s glass, GLASS_EDGE inside, as the half-plane
    (a, b, c): a y + b v <= c (render/glassmarks.py glass_edges)."""
    top, base_half, slope = veh[i, 6], veh[i, 7], veh[i, 8]
    h = ti.sqrt(1.0 + slope * slope)
    a, b, c = 0.0, -1.0, -GLASS_EDGE
    if e == 1:
        a, b, c = 0.0, 1.0, top - GLASS_EDGE
    elif e == 2:
        a, b, c = 1.0 / h, -slope / h, base_half / h - GLASS_EDGE
    elif e == 3:
        a, b, c = -1.0 / h, -slope / h, base_half / h - GLASS_EDGE
    return a, b, c


@ti.func
def _ribbon(glass: ti.template(), veh: ti.template(), j, i, look):
    """The ribbon of glass row ``j`` (of vehicle ``i``) clipped to its glass: (corners (8, 2) in glass
    coordinates, how many)."""
    g0 = ti.Vector([glass[j, 0], glass[j, 1]])
    g1 = ti.Vector([glass[j, 2], glass[j, 3]])
    mid = 0.5 * (_on_glass(veh, i, g0[0], g0[1]) + _on_glass(veh, i, g1[0], g1[1]))
    eye = ti.Vector([veh[i, _EYE], veh[i, _EYE + 1], veh[i, _EYE + 2]])
    half = look.half_per_m * (mid - eye).norm()
    d = g1 - g0
    across = ti.Vector([-d[1], d[0]]) * (half / d.norm())
    corners = ti.Matrix.rows([g0 - across, g0 + across, g1 + across, g1 - across])
    poly = ti.Matrix.zero(ti.f32, 8, 2)
    for k in ti.static(range(4)):
        for a in ti.static(range(2)):
            poly[k, a] = corners[k, a]
    m = 4
    for e in range(4):  # a loop, not four copies: the kernel compiles in a fraction of the time
        a, b, c = _edge(veh, i, e)
        poly, m = _clip(poly, m, a, b, c)
    return poly, m


@ti.func
def _slot(rows: ti.template(), veh: ti.template(), j, col, first):
    """Row ``j``'s vehicle and its slot among the drawn (-1: not drawn; ``col``: the rows' vehicle column,
    ``first``: VEHICLE_ROW's column of the vehicle's first rank drawn, then its first slot)."""
    i = ti.cast(rows[j, col], ti.i32)
    r = rows[j, col + 1] - veh[i, first]
    slot = -1
    if r >= 0.0:
        slot = ti.cast(veh[i, first + 1] + r, ti.i32)
    return i, slot


@ti.func
def _fan(vbo: ti.template(), row, poly, m, t, veh: ti.template(), i, look):
    """Triangle ``t`` of the fan of ``poly`` (its first ``m`` corners, glass coordinates of vehicle ``i``'s
    windscreen) at vertex ``row``: an empty triangle if the fan has fewer."""
    side = veh[i, _SIDE] * ti.Vector([veh[i, 4], 0.0, veh[i, 5]])
    for c in ti.static(range(3)):
        k = 0 if c == 0 else t + c
        p = ti.Vector([0.0, 0.0, 0.0])
        if t < m - 2:
            p = _place(veh, i, _on_glass(veh, i, poly[k, 0], poly[k, 1]) + side)
        _put(vbo, row + c, p, look.sun, look.glass_rgb)


@ti.kernel
def pose_marks(glass: ti.types.ndarray(dtype=ti.f32, ndim=2), chips: ti.types.ndarray(dtype=ti.f32, ndim=2),
               veh: ti.types.ndarray(dtype=ti.f32, ndim=2), vbo: ti.types.ndarray(dtype=ti.f32, ndim=2),
               blocks: ti.types.ndarray(dtype=ti.i32, ndim=1), polys: ti.types.ndarray(dtype=ti.f32, ndim=2),
               span: Span, look: Look):
    """The marks of ``span`` into ``vbo`` (module docstring); ``blocks[n_blocks]`` gets the count of the fans'
    further triangles; ``polys`` (a row per glass row: 8 corners, their count) keeps the clipped ribbons for them."""
    for j in range(span.nc):
        i, slot = _slot(chips, veh, j, 12, _CHIP)
        if slot >= 0:
            n = ti.Vector([chips[j, 9], chips[j, 10], chips[j, 11]])
            eye = ti.Vector([veh[i, _EYE], veh[i, _EYE + 1], veh[i, _EYE + 2]])
            facing = n.dot(eye - ti.Vector([chips[j, 0], chips[j, 1], chips[j, 2]])) > 0.0 or look.see_through
            for c in range(3):
                p = ti.Vector([0.0, 0.0, 0.0])  # seen from behind its face (the body hides it): empty
                if facing:
                    p = _place(veh, i, ti.Vector([chips[j, 3 * c], chips[j, 3 * c + 1], chips[j, 3 * c + 2]]))
                _put(vbo, 3 * slot + c, p, _turn(veh, i, n), look.chip_rgb)
    n_blocks = (span.ng + BLOCK - 1) // BLOCK
    base = 3 * span.chip_slots
    for b in range(n_blocks):  # each segment's first two triangles; the blocks count the others
        more = 0
        for j in range(b * BLOCK, ti.min((b + 1) * BLOCK, span.ng)):
            i, slot = _slot(glass, veh, j, 4, _GLASS)
            m = 0
            if slot >= 0:
                poly, m = _ribbon(glass, veh, j, i, look)
                for k, a in ti.ndrange(8, 2):  # kept for the further triangles, below
                    polys[j, 2 * k + a] = poly[k, a]
                for t in range(2):
                    _fan(vbo, base + 6 * slot + 3 * t, poly, m, t, veh, i, look)
                more += ti.max(m - 4, 0)
            polys[j, 16] = m
        blocks[b] = more
    ti.loop_config(serialize=True)
    for _ in range(1):  # where each block's further triangles go: the counts added up, in order
        total = 0
        for b in range(n_blocks):
            more = blocks[b]
            blocks[b] = total
            total += more
        blocks[n_blocks] = total
    for b in range(n_blocks):
        row = base + 6 * span.glass_slots + 3 * blocks[b]
        for j in range(b * BLOCK, ti.min((b + 1) * BLOCK, span.ng)):
            m = ti.cast(polys[j, 16], ti.i32)
            if m > 4:
                i = ti.cast(glass[j, 4], ti.i32)
                poly = ti.Matrix.zero(ti.f32, 8, 2)
                for k, a in ti.ndrange(8, 2):
                    poly[k, a] = polys[j, 2 * k + a]
                for t in range(2, m - 2):
                    _fan(vbo, row, poly, m, t, veh, i, look)
                    row += 3


@ti.kernel
def _put_rows(dst: ti.types.ndarray(dtype=ti.f32, ndim=2), src: ti.types.ndarray(dtype=ti.f32, ndim=2),
              start: ti.i32):
    """Rows ``src`` into ``dst`` from row ``start`` on (from the host, or a table's rows into a larger one)."""
    for r, c in ti.ndrange(src.shape[0], src.shape[1]):
        dst[start + r, c] = src[r, c]


class _Device:
    """A table of the store on the device: a float32 ndarray of ``width`` columns, grown in powers of two;
    ``n`` rows hold the store's."""

    def __init__(self, width: int):
        self.width, self.n, self.arr = width, 0, ti.ndarray(ti.f32, (64, width))

    def sync(self, rows: np.ndarray, changed: int) -> None:
        """Hold ``rows`` (the store's table), of which those before ``changed`` are held already."""
        start = min(self.n, changed)
        if len(rows) > self.arr.shape[0]:  # grown: the rows held move to a larger array on the device
            cap = self.arr.shape[0]
            while cap < len(rows):
                cap *= 2
            old, self.arr = self.arr, ti.ndarray(ti.f32, (cap, self.width))
            _put_rows(self.arr, old, 0)
        if len(rows) > start:
            _put_rows(self.arr, np.ascontiguousarray(rows[start:], np.float32), start)
        self.n = len(rows)


class MarkMesh:
    """The marks of a :class:`~.markstore.MarkStore` on the device, and their GGUI mesh (see the module
    docstring); ``cabins`` and ``bounds`` (per vehicle: a sphere round its body, centre (3,) and radius, body
    frame) are the vehicles'."""

    def __init__(self, cabins, bounds):
        self.glass, self.chips = _Device(len(GLASS_ROW)), _Device(len(CHIP_ROW))
        self.veh = np.zeros((max(len(cabins), 1), len(VEHICLE_ROW)), np.float32)
        for i, cab in enumerate(cabins):
            self.veh[i, :_G] = glass_frame(cab)
        self.bounds = bounds
        self.identity = host_buffer((1, 4, 4), "marks")
        self.identity[0] = np.eye(4, dtype=np.float32)
        self._spill = 3 * BLOCK  # vertices kept for the fans' further triangles (grows with them)
        self._blocks = np.zeros(0, np.int32)  # per block of glass segments, its fans' further triangles
        self._scratch = None  # the clipped ribbons, between the kernel's passes
        self.drawn = 0  # vertices of the last mesh drawn

    def upload(self, store) -> None:
        """Copy the rows ``store`` made since the last call to the device."""
        g, c = store.changed_from()
        self.glass.sync(store.glass.rows, g)
        self.chips.sync(store.chips.rows, c)

    def draw(self, scene, shown, pos, head, sight: Sight) -> int:
        """Declare the marks ``shown`` (render/markstore.py Shown) in GGUI ``scene``, the vehicles at ``pos``
        (N, 3, local) with headings ``head`` (N,), seen as ``sight`` says. Return the vertices drawn."""
        glass_n, chip_n = self._place(shown, pos, head, sight)
        self.drawn = 0
        if not glass_n and not chip_n:
            return 0
        span = Span(ng=shown.glass, nc=shown.chips, glass_slots=glass_n, chip_slots=chip_n)
        lit = np.array(MARK_COLOR) / (np.array(AMBIENT) + np.array(SUN_COLOR))  # facing the sun: MARK_COLOR
        look = Look(half_per_m=0.5 * MARK_PX / float(sight.px_per_rad), sun=ti.Vector([float(x) for x in sight.sun]),
                    glass_rgb=ti.Vector([float(x) for x in lit]), chip_rgb=ti.Vector(PAINT_CHIP_COLOR),
                    see_through=int(bool(sight.see_through)))
        n_blocks = (shown.glass + BLOCK - 1) // BLOCK
        if len(self._blocks) <= n_blocks:
            self._blocks = np.zeros(_capacity(n_blocks + 1), np.int32)
        while True:
            vbo = host_buffer((_capacity(3 * chip_n + 6 * glass_n + self._spill), VBO_STRIDE), "marks")
            pose_marks(self.glass.arr, self.chips.arr, self.veh, vbo, self._blocks, self._polys(shown.glass), span,
                       look)
            n = 3 * chip_n + 6 * glass_n + 3 * int(self._blocks[n_blocks])
            if n <= len(vbo):
                break
            self._spill = max(2 * self._spill, n - 3 * chip_n - 6 * glass_n)
        self.drawn = n
        declare_mesh(scene, vbo[:n], self.identity)
        return n

    def _polys(self, n: int):
        """The kernel's room for ``n`` clipped ribbons (a device array as large as the glass table's)."""
        if self._scratch is None or self._scratch.shape[0] < max(n, 1):
            self._scratch = ti.ndarray(ti.f32, (self.glass.arr.shape[0], 17))
        return self._scratch

    def _place(self, shown, pos, head, sight) -> tuple:
        """Fill the vehicles' rows (VEHICLE_ROW) for this frame: their poses, the eye in each one's body frame,
        the side of the glass its marks lie on, and which of its rows are drawn where (none of a vehicle out of
        view, nor of a windscreen seen from behind, which the cabin hides; at most MAX_SEGMENTS and
        MAX_CHIP_TRIANGLES, the newest); return the glass and chip slots drawn."""
        v, k = self.veh, min(len(pos), len(self.veh), len(shown.glass_of))
        c, s = np.cos(head[:k]), np.sin(head[:k])
        e = np.asarray(sight.eye, np.float64)[None] - pos[:k]
        eye = np.stack([c * e[:, 0] + s * e[:, 1], -s * e[:, 0] + c * e[:, 1], e[:, 2]], 1)  # body frames
        v[:k, _G:_G + 2] = np.stack([c, s], 1)
        v[:k, _G + 2:_G + 5] = pos[:k]
        v[:k, _EYE:_EYE + 3] = eye
        inside = np.arange(k) == (-1 if sight.inside is None else sight.inside)
        v[:k, _SIDE] = np.where(inside, -GLASS_GAP, GLASS_GAP)
        seen = self._in_view(pos[:k], c, s, sight) | sight.see_through
        # the windscreen's outer side faces the eye (or the eye is in its cabin): else the cabin hides the marks
        front = (eye[:, 0] - v[:k, 0]) * v[:k, 4] + (eye[:, 2] - v[:k, 1]) * v[:k, 5] > 0.0
        glass = np.where(seen & (front | inside | sight.see_through), np.minimum(shown.glass_of[:k], MAX_SEGMENTS), 0)
        chips = np.where(seen, np.minimum(shown.chips_of[:k], MAX_CHIP_TRIANGLES), 0)
        for col, drawn, of in ((_GLASS, glass, shown.glass_of[:k]), (_CHIP, chips, shown.chips_of[:k])):
            v[:k, col] = np.where(drawn > 0, of - drawn, HIDDEN)
            v[:k, col + 1] = np.cumsum(drawn) - drawn
        return int(glass.sum()), int(chips.sum())

    def _in_view(self, pos, c, s, sight) -> np.ndarray:
        """Per vehicle: may its body's sphere be in the camera's view?"""
        if self.bounds is None:
            return np.ones(len(pos), bool)
        centre, radius = self.bounds[0][:len(pos)], self.bounds[1][:len(pos)]
        d = pos + np.stack([c * centre[:, 0] - s * centre[:, 1], s * centre[:, 0] + c * centre[:, 1],
                            centre[:, 2]], 1) - np.asarray(sight.eye, np.float64)
        z, x, y = d @ np.asarray(sight.fwd, np.float64), d @ np.asarray(sight.right, np.float64), \
            d @ np.asarray(sight.up, np.float64)
        sec_x, sec_y = np.hypot(1.0, sight.tan_x), np.hypot(1.0, sight.tan_y)
        return (z > -radius) & (np.abs(x) < z * sight.tan_x + radius * sec_x) & \
            (np.abs(y) < z * sight.tan_y + radius * sec_y)


def body_bounds(vehicles) -> tuple:
    """Per vehicle of ``vehicles`` (the scene's specs): the centre (N, 3) and radius (N,) of a sphere round
    its body's parts (motion/bodies.py; body frame), where its marks lie, 5 cm to spare."""
    centres, radii = [], []
    for spec in vehicles:
        c = np.concatenate([part.corners() for part in body_parts(spec, 0.0).parts])
        mid = 0.5 * (c.min(axis=0) + c.max(axis=0))
        centres.append(mid)
        radii.append(np.linalg.norm(c - mid, axis=1).max() + 0.05)
    return np.array(centres).reshape(-1, 3), np.array(radii)


def _capacity(n: int) -> int:
    """The power of two from 1024 that holds ``n``."""
    cap = 1024
    while cap < n:
        cap *= 2
    return cap
