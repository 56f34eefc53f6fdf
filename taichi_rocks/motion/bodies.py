"""Vehicle body shapes, host side (NumPy): the few convex parts of each kind's body, which the renderer draws
(render/bodies.py) and flying stones hit (engine/impacts.py), and the body part each of their faces stands for.

Body frame: x forward, y left, z up, origin at the body centre on the ground. The body (length x width, from
0.8 tire radius up to that plus ``height``) is shaped by its kind (:func:`vehicle_kind`):
  car    lower body, a glazed cabin (a frustum: windows sloping in to the roof), front and rear bumpers;
  van    lower body, a tall upper body glazed at the front (a sloping windscreen) behind a short bonnet, bumpers;
  truck  chassis, a cab (lower part, glazed upper part), a cargo box behind it, bumpers.
Each part is a box (``center``, ``size``: exactly what the renderer's ``box`` draws) or a frustum between two
horizontal rectangles centred on y = 0 (``bottom``, ``top`` = (x0, x1, half width) at ``z0``, ``z1``): both are
convex hexahedra of 8 corners (:meth:`Part.corners`) with planar faces (:data:`FACES`). The wheel wells the
renderer cuts round the wheels are filled in the collision hull (the wheels fill them).

A hit's part label comes from the face it meets (the face whose outward normal is closest to the contact
normal, so an edge or corner hit takes the face it leans to) and, for faces that stand for two parts (a car's
lower-body top: bonnet ahead of the cabin, boot behind it), the contact point's x (:meth:`Part.label`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config.keys import choices

__all__ = ["KINDS", "LABELS", "FACES", "FACE_CORNERS", "EDGES", "GAP", "EPS", "Part", "Body", "vehicle_kind",
           "body_parts", "inner_width", "hexahedron_planes", "label_table"]

KINDS = tuple(k for k in choices("vehicle.kind") if k != "auto")  # the bodies drawn and hit
# What a hit is on. front_bumper: the front below the bonnet or windscreen (bumper, grille, lights); bonnet: the
# top ahead of the windscreen; roof: top surfaces above the glass (and a truck's box above its cab); rear: the
# back, the rear window and a car's boot lid; underbody: the bottom faces.
LABELS = ("front_bumper", "bonnet", "windscreen", "roof", "side", "rear", "underbody")
FACES = ("front", "back", "left", "right", "top", "bottom")  # outward +x, -x, +y, -y, +z, -z
# Corners: the bottom rectangle (z0) then the top one (z1), each (x0, -y), (x1, -y), (x1, +y), (x0, +y).
FACE_CORNERS = ((1, 2, 6, 5), (0, 3, 7, 4), (3, 2, 6, 7), (0, 1, 5, 4), (4, 5, 6, 7), (0, 1, 2, 3))
EDGES = ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7))
GAP = 0.04  # m between a wheel and its well
EPS = 0.01  # m: pieces that touch overlap this much (their touching faces hidden inside)


@dataclass(frozen=True)
class Part:
    """One convex part of a body. ``shape`` "box": ``dims`` = (center, size); "frustum": ``dims`` = (bottom,
    top, z0, z1). ``bounds`` (x0, x1, half width, z0, z1): the numbers a box centred on y = 0 was made from.
    ``labels[f]``: the label (:data:`LABELS`) of a hit on face f (:data:`FACES`), or ``behind[f]`` where the
    contact point's x < ``split``."""

    name: str
    shape: str
    dims: tuple
    labels: tuple
    behind: tuple
    split: float = -math.inf
    bounds: tuple | None = None

    def corners(self) -> np.ndarray:
        """(8, 3) float64 corners, computed as the renderer computes its vertices: the bottom rectangle (z0),
        then the top one, each (x0, -y), (x1, -y), (x1, +y), (x0, +y)."""
        if self.shape == "box":
            (cx, cy, cz), size = self.dims
            hx, hy, hz = (s / 2 for s in size)
            x0, x1, y0, y1, z0, z1 = cx - hx, cx + hx, cy - hy, cy + hy, cz - hz, cz + hz
            lo = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)]
            hi = [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
        else:
            (a0, a1, ay), (b0, b1, by), z0, z1 = self.dims
            lo = [(a0, -ay, z0), (a1, -ay, z0), (a1, ay, z0), (a0, ay, z0)]
            hi = [(b0, -by, z1), (b1, -by, z1), (b1, by, z1), (b0, by, z1)]
        return np.array(lo + hi, np.float64)

    def label(self, face: int, x: float) -> str:
        """The label of a hit on face ``face`` (index into :data:`FACES`) at body-frame x ``x``."""
        return self.behind[face] if x < self.split else self.labels[face]


@dataclass(frozen=True)
class Body:
    """A vehicle's body: its kind, the height of its underside (m) and its parts."""

    kind: str
    floor: float
    parts: tuple

    def part(self, name: str) -> Part:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(f"no part {name!r} in a {self.kind} body")


def vehicle_kind(spec) -> str:
    """"truck", "van" or "car": the vehicle's ``kind``, or for "auto" (and specs without one) from its
    proportions."""
    kind = getattr(spec, "kind", "auto")
    if kind in KINDS:
        return kind
    L, H = float(spec.length), float(spec.height)
    if H >= 2.6 or L >= 6.5:
        return "truck"
    if H >= 1.75:
        return "van"
    return "car"


def inner_width(spec) -> float:
    """m: the width of the body between the wheels (a truck's chassis; the inner part of a wheel well)."""
    return max(float(spec.track) - float(spec.tire_width) - 0.06, 0.3 * float(spec.width))


def _labels(front, back, side, top, bottom="underbody"):
    return (front, back, side, side, top, bottom)


def _span(name, x0, x1, y, z0, z1, labels, width=None, **kw) -> Part:
    """A box from x0 to x1 and z0 to z1, ``width`` wide (default 2 y) and centred on y = 0."""
    w = 2.0 * y if width is None else width
    return Part(name, "box", (((x0 + x1) / 2, 0.0, (z0 + z1) / 2), (x1 - x0, w, z1 - z0)), labels,
                kw.pop("behind", labels), bounds=(x0, x1, w / 2, z0, z1), **kw)


def _frustum(name, bottom, top, z0, z1, labels) -> Part:
    return Part(name, "frustum", (bottom, top, z0, z1), labels, labels)


def _bumpers(spec, z0) -> list:
    """Front and rear bumpers, proud of the body."""
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    bump_h = min(0.18, 0.12 * H)
    front, rear = ("front_bumper",) * 6, ("rear",) * 6
    return [Part(name, "box", ((sx * (L / 2 + 0.02), 0.0, z0 - 0.01 + bump_h / 2), (0.08, 1.02 * W, bump_h)),
                 lab, lab) for name, sx, lab in (("front_bumper", 1.0, front), ("rear_bumper", -1.0, rear))]


def _car(spec, z0) -> list:
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    top = z0 + 0.5 * H
    cabin = ((-0.33 * L, 0.22 * L, 0.43 * W), (-0.24 * L, 0.06 * L, 0.39 * W), top - EPS, z0 + H)
    return [_span("lower", -L / 2, L / 2, W / 2, z0, top, _labels("front_bumper", "rear", "side", "bonnet"),
                  behind=_labels("front_bumper", "rear", "side", "rear"), split=0.5 * (cabin[0][0] + cabin[0][1])),
            _frustum("cabin", *cabin, _labels("windscreen", "rear", "side", "roof"))]


def _van(spec, z0) -> list:
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    top = z0 + 0.45 * H
    xf1 = L / 2 - 0.2 * L  # the upper body: glazed front part [xf0, xf1], closed rear part [-L/2, xf0]
    xf0 = xf1 - 0.25 * L
    return [_span("lower", -L / 2, L / 2, W / 2, z0, top, _labels("front_bumper", "rear", "side", "bonnet")),
            _frustum("glazed", (xf0, xf1, 0.485 * W), (xf0, xf1 - 0.1 * L, 0.485 * W), top - EPS, z0 + H,
                     _labels("windscreen", "rear", "side", "roof")),
            _span("upper", -L / 2, xf0, 0.0, top - EPS, z0 + H, _labels("windscreen", "rear", "side", "roof"),
                  width=0.97 * W)]


def _truck(spec, z0) -> list:
    L, W, H, R = float(spec.length), float(spec.width), float(spec.height), float(spec.tire_radius)
    inner = inner_width(spec)
    chassis_top = max(z0 + 0.22 * H, 2.0 * R + GAP)
    cab_l = min(2.2, 0.3 * L)
    cab_top = z0 + 0.78 * H
    mid = 0.5 * (chassis_top + cab_top)
    box_x1 = L / 2 - cab_l - 0.15
    return [_span("chassis", -L / 2, L / 2, 0.0, z0, chassis_top, _labels("front_bumper", "rear", "side", "roof"),
                  width=inner),
            _span("cab", L / 2 - cab_l, L / 2, W / 2, chassis_top - EPS, mid,
                  _labels("front_bumper", "rear", "side", "roof")),
            _span("cab_glass", L / 2 - cab_l + 0.005, L / 2 - 0.005, W / 2, mid - EPS, cab_top,
                  _labels("windscreen", "rear", "side", "roof"), width=W - 0.006),
            _span("cargo", -L / 2, box_x1, W / 2, chassis_top - EPS, z0 + H, _labels("roof", "rear", "side", "roof"))]


def body_parts(spec, ground_z: float = 0.0) -> Body:
    """The body of vehicle ``spec`` (a scene's [[vehicle]]: length, width, height, tire sizes, kind), its parts
    in the body frame on ground ``ground_z``: the kind's parts, then the front and rear bumpers."""
    z0 = ground_z + 0.8 * float(spec.tire_radius)
    kind = vehicle_kind(spec)
    build = {"car": _car, "van": _van, "truck": _truck}[kind]
    return Body(kind, z0, tuple(build(spec, z0) + _bumpers(spec, z0)))


def hexahedron_planes(corners) -> np.ndarray:
    """(6, 4) outward face planes (unit normal n, offset d: n . x <= d inside) of a convex hexahedron given by its
    8 corners in :meth:`Part.corners` order (faces in :data:`FACES` order). Raises ValueError if a face is not planar
    or the solid is not convex."""
    c = np.asarray(corners, np.float64)
    centre = c.mean(axis=0)
    size = float(np.ptp(c, axis=0).max())
    scale = size + float(np.abs(c).max())  # rounding grows with the coordinates, not only with the size
    out = np.empty((6, 4))
    for f, idx in enumerate(FACE_CORNERS):
        q = c[list(idx)]
        n = np.cross(q[2] - q[0], q[3] - q[1])  # the diagonals: robust for a trapezoid or a thin face
        norm = np.linalg.norm(n)
        if norm <= 1e-12 * size * size:
            raise ValueError(f"face {FACES[f]} of the hexahedron is degenerate")
        n /= norm
        if n @ (q.mean(axis=0) - centre) < 0:
            n = -n
        d = float(n @ q.mean(axis=0))
        if np.max(np.abs(q @ n - d)) > 1e-9 * scale:
            raise ValueError(f"face {FACES[f]} of the hexahedron is not planar")
        out[f, :3], out[f, 3] = n, d
    if np.max(c @ out[:, :3].T - out[:, 3]) > 1e-9 * scale:
        raise ValueError("the hexahedron is not convex")
    return out


def label_table(parts) -> tuple[np.ndarray, np.ndarray]:
    """The parts' labels as indices into :data:`LABELS`: (P, 6, 2) int32 (label ahead, label behind per face)
    and (P,) float64 splits (x below which the label behind applies), for a device to look hits up in."""
    idx = np.array([[[LABELS.index(p.labels[f]), LABELS.index(p.behind[f])] for f in range(6)] for p in parts],
                   np.int32).reshape(-1, 6, 2)
    return idx, np.array([p.split for p in parts], np.float64)
