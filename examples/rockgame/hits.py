"""The hits the game shows, from ``Simulation.impacts()``: each one flashes where it struck, and a chip or a crack
leaves a mark, drawn in the frame of the vehicle hit so that it rides with it.

Events (engine/events.py): point and normal in the hit vehicle's frame (x forward, y left, z up; z measured in the
engine's local frame, whose ground lies at ``ground_local`` = ground_z - origin z), part (motion/bodies.py
LABELS), damage class (mark, chip, crack: config/impacts.py) and the hit's normal energy 1/2 m u_n^2 or momentum
m u_n, which place it in its class on a log scale, s in [0, 1] (chip: from the chip to the crack threshold;
crack: from the crack threshold to 10 times it).

  flash      a white-hot core and eight sparks at the point, facing the camera, for FLASH_S seconds: growing,
             then fading; never smaller than FLASH_PX pixels across, so a hit 20 m away reads
  windscreen a chip is a bullseye (a ring of 0.35 r) with 5-7 arms of 0.6-1.0 r, r from 8 to 20 mm by s; a
             crack is two jagged arms through the point, 20 to 60 cm end to end by s, with short branches:
             segments in the glass's plane (motion/cabin.py: from the belt line to the roof), clipped to the glass
             a centimetre inside its edges, GAP outside it (seen from the driver's seat through the glass and from
             outside alike)
  paint      a chip or a crack on the bonnet or the front chips the paint: a small pale flake, 4-25 mm, on the
             plane of the hit, GAP off it

A mark's shape comes from a generator seeded by the hit (rock, step), so a replay draws the same marks.
"""

from __future__ import annotations

import math

import numpy as np
from panda3d.core import NodePath, TransparencyAttrib

from taichi_rocks.config.impacts import DAMAGE_CLASSES
from taichi_rocks.motion.bodies import LABELS

from .meshes import card, lines, rgba, texture_rgba, triangles

WINDSCREEN = LABELS.index("windscreen")
PAINTED = (LABELS.index("bonnet"), LABELS.index("front_bumper"))
MARK, CHIP, CRACK = (DAMAGE_CLASSES.index(c) for c in ("mark", "chip", "crack"))
FLASH_S = 0.13  # s a flash lasts
FLASH_M = 0.05  # m: a flash's radius (sparks), at its largest
FLASH_PX = 14.0  # pixels: at least this radius on screen
GAP = 0.003  # m off the glass or the paint
MARGIN = 0.01  # m: marks stay this far inside the glass's edges
CRACK_COLOUR = (0.93, 0.95, 0.97)
PAINT_COLOUR = (0.78, 0.76, 0.72)


def severity(e, thresholds, measure: str) -> float:
    """s in [0, 1]: where the hit's measure lies in its class (module docstring)."""
    value = 0.5 * float(e["normal_momentum"]) * float(e["normal_speed"]) if measure == "energy" \
        else float(e["normal_momentum"])
    chip, crack = thresholds
    lo, hi = (chip, crack) if int(e["damage"]) == CHIP else (crack, 10.0 * crack)
    if value <= 0.0:
        return 0.0
    return float(np.clip(math.log(value / lo) / math.log(hi / lo), 0.0, 1.0))


class Glass:
    """A windscreen (motion/cabin.py Cabin): glass coordinates (y, a), a = metres up the glass from its foot."""

    def __init__(self, cab):
        self.cab = cab
        self.slope = math.hypot(cab.top_x - cab.base_x, cab.roof - cab.belt)
        n = np.array([cab.roof - cab.belt, 0.0, cab.base_x - cab.top_x])
        self.normal = n / np.linalg.norm(n)

    def along(self, z: float) -> float:
        return (z - self.cab.belt) * self.slope / (self.cab.roof - self.cab.belt)

    def inside(self, p) -> bool:
        u = p[1] / self.slope
        if not (MARGIN / self.slope <= u <= 1.0 - MARGIN / self.slope):
            return False
        return abs(p[0]) <= self.cab.base_half + u * (self.cab.top_half - self.cab.base_half) - MARGIN

    def clip(self, a, b):
        """The part of segment a-b from a to where it leaves the glass (None if a is off it): the glass is convex,
        so bisect to its edge."""
        if not self.inside(a):
            return None
        if self.inside(b):
            return a, b
        lo, hi = 0.0, 1.0
        for _ in range(16):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.inside(a + mid * (b - a)) else (lo, mid)
        return a, a + lo * (b - a)

    def to_body(self, p) -> np.ndarray:
        u = p[1] / self.slope
        z = self.cab.belt + u * (self.cab.roof - self.cab.belt)
        x = self.cab.base_x + u * (self.cab.top_x - self.cab.base_x)
        return np.array([x, p[0], z]) + GAP * self.normal


def _star(c, r, rng) -> list:
    ring = [c + 0.35 * r * np.array([math.cos(a), math.sin(a)]) for a in np.linspace(0, 2 * math.pi, 9)]
    segs = list(zip(ring[:-1], ring[1:]))
    n = int(rng.integers(5, 8))
    for a in rng.uniform(0, 2 * math.pi) + np.arange(n) * 2 * math.pi / n + rng.uniform(-0.3, 0.3, n):
        segs.append((c, c + r * rng.uniform(0.6, 1.0) * np.array([math.cos(a), math.sin(a)])))
    return segs


def _crack(c, s, rng) -> list:
    segs = _star(c, 0.02, rng)
    half = 0.5 * (0.20 + s * 0.40)
    heading = rng.uniform(0, math.pi)
    for direction in (heading, heading + math.pi):
        p, a = c, direction
        for k in range(6):
            a += rng.uniform(-0.35, 0.35)
            q = p + half / 6 * np.array([math.cos(a), math.sin(a)])
            segs.append((p, q))
            if k in (1, 3) and rng.random() < 0.7:
                b = a + rng.choice([-1, 1]) * rng.uniform(0.45, 0.9)
                segs.append((q, q + half * rng.uniform(0.2, 0.4) * np.array([math.cos(b), math.sin(b)])))
            p = q
    return segs


def windscreen_mark(e, s: float, glass: Glass) -> np.ndarray:
    """Segments (K, 2, 3), body frame, of a chip or crack ``e`` of severity ``s`` on ``glass``."""
    rng = np.random.default_rng([int(e["rock"]) & 0xFFFFFFFF, int(e["step"]) & 0xFFFFFFFF, 53])
    c = np.array([float(e["point"][1]), glass.along(float(e["point"][2]))])
    segs = _crack(c, s, rng) if int(e["damage"]) == CRACK else _star(c, 0.008 + 0.012 * s, rng)
    out = [glass.clip(np.asarray(a), np.asarray(b)) for a, b in segs]
    return np.array([(glass.to_body(a), glass.to_body(b)) for a, b in (x for x in out if x is not None)]).reshape(-1, 2, 3)


def paint_flake(e, s: float) -> np.ndarray:
    """Triangles (K, 3, 3), body frame: a pale irregular flake on the plane of hit ``e``, GAP off it."""
    rng = np.random.default_rng([int(e["rock"]) & 0xFFFFFFFF, int(e["step"]) & 0xFFFFFFFF, 54])
    n = np.asarray(e["normal"], np.float64)
    n /= np.linalg.norm(n)
    u = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    r = (0.004 + 0.006 * s) if int(e["damage"]) == CHIP else (0.010 + 0.015 * s)
    c = np.asarray(e["point"], np.float64) + GAP * n
    a = np.linspace(0, 2 * math.pi, 8, endpoint=False)
    rim = c + (r * rng.uniform(0.6, 1.0, 8))[:, None] * (np.cos(a)[:, None] * u + np.sin(a)[:, None] * v)
    return np.array([(c, rim[k], rim[(k + 1) % 8]) for k in range(8)])


def flash_texture(size: int = 64) -> np.ndarray:
    """(size, size, 4): a hit's flash, radius 1 across the card: a white-hot core and eight sparks (every other one
    shorter) going yellow as they reach out, alpha fading with the distance from the centre."""
    u = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    X, Y = np.meshgrid(u, u)
    r, a = np.hypot(X, Y), np.arctan2(Y, X)
    reach = np.where(np.round(a / (np.pi / 4)) % 2 == 0, 1.0, 0.6)
    off = np.abs(np.sin(4.0 * a)) * r  # distance from the nearest spark's line, about
    spark = np.clip(1.0 - off / 0.06, 0, 1) * np.clip(1.0 - r / reach, 0, 1)
    core = np.exp(-(r / 0.18) ** 2)
    alpha = np.clip(core + 0.9 * spark, 0, 1)
    img = np.empty((size, size, 4))
    img[..., 0] = 1.0
    img[..., 1] = np.clip(0.8 + 0.2 * core, 0, 1)
    img[..., 2] = np.clip(0.35 + 0.65 * core, 0, 1)
    img[..., 3] = alpha
    return img


class HitView:
    """The flashes and marks of the hits so far. ``vehicles``: the VehicleModels by scene index; ``glasses``:
    {vehicle index: Glass} of the vehicles whose windscreens take marks; ``thresholds``, ``measure``: the scene's
    [impacts] damage thresholds (``Impacts.thresholds()``) and measure; ``ground_local``: the engine's ground
    height in its local frame."""

    def __init__(self, vehicles, glasses, thresholds, measure: str, ground_local: float):
        self.vehicles, self.glasses = vehicles, glasses
        self.thresholds, self.measure, self.ground_local = thresholds, measure, float(ground_local)
        self.flashes = []  # (node, time of the hit)
        self.marks = {i: [] for i in glasses}  # vehicle -> windscreen segments, one array a mark
        self.flakes = {i: [] for i in glasses}
        self._mark_nodes, self._flake_nodes = {}, {}
        self._flash = NodePath(card("flash", -1.0, 1.0, -1.0, 1.0, plane="xz"))
        self._flash.setTexture(texture_rgba("flash", flash_texture()))
        self._flash.setTransparency(TransparencyAttrib.MAlpha)
        self._flash.setLightOff()
        self._flash.setDepthWrite(False)
        self._flash.setBin("fixed", 10)
        self._flash.setTwoSided(True)
        self.counts = np.zeros((len(vehicles), len(DAMAGE_CLASSES)), np.int64)  # hits by vehicle and class
        self.taken = 0  # events taken from impacts()

    def add(self, events, t: float) -> None:
        """The frame's events (``impacts()``), the frame's time ``t``."""
        self.taken += len(events)
        for e in events:
            vi = int(e["vehicle"])
            self.counts[vi, int(e["damage"])] += 1
            point = np.array(e["point"], np.float64)
            point[2] -= self.ground_local  # into the body frame the vehicles are drawn in (ground at z = 0)
            node = self._flash.instanceTo(self.vehicles[vi].node)
            node.setPos(*point)
            node.setBillboardPointEye()
            self.flashes.append((node, float(e["time"])))
            if vi not in self.glasses or int(e["damage"]) < CHIP:
                continue
            hit = e.copy()
            hit["point"] = point
            s = severity(e, self.thresholds, self.measure)
            if int(e["part"]) == WINDSCREEN:
                self.marks[vi].append(windscreen_mark(hit, s, self.glasses[vi]))
                self._redraw(vi, marks=True)
            elif int(e["part"]) in PAINTED:
                self.flakes[vi].append(paint_flake(hit, s))
                self._redraw(vi, marks=False)

    def _redraw(self, vi: int, marks: bool) -> None:
        nodes = self._mark_nodes if marks else self._flake_nodes
        if vi in nodes:
            nodes[vi].removeNode()
        parent = self.vehicles[vi].node
        if marks:
            segs = np.concatenate(self.marks[vi]) if self.marks[vi] else np.empty((0, 2, 3))
            if not len(segs):
                return
            nodes[vi] = parent.attachNewNode(lines(f"marks-{vi}", segs, rgba(CRACK_COLOUR)))
        else:
            tri = np.concatenate(self.flakes[vi]).reshape(-1, 3)
            nodes[vi] = parent.attachNewNode(triangles(f"paint-{vi}", tri, rgba(PAINT_COLOUR),
                                                       np.arange(len(tri)).reshape(-1, 3)))
            nodes[vi].setTwoSided(True)
        nodes[vi].setLightOff()

    def clear(self, vi: int) -> None:
        """A new car: its marks gone."""
        for nodes in (self._mark_nodes, self._flake_nodes):
            if vi in nodes:
                nodes.pop(vi).removeNode()
        self.marks[vi], self.flakes[vi] = [], []

    def update(self, t: float, camera, pixel_angle: float) -> None:
        """The flashes at time ``t``: grown, faded, at least FLASH_PX pixels at their distance from ``camera``
        (``pixel_angle``: rad a pixel subtends); those older than FLASH_S gone."""
        keep = []
        for node, t0 in self.flashes:
            age = t - t0
            if age >= FLASH_S:
                node.removeNode()
                continue
            k = age / FLASH_S
            dist = max(node.getDistance(camera), 0.1)
            r = max(FLASH_M, FLASH_PX * pixel_angle * dist) * (0.6 + 0.4 * min(1.0, 3.0 * k))
            node.setScale(r)
            node.setColorScale(1, 1, 1, 1.0 - k * k)
            keep.append((node, t0))
        self.flashes = keep

    def windscreen_marks(self, vi: int) -> int:
        return len(self.marks.get(vi, ()))
