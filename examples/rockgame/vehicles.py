"""The vehicles drawn: each body from its parts in motion/bodies.py (the same convex hexahedra the stones hit),
flat-shaded and lit by the sun, glazed parts dark glass, four wheels that turn with the distance driven (the
front pair steers); and for the player, the inside of its cabin seen from the driver's seat (motion/cabin.py: a
dashboard under the windscreen, the pillars and the roof's lining round it).

Body frame: x forward, y left, z up, origin at the body centre on the ground; a vehicle's node is placed at its
pose (heading h about z: the body's x points along (cos h, sin h)).
"""

from __future__ import annotations

import math

import numpy as np
from panda3d.core import NodePath, TransparencyAttrib

from taichi_rocks.motion.bodies import EPS, GAP, body_parts, inner_width
from taichi_rocks.motion.cabin import cabin_of

from .meshes import card, cylinder, hexahedron, rgba, texture_rgba, triangles, vertex_view
from .rocks import SUN

GLASS = (0.24, 0.31, 0.40)
TIRE, HUB = (0.09, 0.09, 0.10), (0.62, 0.62, 0.64)
BUMPER = (0.13, 0.13, 0.14)
TAIL, HEAD = (1.0, 0.30, 0.22), (0.98, 0.96, 0.85)
STRIPE = (0.97, 0.97, 0.95)  # the player's stripes
PILLAR, HEADLINER, DASHBOARD = (0.30, 0.30, 0.32), (0.62, 0.61, 0.58), (0.22, 0.22, 0.24)
PROUD = 0.004  # m: lights and stripes stand this far off the surface they are on
AMBIENT, DIFFUSE = 0.55, 0.5  # the vehicles' light: sky and sun
LIGHT_STEP = math.radians(0.5)  # a vehicle's colours are lit again when it has turned this much
SHADOW_Z = 0.07  # m: a shadow lies on the pebbles' tops (they stand up to ~6 cm)
SHADOW_RIM = 0.6  # m: how far a shadow fades out beyond the body
FACE = {"front": 0, "back": 1, "left": 2, "right": 3, "top": 4, "bottom": 5}


def _box(x0, x1, y0, y1, z0, z1) -> np.ndarray:
    """The 8 corners of an axis-aligned box in motion/bodies.py Part.corners order."""
    return np.array([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                     (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], np.float64)


def _span(x0, x1, half, z0, z1) -> np.ndarray:
    return _box(x0, x1, -half, half, z0, z1)


def _colours(base, **faces) -> np.ndarray:
    """(6, 4) bytes: ``base`` on every face but those named (front, back, left, right, top, bottom)."""
    out = np.array([rgba(base)] * 6)
    for name, c in faces.items():
        out[FACE[name]] = rgba(c)
    return out


def _lower_body(spec, part, colour) -> list:
    """The lower body cut round each wheel: an inner part (between the wheels) up to a fender above the wheel."""
    x_lo, x_hi, hw, z_bot, z_top = part.bounds
    R = float(spec.tire_radius)
    inner = 0.5 * inner_width(spec)
    wells = sorted((max(x - R - GAP, x_lo), min(x + R + GAP, x_hi))
                   for x in (0.5 * float(spec.wheelbase), -0.5 * float(spec.wheelbase)))
    out, cur = [], x_lo
    for a, b in wells:
        if a > cur:
            out.append((_span(cur, a, hw, z_bot, z_top), _colours(colour)))
        cur = max(cur, b)
    if cur < x_hi:
        out.append((_span(cur, x_hi, hw, z_bot, z_top), _colours(colour)))
    fender = 2.0 * R + GAP
    for a, b in wells:
        a, b = max(a - EPS, x_lo), min(b + EPS, x_hi)
        out.append((_span(a, b, inner, z_bot + 0.005, min(fender + EPS, z_top - 0.005)), _colours(colour)))
        if fender < z_top - 0.01:
            out.append((_span(a, b, hw - 0.003, fender, z_top - 0.005), _colours(colour)))
    return out


def body_pieces(spec, body, player: bool) -> list:
    """(corners, face colours) of everything drawn of a body: its parts (wheel wells cut), glass, bumpers, lights,
    and the player's stripes."""
    col = np.asarray(spec.color, np.float64)
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    out = []
    if body.kind in ("car", "van"):
        out += _lower_body(spec, body.part("lower"), col)
        glazed = body.part("cabin" if body.kind == "car" else "glazed")
        glass = dict(front=GLASS, left=GLASS, right=GLASS, back=GLASS if body.kind == "car" else col * 0.95)
        out.append((glazed.corners(), _colours(col * 0.95, **glass)))
        if body.kind == "van":
            out.append((body.part("upper").corners(), _colours(col * 0.95)))
    else:
        chassis, cargo = body.part("chassis"), body.part("cargo")
        out.append((chassis.corners(), _colours(np.array(TIRE) * 2)))
        out.append((body.part("cab").corners(), _colours(col)))
        out.append((body.part("cab_glass").corners(), _colours(col, front=GLASS, left=GLASS, right=GLASS)))
        light = np.clip(col * 1.08 + 0.04, 0, 1)
        out.append((cargo.corners(), _colours(light, back=col * 0.8)))
        x_back, _, _, z_c, roof = cargo.bounds
        for y in (-0.25 * W, 0.0, 0.25 * W):  # the doors' lines
            out.append((_box(x_back - PROUD - 0.008, x_back - PROUD, y - 0.015, y + 0.015, z_c + 0.1, roof - 0.1),
                        _colours(BUMPER)))
        for side in (1.0, -1.0):  # mud flaps behind the rear wheels
            x = -0.5 * float(spec.wheelbase) - 1.1 * float(spec.tire_radius)
            y = side * 0.5 * float(spec.track)
            out.append((_box(x - 0.02, x, y - 0.2, y + 0.2, 0.12, body.floor + 0.02), _colours(BUMPER)))
    for name in ("front_bumper", "rear_bumper"):
        out.append((body.part(name).corners(), _colours(BUMPER)))
    bump_h = body.part("front_bumper").dims[1][2]
    lz = body.floor + bump_h + 0.06 * min(H, 2.0)
    for side in (1.0, -1.0):
        y = side * 0.38 * W
        out.append((_box(-L / 2 - 0.03, -L / 2 - 0.005, y - 0.08 * W, y + 0.08 * W, lz - 0.035 * H, lz + 0.035 * H),
                    _colours(TAIL)))
        out.append((_box(L / 2 + 0.005, L / 2 + 0.03, y - 0.08 * W, y + 0.08 * W, lz - 0.03 * H, lz + 0.03 * H),
                    _colours(HEAD)))
    if player and body.kind == "car":
        lower, cabin = body.part("lower"), body.part("cabin")
        x_lo, x_hi, _, _, top = lower.bounds
        (c0, c1, _), (r0, r1, _), _, roof = cabin.dims
        for x0, x1, z in ((c1, x_hi, top), (r0, r1, roof), (x_lo, c0, top)):
            for y in (0.09 * W, -0.09 * W):
                out.append((_box(x0 + 0.05, x1 - 0.05, y - 0.035 * W, y + 0.035 * W, z, z + PROUD + 0.006),
                            _colours(STRIPE)))
    return out


def body_mesh(pieces) -> tuple:
    """The pieces as one mesh of flat faces: vertices, normals, colours (unlit), triangles."""
    out = [hexahedron(c, f) for c, f in pieces]
    base = np.cumsum([0] + [len(o[0]) for o in out[:-1]])
    return (np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out]),
            np.concatenate([o[2] for o in out]), np.concatenate([o[3] + b for o, b in zip(out, base)]))


def shadow_texture(length: float, width: float, size: int = 64) -> np.ndarray:
    """(size, size, 4): a soft dark patch for a body of ``length`` x ``width`` drawn on a card SHADOW_RIM larger
    on each side (the sun is high): alpha 0.6 under the body, fading to 0 over the rim."""
    u = (np.arange(size) + 0.5) / size
    X, Y = np.meshgrid((u - 0.5) * (length + 2 * SHADOW_RIM), (u - 0.5) * (width + 2 * SHADOW_RIM))
    out_x = np.maximum(np.abs(X) - 0.5 * length, 0.0)
    out_y = np.maximum(np.abs(Y) - 0.5 * width, 0.0)
    fade = np.clip(1.0 - np.hypot(out_x, out_y) / SHADOW_RIM, 0.0, 1.0)
    img = np.zeros((size, size, 4))
    img[..., 3] = 0.6 * fade * fade * (3 - 2 * fade)
    return img


def interior_parts(cab) -> list:
    """The cabin seen from the driver's seat, (corners, face colours): the dashboard, the two front pillars along
    the windscreen's side edges, the roof's lining and the header above the glass."""
    w = 0.07  # m: a pillar's width
    half = cab.half_inside - 0.01
    out = [(_box(cab.base_x - 0.55, cab.base_x - 0.02, -half, half, cab.belt - 0.30, cab.belt + 0.03),
            _colours(DASHBOARD))]
    for side in (-1.0, 1.0):  # a pillar: the windscreen's side edge, w wide across it, a little inside the glass
        b = np.array([cab.base_x - 0.03, side * (cab.base_half - 0.005), cab.belt])
        t = np.array([cab.top_x - 0.03, side * (cab.top_half - 0.005), cab.roof])
        inward = np.array([0.0, -side * w, 0.0])
        back = np.array([-w, 0.0, 0.0])
        c = np.array([b + back, b, b + inward, b + back + inward, t + back, t, t + inward, t + back + inward])
        out.append((c if side < 0 else c[[3, 2, 1, 0, 7, 6, 5, 4]], _colours(PILLAR)))
    out.append((_box(cab.back_top_x, cab.top_x + 0.01, -half, half, cab.roof - 0.04, cab.roof - 0.02),
                _colours(HEADLINER)))
    out.append((_box(cab.top_x - 0.06, cab.top_x + 0.01, -half, half, cab.roof - 0.07, cab.roof - 0.02),
                _colours(PILLAR)))
    return out


class Lit:
    """A mesh of flat faces whose colours are lit on the host: colour = base (AMBIENT + DIFFUSE max(0, n . sun)),
    n the face's normal turned by the vehicle's heading (it only yaws). The engine's own lights are not used: the
    software renderer applies a vertex colour twice under them (measured: a grey of 0.39 lit by a white light came
    out 0.15), and the same colours must come out of the OpenGL window."""

    def __init__(self, name, verts, normals, colours, tris, parent: NodePath):
        self.base = np.asarray(colours, np.float64)[:, :3] / 255.0
        self.normals = np.asarray(normals, np.float64)
        self.node = parent.attachNewNode(triangles(name, verts, colours, tris, dynamic=True))
        self.vdata = self.node.node().modifyGeom(0).modifyVertexData()
        self.heading = None

    def light(self, heading: float) -> None:
        if self.heading is not None and abs(math.remainder(heading - self.heading, 2 * math.pi)) < LIGHT_STEP:
            return
        self.heading = heading
        c, s = math.cos(heading), math.sin(heading)
        sun = np.array([c * SUN[0] + s * SUN[1], -s * SUN[0] + c * SUN[1], SUN[2]])  # the sun in the body frame
        shade = AMBIENT + DIFFUSE * np.maximum(self.normals @ sun, 0.0)
        vertex_view(self.vdata)["c"][:, :3] = np.round(255.0 * np.clip(self.base * shade[:, None], 0.0, 1.0))


class VehicleModel:
    """One vehicle's node, its wheels and (``interior``) the inside of its cabin, shown with ``show_interior``."""

    def __init__(self, spec, parent: NodePath, ground_z: float, interior: bool = False):
        self.spec = spec
        self.node = parent.attachNewNode(spec.name)
        body = body_parts(spec, ground_z)
        self.lit = [Lit(f"{spec.name}-body", *body_mesh(body_pieces(spec, body, interior)), self.node)]
        R, W = float(spec.tire_radius), float(spec.tire_width)
        v, n, c, t = cylinder(R, W, 14, rgba(TIRE), rgba(HUB))
        wheel = triangles(f"{spec.name}-wheel", v, c, t)
        self.wheels, self.steered = [], []
        for ax in (1.0, -1.0):
            for side in (1.0, -1.0):
                pivot = self.node.attachNewNode("pivot")
                pivot.setPos(ax * spec.wheelbase / 2, side * spec.track / 2, ground_z + R)
                spin = pivot.attachNewNode("spin")
                spin.attachNewNode(wheel)
                self.wheels.append(spin)
                if ax > 0:
                    self.steered.append(pivot)
        self.radius = R
        self.rolled = 0.0  # rad the wheels have turned
        hl, hw = 0.5 * spec.length + SHADOW_RIM, 0.5 * spec.width + SHADOW_RIM
        self.shadow = self.node.attachNewNode(card(f"{spec.name}-shadow", -hl, hl, -hw, hw))
        self.shadow.setTexture(texture_rgba("shadow", shadow_texture(spec.length, spec.width)))
        self.shadow.setTransparency(TransparencyAttrib.MAlpha)
        self.shadow.setDepthWrite(False)
        self.shadow.setLightOff()
        self.shadow.setZ(ground_z + SHADOW_Z)
        self.height = float(spec.height)
        self.interior = None
        if interior:
            cab = cabin_of(spec, ground_z)
            self.lit.append(Lit(f"{spec.name}-cabin", *body_mesh(interior_parts(cab)), self.node))
            self.interior = self.lit[-1].node
            self.interior.hide()
            self.cabin = cab

    def place(self, position, heading: float, origin, speed: float, dt: float, steer: float = 0.0) -> None:
        """Put the vehicle at its pose (world ``position`` (x, y[, z]) m, ``heading`` rad), the wheels turned on by
        what it drove in ``dt`` and the front pair steered by ``steer`` rad."""
        self.node.setPos(float(position[0] - origin[0]), float(position[1] - origin[1]), 0.0)
        self.node.setH(math.degrees(heading))
        for mesh in self.lit:
            mesh.light(heading)
        c, s = math.cos(heading), math.sin(heading)  # the shadow falls away from the sun: SUN is world-fixed
        dx, dy = -SUN[0] / SUN[2] * 0.4 * self.height, -SUN[1] / SUN[2] * 0.4 * self.height
        self.shadow.setPos(c * dx + s * dy, -s * dx + c * dy, self.shadow.getZ())
        self.rolled = (self.rolled + speed * dt / self.radius) % (2.0 * math.pi)
        for w in self.wheels:
            w.setR(math.degrees(self.rolled))
        for p in self.steered:
            p.setH(math.degrees(steer))

    def show_interior(self, on: bool) -> None:
        if self.interior is not None:
            (self.interior.show if on else self.interior.hide)()
