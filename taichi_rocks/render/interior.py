"""A vehicle seen from its own driver's seat, host side (NumPy, no Taichi): which faces of its body mesh hide
the view from inside, and the windscreen's frame drawn in their place.

The body (render/bodies.py) is a set of closed pieces with opaque glass: a camera in the cabin would see the
inside of the glass and the roof. From the inside, the pieces above the belt line over the cabin (the
greenhouse: windows, the roof and its stripes, a van's or a truck cab's upper part) are left out, and the
windscreen's frame is drawn from the same cabin dimensions (motion/cabin.py): the A-pillars along the
windscreen's sides, the roof's front edge (the header) and the roof's lining behind it, the dashboard in
front of the driver and the cabin's floor at the belt line (in the interior's colour, not the paint's). What
stays of the body (the bonnet, the doors' tops, the wheels) is drawn as from outside.

The dashboard's top stays below the line from the driver's eye over the bonnet's front edge, so it never
hides what the bonnet does not: the road and the vehicle ahead stay in view (a pixel test checks that in a
drawn frame); and it stays behind the glass (a sloping windscreen leans back over the dashboard's far edge).
The pillars and the header are beams of rectangular section lying just inside the glass.

Cost. The eye is fixed in the body frame, so what it can see of its own vehicle is decided once: GGUI 1.7.4
draws both sides of every triangle (checked), so the faces turned away from the eye (closed pieces: hidden by
their front faces) and the wheels (under the bonnet and the floor) are left out as well, and the rest is
drawn nearest first, so that the depth test rejects what lies behind the dashboard and the bonnet before it
is shaded: on lavapipe GGUI's cost grows with the pixels it shades, and from the driver's seat the vehicle's
own surfaces cover a third of the image.
"""

from __future__ import annotations

import numpy as np

from ..motion.cabin import cabin_of
from .looks import DASHBOARD_COLOR, HEADLINER_COLOR, PILLAR_COLOR
from .meshes import VehicleMesh, box, merge, quad

__all__ = ["Interior", "interior_of", "hidden_from_inside", "windscreen_frame", "frame_solids"]

PILLAR = 0.04  # A-pillar width, in vehicle widths (7 cm for a 1.8 m car)
HEADER = 0.08  # the roof's front edge: its height down the windscreen, in its height
DASH_DEPTH = 0.08  # the dashboard's depth behind the windscreen's foot, in lengths
DASH_RISE = 0.5  # the dashboard's height, in the room below the eye's line over the bonnet's front edge
INSET = 0.006  # m: the frame stands this far inside the glass (no shared planes: see render/meshes.py)


class Interior:
    """One vehicle's mesh with its windscreen frame appended (``mesh``: the body mesh's vertices, then the
    frame's, owned by the body) and two sets of its triangles (per triangle, bool): ``outside`` (the body as
    always drawn) and ``inside`` (the view from its cabin: the greenhouse, the wheels and the faces turned away
    from ``eye`` left out, the frame in), drawn nearest to the eye first."""

    def __init__(self, mesh: VehicleMesh, outside: np.ndarray, inside: np.ndarray, eye):
        self.mesh, self.outside, self.inside = mesh, outside, inside
        tri = mesh.verts[mesh.idx.reshape(-1, 3)]
        near = np.linalg.norm(tri.mean(axis=1) - np.asarray(eye, np.float64), axis=1)
        sel = np.flatnonzero(inside)
        self.order = sel[np.argsort(near[sel], kind="stable")]

    def triangles(self, inside: bool) -> np.ndarray:
        """The mesh's indices of the triangles drawn from inside (nearest the eye first) or from outside, (3 T,)."""
        tri = self.mesh.idx.reshape(-1, 3)
        return tri[self.order if inside else np.flatnonzero(self.outside)].reshape(-1)


def hidden_from_inside(mesh: VehicleMesh, cab) -> np.ndarray:
    """Per triangle of ``mesh``: True if it is part of the greenhouse over the cabin of ``cab`` (a body
    triangle whose centre lies above the belt line and between the cabin's back and the windscreen's foot)."""
    tri = mesh.verts[mesh.idx.reshape(-1, 3)]
    c = tri.mean(axis=1)
    body = mesh.triangle_owner() < 0
    back = min(cab.back_x, cab.back_top_x) - 0.01
    return body & (c[:, 2] > cab.belt + 1e-3) & (c[:, 0] >= back) & (c[:, 0] <= cab.base_x + 0.01)


def _beam_axes(a, b, side) -> tuple:
    """A beam's unit axes: along it (a to b), across it towards ``side``, and their normal."""
    u = (b - a) / np.linalg.norm(b - a)
    v = np.asarray(side, np.float64) - (np.asarray(side, np.float64) @ u) * u
    v /= np.linalg.norm(v)
    return u, v, np.cross(u, v)


def _beam(a, b, side, width: float, depth: float, color):
    """A straight beam from ``a`` to ``b`` (3-vectors), ``width`` across towards ``side`` (a unit vector
    roughly perpendicular to b - a) and ``depth`` deep along their normal: a box of 6 flat faces."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    u, v, n = _beam_axes(a, b, side)
    corners = [p + dv * width * v + dn * depth * n for dn in (-0.5, 0.5) for dv in (0.0, 1.0) for p in (a, b)]
    c = np.array(corners)  # index: 4 * dn + 2 * dv + end
    faces = [((0, 1, 3, 2), -n), ((4, 5, 7, 6), n), ((0, 1, 5, 4), -v), ((2, 3, 7, 6), v), ((0, 2, 6, 4), -u),
             ((1, 3, 7, 5), u)]
    return merge([quad(c[list(f)], normal, color) for f, normal in faces])


def _frame_parts(cab) -> list:
    """The windscreen's frame of cabin ``cab`` as parts (body frame), each once for its mesh and its solid:
    ("beam", a, b, side, width, depth, colour), ("quad", corners, normal, colour) or ("box", centre, size,
    colour): the two A-pillars, the header with the roof's lining behind it, the dashboard and the floor."""
    W = cab.width
    pillar, colour = PILLAR * W, np.array(PILLAR_COLOR)
    header = HEADER * (cab.roof - cab.belt)
    parts = []
    for s in (1.0, -1.0):
        foot = (cab.base_x - INSET, s * (cab.base_half - INSET), cab.belt)
        head = (cab.top_x - INSET, s * (cab.top_half - INSET), cab.roof - INSET)
        parts.append(("beam", foot, head, (0.0, -s, 0.0), pillar, 2.0 * INSET, colour))
    top = cab.top_x - INSET
    slope = (cab.top_x - cab.base_x) / (cab.roof - cab.belt)  # dx per dz down the windscreen
    parts.append(("beam", (top, -cab.top_half, cab.roof - INSET), (top, cab.top_half, cab.roof - INSET),
                  (-slope * header, 0.0, -header), header, 2.0 * INSET, colour))
    back = cab.back_top_x + 0.02
    lining = [(back, -cab.top_half, cab.roof - 2 * INSET), (top, -cab.top_half, cab.roof - 2 * INSET),
              (top, cab.top_half, cab.roof - 2 * INSET), (back, cab.top_half, cab.roof - 2 * INSET)]
    parts.append(("quad", lining, (0.0, 0.0, -1.0), HEADLINER_COLOR))
    parts.append(("box", *_dashboard(cab), DASHBOARD_COLOR))
    floor = cab.belt + INSET  # the cabin's floor at the belt line, in the interior's colour (not the paint's)
    x0, x1 = cab.back_x + 0.02, cab.base_x - DASH_DEPTH * cab.length
    half = 0.98 * cab.half_inside
    parts.append(("quad", [(x0, -half, floor), (x1, -half, floor), (x1, half, floor), (x0, half, floor)],
                  (0.0, 0.0, 1.0), DASHBOARD_COLOR))
    return parts


def windscreen_frame(cab):
    """The frame of the windscreen of cabin ``cab`` seen from inside (one mesh, body frame): the two A-pillars,
    the header with the roof's lining behind it, the dashboard and the floor."""
    meshes = []
    for kind, *args in _frame_parts(cab):
        if kind == "beam":
            meshes.append(_beam(*args))
        elif kind == "quad":
            meshes.append(quad(*args))
        else:
            centre, size, colour = args
            meshes.append(box(centre, size, {k: np.array(colour) for k in ("+x", "-x", "+y", "-y", "+z")}))
    return merge(meshes)


def frame_solids(cab) -> np.ndarray:
    """The parts of the windscreen's frame of cabin ``cab`` (body frame) as solids the dust's drawing casts
    rays at (render/dust.py): (K, 4, 3), each a corner and its three edges (a parallelepiped; a quad gets the
    frame's depth, 2 INSET, centred on it)."""
    out = []
    for kind, *args in _frame_parts(cab):
        if kind == "beam":
            a, b, side, width, depth, _ = args
            a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
            _, v, n = _beam_axes(a, b, side)
            out.append((a - 0.5 * depth * n, b - a, width * v, depth * n))
        elif kind == "quad":
            corners, normal, _ = args
            c, n = np.asarray(corners, np.float64), np.asarray(normal, np.float64)
            out.append((c[0] - INSET * n, c[1] - c[0], c[3] - c[0], 2.0 * INSET * n))
        else:
            centre, size, _ = args
            half = 0.5 * np.asarray(size, np.float64)
            out.append((np.asarray(centre, np.float64) - half, *np.diag(2.0 * half)))
    return np.array([np.stack(s) for s in out])


def _dashboard(cab) -> tuple:
    """The (centre, size) of a box across the cabin in front of the driver, its top (up to its far edge) below the eye's line over
    the bonnet's front, and its far edge INSET behind the glass at the top's height (a sloping windscreen leans
    back over it: a box up to the glass's foot would poke through the glass, in front of the marks on it)."""
    eye = cab.eye
    depth = DASH_DEPTH * cab.length
    x0, x1 = cab.base_x - depth, cab.base_x - INSET
    reach = max(cab.front_x - eye[0], 1e-3)  # the eye to the front edge of the bonnet (or the cab)
    sight = (eye[2] - cab.bonnet_z) / reach  # the line over that edge drops this much per metre
    room = eye[2] - sight * (x1 - eye[0]) - cab.belt  # up to the line at the far edge (it rises highest)
    height = max(DASH_RISE * room, 0.02)
    height = min(height, 0.5 * (cab.roof - cab.belt))
    x1 = min(x1, cab.windscreen_x(cab.belt + height) - INSET)  # nearer the eye the line is higher: still below
    x0 = min(x0, x1 - 0.02)
    half = 0.98 * min(cab.base_half, cab.half_inside)
    return ((x0 + x1) / 2, 0.0, cab.belt + height / 2 - 0.002), (x1 - x0, 2 * half, height)


def interior_of(spec, mesh: VehicleMesh, ground_z: float = 0.0) -> Interior:
    """Vehicle ``spec``'s ``mesh`` (render/bodies.py vehicle_mesh) with its windscreen frame, and which of its
    triangles are drawn from outside and from inside (:class:`Interior`)."""
    cab = cabin_of(spec, ground_z)
    fv, fn, fc, fi = windscreen_frame(cab)
    n_tri = len(mesh.idx) // 3
    hidden = hidden_from_inside(mesh, cab)
    ext = VehicleMesh(np.concatenate([mesh.verts, fv]), np.concatenate([mesh.norms, fn]),
                      np.concatenate([mesh.cols, fc]), np.concatenate([mesh.idx, fi + len(mesh.verts)]),
                      np.concatenate([mesh.wheel, np.full(len(fv), -1)]), mesh.centres, mesh.rear)
    frame = np.ones(len(fi) // 3, bool)
    outside = np.concatenate([np.ones(n_tri, bool), ~frame])
    eye = np.array(cab.eye)
    tri = ext.verts[ext.idx.reshape(-1, 3)]
    facing = np.einsum("ij,ij->i", ext.norms[ext.idx[0::3]], tri.mean(axis=1) - eye) < 0.0
    body = np.concatenate([mesh.triangle_owner() < 0, frame])
    inside = np.concatenate([~hidden, frame]) & facing & body
    return Interior(ext, outside, inside, eye)
