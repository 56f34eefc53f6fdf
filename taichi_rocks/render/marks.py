"""Hits you can see, host side (NumPy, no Taichi calls): the impacts seen so far, their flashes and the marks
they leave on windscreens, kept by time so that going back in time hides them again.

State (:class:`Hits`): the events (engine/events.py ``EVENT_DTYPE``) the simulation reported, their points moved
into the body frame the renderer draws in (motion/bodies.py: on the ground, :func:`to_body_frame`), and the time
of the frame shown. :meth:`Hits.update` adds a frame's events and sets that time (an event seen again, as after
a restore that steps the same steps again, is kept once: its key is (step, rock, vehicle)). Only the hits up to
the time shown count, flash and mark: a scrub back, the view playing round to frame 0 or a restart hides the
later ones, and a scrub forward past a saved state (whose steps are not stepped again) shows them again, as the
run is deterministic. What changes the future (a runtime parameter, a rebuild) forgets the hits after the time
(:meth:`Hits.clear_after`). :meth:`Hits.counts` counts a vehicle's hits by damage class (config/impacts.py
DAMAGE_CLASSES), the view's HUD.

Flash (:func:`flash_geometry`): every impact flashes at its contact point for FLASH_S seconds (4 frames at 30
frames/s): a hot core and RAYS short sparks along the surface, fading and spreading as it ages; the point rides
with the vehicle hit (its pose at the frame). Sizes are in metres, but never below FLASH_PX pixels for the core
and RAY_PX for the sparks at the camera's distance, so a hit 20 m ahead reads as well as one on the bonnet.

Marks (:func:`mark_segments`): a chip or a crack on a windscreen stays as line segments on the glass, shaped by
its damage class and sized by how far its measure (normal energy 1/2 m u_n^2 or normal momentum m u_n, as
[impacts] damage_by) lies above the class's threshold (s in [0, 1], log scale):

  chip   a bullseye with a star: a ring of radius 0.35 R and 5-7 arms of 0.6-1.0 R, R = CHIP_R (8 -> 20 mm);
  crack  the chip's star at the point, and a line crack through it, L = CRACK_L (20 -> 60 cm) end to end, as
         two jagged arms (bent at CRACK_STEPS points by up to CRACK_JITTER rad) with 2-4 branches of 0.2-0.4 of
         an arm at 25-50 degrees off it.

Windscreen chips are typically 5-20 mm bullseyes and stars, and a crack from a stone runs from a few cm to
across the glass; a mark's shape is drawn from a hash of (rock, step), so it is the same in every run. The
segments lie in the windscreen's plane (motion/cabin.py: the front face of the cabin, from the belt line to the
roof; on it or up to a few mm outside the body's glass face), whatever depth the contact point was reported at,
clipped to the glass GLASS_MARGIN inside its edges, GLASS_GAP inside it from the driver's seat (behind the
windscreen's frame, render/interior.py INSET, which hides what its pillars cover) or outside it seen from
outside. They are drawn as ribbons on the glass (:func:`glass_ribbons`): a few pixels wide at their distance from
the camera and clipped to the glass GLASS_EDGE inside its edges, so every pixel of a mark lies on the glass, and
the depth test hides what the cabin's frame, the dashboard or another body covers.

Paint chips (:func:`paint_chip`): a chip or a crack on the bonnet or the front (part "bonnet", "front_bumper")
chips the paint: an irregular flake of radius PAINT_R (chip class 4 -> 10 mm, crack class 10 -> 25 mm, by s),
on the body face the stone hit (motion/bodies.py: the part's face whose outward normal is closest to the
contact normal and whose plane passes nearest the contact point), clipped to that face PAINT_MARGIN inside its
edges, PAINT_GAP off it.
"""

from __future__ import annotations

import math

import numpy as np

from ..config.impacts import DAMAGE_CLASSES
from ..engine.events import EVENT_DTYPE
from ..motion.bodies import FACE_CORNERS, LABELS, body_parts, hexahedron_planes
from ..motion.cabin import cabin_of

__all__ = ["Hits", "to_body_frame", "body_to_local", "flash_geometry", "mark_segments", "glass_side", "glass_normal",
           "cabin_for", "severity", "glass_ribbons", "body_faces", "face_of", "paint_chip", "FLASH_S", "WINDSCREEN",
           "PAINTED", "CHIP", "CRACK"]

WINDSCREEN = LABELS.index("windscreen")
PAINTED = tuple(LABELS.index(p) for p in ("bonnet", "front_bumper"))  # parts whose paint a hit chips
MARK, CHIP, CRACK = (DAMAGE_CLASSES.index(c) for c in ("mark", "chip", "crack"))
FLASH_S = 0.13  # s a flash lasts (4 frames at 30 frames/s)
FLASH_M = 0.012  # m: the flash core's radius, at its largest
FLASH_PX = 5.0  # pixels: the core's radius at least, at its largest
RAY_M = 0.09  # m: a spark's length, fully spread
RAY_PX = 24.0  # pixels: a spark's length at least, fully spread
RAYS = 8
HOT = 2.5  # the core's colour at its brightest (white-hot once GGUI's shading and the 8-bit image clip it)
CHIP_R = (0.008, 0.02)  # m: the chip's radius, at s = 0 and s = 1
CRACK_L = (0.20, 0.60)  # m: the crack's length end to end, at s = 0 and s = 1
CRACK_STEPS = 6  # bends per arm of a crack
CRACK_JITTER = 0.35  # rad: at most this much turn at a bend
GLASS_GAP = 0.002  # m between a mark and the glass, on the camera's side
GLASS_MARGIN = 0.01  # m: marks stop this far inside the glass's edges
GLASS_EDGE = 0.002  # m: and their ribbons, drawn a few pixels wide, this far
CRACK_DECADE = 10.0  # a crack's measure this many times its threshold is the largest crack
PAINT_R = ((0.004, 0.010), (0.010, 0.025))  # m: a paint chip's radius, (s = 0, s = 1) of the chip and crack class
PAINT_MARGIN = 0.004  # m: paint chips stop this far inside the face's edges
PAINT_GAP = 0.0015  # m between a paint chip and its face, outside


def to_body_frame(events: np.ndarray, ground_local: float) -> np.ndarray:
    """A copy of ``events`` with their points in the body frame the renderer and motion/bodies.py use (origin on
    the ground): the engine's points have their z in its local frame, whose ground lies at ``ground_local``
    (scene ground_z minus the floating origin's z)."""
    out = np.array(events, EVENT_DTYPE, copy=True)
    out["point"][:, 2] -= float(ground_local)
    return out


def body_to_local(points, positions, headings) -> np.ndarray:
    """Body-frame points (N, 3) of vehicles at ``positions`` (N, 3, body centre at ground level, any frame:
    world or local) with ``headings`` (N,) rad: p' = position + R_z(heading) p."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    h = np.asarray(headings, np.float64).reshape(-1)
    c, s = np.cos(h), np.sin(h)
    return np.asarray(positions, np.float64).reshape(-1, 3) + np.stack(
        [c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1], p[:, 2]], 1)


def _keys(ev: np.ndarray) -> list:
    """Each event's key, (step, rock, vehicle): one hit."""
    return list(zip(ev["step"].tolist(), ev["rock"].tolist(), ev["vehicle"].tolist()))


class Hits:
    """The impacts seen up to time ``t`` (see the module docstring). ``thresholds``: (chip, crack) in the unit of
    ``measure`` ("energy" or "momentum": config/impacts.py ``Impacts.thresholds``), which size the marks."""

    def __init__(self, thresholds=(0.0055, 0.14), measure: str = "energy"):
        self.thresholds = (float(thresholds[0]), float(thresholds[1]))
        self.measure = measure
        self.events = np.empty(0, EVENT_DTYPE)
        self.t = 0.0
        self._seen = set()  # the keys of self.events
        self._shapes = {}  # key -> the mark's segments, body frame (K, 2, 3), or a paint chip (triangles, normal)
        self._chips = {}  # vehicle -> (the chips' keys, their triangles and normals), of the last call

    @classmethod
    def of_scene(cls, scene) -> Hits:
        return cls(scene.impacts.thresholds(), scene.impacts.damage_by)

    def update(self, events, t: float) -> int:
        """Add the events reported up to time ``t`` (body frame: :func:`to_body_frame`), the time shown now;
        return how many were new."""
        self.t = float(t)
        ev = np.asarray(events, EVENT_DTYPE)
        if not len(ev):
            return 0
        new = []
        for i, key in enumerate(_keys(ev)):
            if key not in self._seen:
                self._seen.add(key)
                new.append(i)
        ev = ev[new]
        if len(ev):
            allev = np.concatenate([self.events, ev])
            self.events = allev[np.argsort(allev["time"], kind="stable")]
        return len(ev)

    def shown(self) -> np.ndarray:
        """The hits up to the time shown."""
        return self.events[self.events["time"] <= self.t]

    def clear_after(self, t: float) -> None:
        """Forget the events after time ``t`` (their future changed: a runtime parameter, a rebuild)."""
        keep = self.events["time"] <= float(t)
        if not keep.all():
            gone = set(_keys(self.events[~keep]))
            self._seen -= gone
            self._shapes = {k: v for k, v in self._shapes.items() if k not in gone}
            self._chips = {}
            self.events = self.events[keep]
        self.t = min(self.t, float(t))

    def clear(self) -> None:
        self.events = np.empty(0, EVENT_DTYPE)
        self._seen, self._shapes, self._chips = set(), {}, {}
        self.t = 0.0

    def counts(self, vehicle: int) -> dict:
        """Hits on ``vehicle`` so far, by damage class: {"mark": n, "chip": n, "crack": n}."""
        ev = self.shown()
        ev = ev[ev["vehicle"] == int(vehicle)]
        n = np.bincount(ev["damage"].astype(np.int64), minlength=len(DAMAGE_CLASSES))
        return {c: int(n[k]) for k, c in enumerate(DAMAGE_CLASSES)}

    def flashing(self, t: float) -> tuple:
        """(events, ages in s) of the flashes at time ``t``: the hits of the last FLASH_S seconds."""
        ev = self.shown()
        age = float(t) - ev["time"]
        sel = (age >= 0.0) & (age < FLASH_S)
        return ev[sel], age[sel]

    def marks(self) -> np.ndarray:
        """The hits shown that left a mark: chips and cracks on part "windscreen" (on the glass) and on the
        painted parts (:data:`PAINTED`: the paint chipped)."""
        ev = self.shown()
        return ev[((ev["part"] == WINDSCREEN) | np.isin(ev["part"], PAINTED)) & (ev["damage"] >= CHIP)]

    def windscreen_segments(self, vehicle: int, cabin) -> np.ndarray:
        """Segments (K, 2, 3) of every mark on ``vehicle``'s windscreen, body frame on the glass (no gap: the
        caller moves them to the camera's side, :func:`glass_side`); ``cabin``: its motion/cabin.py Cabin."""
        ev = self.marks()
        ev = ev[(ev["vehicle"] == int(vehicle)) & (ev["part"] == WINDSCREEN)]
        out = []
        for e in ev:
            key = (int(e["step"]), int(e["rock"]), int(e["vehicle"]))
            if key not in self._shapes:
                self._shapes[key] = mark_segments(e, severity(e, self.thresholds, self.measure), cabin)
            out.append(self._shapes[key])
        return np.concatenate(out) if out else np.empty((0, 2, 3))

    def paint_chips(self, vehicle: int, faces) -> tuple:
        """Every paint chip on ``vehicle`` (``faces``: its :func:`body_faces`): triangles (K, 3, 3), body frame,
        PAINT_GAP off their faces, and each triangle's face normal (K, 3)."""
        ev = self.marks()
        ev = ev[(ev["vehicle"] == int(vehicle)) & np.isin(ev["part"], PAINTED)]
        which = (len(ev), ev["step"].tobytes(), ev["rock"].tobytes())
        cached = self._chips.get(int(vehicle))
        if cached is not None and cached[0] == which:  # the same chips as the last frame: hundreds on a bumper
            return cached[1]
        tris, nrms = [], []
        for e in ev:
            key = (int(e["step"]), int(e["rock"]), int(e["vehicle"]))
            if key not in self._shapes:
                self._shapes[key] = paint_chip(e, severity(e, self.thresholds, self.measure), faces)
            t, n = self._shapes[key]
            tris.append(t)
            nrms.append(np.repeat(n[None], len(t), 0))
        out = (np.concatenate(tris), np.concatenate(nrms)) if tris else (np.empty((0, 3, 3)), np.empty((0, 3)))
        self._chips[int(vehicle)] = (which, out)
        return out


def severity(e, thresholds, measure: str) -> float:
    """s in [0, 1]: where event ``e``'s measure lies in its damage class, log scale (chip: from the chip to the
    crack threshold; crack: from the crack threshold to CRACK_DECADE times it)."""
    value = 0.5 * float(e["normal_momentum"]) * float(e["normal_speed"]) if measure == "energy" \
        else float(e["normal_momentum"])
    chip, crack = thresholds
    lo, hi = (chip, crack) if int(e["damage"]) == CHIP else (crack, CRACK_DECADE * crack)
    if value <= 0.0 or lo <= 0.0:
        return 0.0
    return float(np.clip(math.log(value / lo) / math.log(hi / lo), 0.0, 1.0))


def _random(e) -> np.random.Generator:
    """A generator seeded by the hit (rock, step): the same mark in every run."""
    return np.random.default_rng([int(e["rock"]) & 0xFFFFFFFF, int(e["step"]) & 0xFFFFFFFF, 22])


def _star(c, r, rng) -> list:
    """A chip around ``c`` (glass coordinates y, z): a ring of 8 segments and 5-7 arms."""
    segs = []
    ring = [c + 0.35 * r * np.array([math.cos(a), math.sin(a)]) for a in np.linspace(0, 2 * math.pi, 9)]
    segs += list(zip(ring[:-1], ring[1:]))
    n = int(rng.integers(5, 8))
    for a in rng.uniform(0, 2 * math.pi) + np.arange(n) * 2 * math.pi / n + rng.uniform(-0.3, 0.3, n):
        segs.append((c, c + r * rng.uniform(0.6, 1.0) * np.array([math.cos(a), math.sin(a)])))
    return segs


def _arm(start, angle, length, rng, steps=CRACK_STEPS) -> list:
    """A jagged line from ``start`` at ``angle``, ``length`` long: ``steps`` segments, each bent a little."""
    pts, a = [np.asarray(start, np.float64)], angle
    for _ in range(steps):
        a += rng.uniform(-CRACK_JITTER, CRACK_JITTER)
        pts.append(pts[-1] + (length / steps) * np.array([math.cos(a), math.sin(a)]))
    return pts


def _crack(c, s, rng) -> list:
    """A line crack through ``c``: two arms, mostly across the glass, with branches, and the chip at c."""
    half = 0.5 * (CRACK_L[0] + s * (CRACK_L[1] - CRACK_L[0]))
    base = rng.uniform(-0.6, 0.6)  # rad from the horizontal: stone cracks run mostly across a windscreen
    segs = _star(c, CHIP_R[1], rng)
    for side in (0.0, math.pi):
        arm = _arm(c, base + side, half * rng.uniform(0.7, 1.0), rng)
        segs += list(zip(arm[:-1], arm[1:]))
        for _ in range(int(rng.integers(1, 3)) + (1 if s > 0.5 else 0)):
            k = int(rng.integers(1, len(arm) - 1))
            turn = math.radians(rng.uniform(25, 50)) * rng.choice((-1.0, 1.0))
            d = arm[k + 1] - arm[k]
            branch = _arm(arm[k], math.atan2(d[1], d[0]) + turn, half * rng.uniform(0.2, 0.4), rng, 3)
            segs += list(zip(branch[:-1], branch[1:]))
    return segs


def mark_segments(e, s: float, cabin) -> np.ndarray:
    """The mark of event ``e`` (a chip or a crack, body frame) of severity ``s`` on the windscreen of ``cabin``:
    segments (K, 2, 3), body frame, on the glass's plane and clipped to it (see the module docstring). Drawn in
    glass coordinates (y, metres up the glass), so that lengths on the sloping glass are true."""
    rng = _random(e)
    c = np.array([float(e["point"][1]), _along(cabin, float(e["point"][2]))])  # glass coordinates
    if int(e["damage"]) == CRACK:
        segs = _crack(c, s, rng)
    else:
        segs = _star(c, CHIP_R[0] + s * (CHIP_R[1] - CHIP_R[0]), rng)
    # on the cabin's windscreen plane, whatever depth the contact point was reported at (a stone is found a few
    # mm inside the glass, more at speed): on the body's glass face or up to a few mm outside it (the face starts
    # 1 cm below the belt line, motion/bodies.py EPS), never inside the cabin in front of its frame
    out = []
    for a, b in segs:
        a, b = _clip(cabin, np.asarray(a), np.asarray(b))
        if a is not None:
            out.append((_on_glass(cabin, a), _on_glass(cabin, b)))
    return np.array(out, np.float64).reshape(-1, 2, 3)


def _along(cabin, z: float) -> float:
    """m up the glass from its foot to height ``z``: glass coordinates are (y, this), lengths true on it."""
    return (z - cabin.belt) * math.hypot(cabin.top_x - cabin.base_x, cabin.roof - cabin.belt) / (cabin.roof - cabin.belt)


def _height(cabin, v: float) -> float:
    return cabin.belt + v * (cabin.roof - cabin.belt) / math.hypot(cabin.top_x - cabin.base_x, cabin.roof - cabin.belt)


def _inside(cabin, p) -> bool:
    y, z = p[0], _height(cabin, p[1])
    if not (cabin.belt + GLASS_MARGIN <= z <= cabin.roof - GLASS_MARGIN):
        return False
    u = (z - cabin.belt) / (cabin.roof - cabin.belt)
    return abs(y) <= cabin.base_half + u * (cabin.top_half - cabin.base_half) - GLASS_MARGIN


def _clip(cabin, a, b):
    """The part of segment a-b (glass coordinates) from a up to where it leaves the glass (None if a is out)."""
    if not _inside(cabin, a):
        return None, None
    if _inside(cabin, b):
        return a, b
    lo, hi = 0.0, 1.0
    for _ in range(20):  # the glass is convex: bisect to its edge
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _inside(cabin, a + mid * (b - a)) else (lo, mid)
    return a, a + lo * (b - a)


def _on_glass(cabin, p) -> tuple:
    y, z = p[0], _height(cabin, p[1])
    return (cabin.windscreen_x(z), y, z)


def glass_normal(cabin) -> np.ndarray:
    """The outward unit normal of the windscreen of ``cabin`` (body frame)."""
    n = np.array([cabin.roof - cabin.belt, 0.0, cabin.base_x - cabin.top_x])
    return n / np.linalg.norm(n)


def glass_side(segments: np.ndarray, cabin, inside: bool) -> np.ndarray:
    """Segments moved GLASS_GAP off the windscreen of ``cabin``, towards the cabin (``inside``) or out."""
    return segments + (-GLASS_GAP if inside else GLASS_GAP) * glass_normal(cabin)


def _glass_edges(cabin, margin: float) -> list:
    """The windscreen of ``cabin`` in glass coordinates (y, metres up the glass) as half-planes (a, b, c):
    a y + b v <= c, ``margin`` inside its edges."""
    top = _along(cabin, cabin.roof)
    k = (cabin.top_half - cabin.base_half) / top  # the half width grows this much per metre up the glass
    h = math.hypot(1.0, k)
    return [(0.0, -1.0, -margin), (0.0, 1.0, top - margin), (1.0 / h, -k / h, cabin.base_half / h - margin),
            (-1.0 / h, -k / h, cabin.base_half / h - margin)]


def glass_ribbons(segments: np.ndarray, cabin, inside: bool, eye, px_per_rad: float, width_px: float) -> np.ndarray:
    """Windscreen mark segments (K, 2, 3: body frame on the glass of ``cabin``) as ribbons on the glass, drawn
    from ``eye`` (body frame; ``px_per_rad``: the camera's pixels per radian): triangles (T, 3, 3), body frame,
    GLASS_GAP off the glass on the camera's side (:func:`glass_side`). Each ribbon is ``width_px`` pixels wide at
    its distance from the eye and clipped to the glass GLASS_EDGE inside its edges, so that no pixel of a mark
    falls off the glass (a line is drawn at a width in pixels, past the ends of whatever it lies on)."""
    seg = np.asarray(segments, np.float64).reshape(-1, 2, 3)
    if not len(seg):
        return np.empty((0, 3, 3))
    g = np.stack([seg[..., 1], _along(cabin, seg[..., 2])], -1)  # glass coordinates (K, 2, 2): lengths true
    dist = np.linalg.norm(seg.mean(axis=1) - np.asarray(eye, np.float64), axis=1)
    half = 0.5 * float(width_px) * dist / float(px_per_rad)
    d = g[:, 1] - g[:, 0]
    norm = np.linalg.norm(d, axis=1)
    keep = norm > 1e-9
    g, d, half, norm = g[keep], d[keep], half[keep], norm[keep]
    across = np.stack([-d[:, 1], d[:, 0]], 1) * (half / norm)[:, None]
    quads = np.stack([g[:, 0] - across, g[:, 0] + across, g[:, 1] + across, g[:, 1] - across], 1)  # (K, 4, 2)
    edges = _glass_edges(cabin, GLASS_EDGE)
    inside_all = np.ones(len(quads), bool)
    for a, b, c in edges:
        inside_all &= np.all(a * quads[..., 0] + b * quads[..., 1] <= c, axis=1)
    tris = [quads[inside_all][:, [0, 1, 2]], quads[inside_all][:, [0, 2, 3]]]
    for q in quads[~inside_all]:  # the few at the glass's edges: clipped to it (convex: a fan stays inside)
        poly = _clip_convex(q, edges)
        if len(poly) >= 3:
            tris.append(np.stack([np.repeat(poly[:1], len(poly) - 2, 0), poly[1:-1], poly[2:]], 1))
    t2 = np.concatenate(tris).reshape(-1, 2)
    z = _height(cabin, t2[:, 1])
    pts = np.stack([cabin.windscreen_x(z), t2[:, 0], z], 1) + (-GLASS_GAP if inside else GLASS_GAP) * \
        glass_normal(cabin)
    return pts.reshape(-1, 3, 3)


def body_faces(spec) -> list:
    """Every face of the body of vehicle ``spec`` (motion/bodies.py, body frame on the ground): (corners (4, 3),
    outward plane (n, d): n . x = d on it)."""
    out = []
    for part in body_parts(spec, 0.0).parts:
        c = part.corners()
        planes = hexahedron_planes(c)
        out += [(c[list(idx)], planes[f]) for f, idx in enumerate(FACE_CORNERS)]
    return out


def face_of(faces, point, normal):
    """The face of ``faces`` (:func:`body_faces`) a hit at ``point`` with outward ``normal`` is on: of the faces
    turned within 60 degrees of the normal, the one whose plane passes nearest the point."""
    p, n = np.asarray(point, np.float64), np.asarray(normal, np.float64)
    best, key = None, None
    for corners, plane in faces:
        if plane[:3] @ n < 0.5:
            continue
        q = (abs(float(plane[:3] @ p - plane[3])), -float(plane[:3] @ n))
        if key is None or q < key:
            best, key = (corners, plane), q
    return best


def _clip_convex(poly: np.ndarray, edges) -> np.ndarray:
    """Polygon ``poly`` (N, 2) clipped to the half-planes ``edges`` ((a, b, c): a x + b y <= c; Sutherland and
    Hodgman)."""
    for a, b, c in edges:
        if not len(poly):
            break
        out = []
        for k in range(len(poly)):
            p, q = poly[k], poly[(k + 1) % len(poly)]
            fp, fq = a * p[0] + b * p[1] - c, a * q[0] + b * q[1] - c
            if fp <= 0.0:
                out.append(p)
            if (fp < 0.0) != (fq < 0.0) and fp != fq:
                out.append(p + (q - p) * (fp / (fp - fq)))
        poly = np.array(out).reshape(-1, 2)
    return poly


def paint_chip(e, s: float, faces) -> tuple:
    """The paint chip of event ``e`` (body frame) of severity ``s`` on the face of ``faces`` it hit
    (:func:`face_of`): triangles (K, 3, 3), body frame, PAINT_GAP outside the face and clipped to it
    PAINT_MARGIN inside its edges (none if the hit lies outside that), and the face's outward normal (3,). An
    irregular flake: 7-9 corners round the hit at 0.55-1 of its radius, drawn from a hash of (rock, step)."""
    found = face_of(faces, e["point"], e["normal"])
    if found is None:
        return np.empty((0, 3, 3)), np.array(e["normal"], np.float64)
    corners, plane = found
    n = plane[:3]
    u = np.cross(n, (0.0, 0.0, 1.0))
    if np.linalg.norm(u) < 1e-6:  # a top or bottom face
        u = np.cross(n, (0.0, 1.0, 0.0))
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    c = np.asarray(e["point"], np.float64)
    c = c - (n @ c - plane[3]) * n  # on the face
    face = np.stack([(corners - c) @ u, (corners - c) @ v], 1)
    d0, d1 = face[1] - face[0], face[2] - face[1]
    if d0[0] * d1[1] - d0[1] * d1[0] < 0:  # clockwise: turn it round
        face = face[::-1]
    edges = []
    for k in range(len(face)):  # inward offsets of the (counter-clockwise) face's edges
        d = face[(k + 1) % len(face)] - face[k]
        out = np.array([d[1], -d[0]]) / np.linalg.norm(d)
        edges.append((out[0], out[1], float(out @ face[k]) - PAINT_MARGIN))
    if any(-cc > 0.0 for _, _, cc in edges):  # the hit itself lies outside the face's margin
        return np.empty((0, 3, 3)), n
    rng = _random(e)
    lo, hi = PAINT_R[1 if int(e["damage"]) == CRACK else 0]
    r = lo + s * (hi - lo)
    k = int(rng.integers(7, 10))
    ang = rng.uniform(0, 2 * math.pi) + np.arange(k) * 2 * math.pi / k + rng.uniform(-0.25, 0.25, k)
    poly = r * rng.uniform(0.55, 1.0, k)[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
    poly = _clip_convex(poly, edges)
    if len(poly) < 2:
        return np.empty((0, 3, 3)), n
    lift = c + PAINT_GAP * n
    pts = lift[None] + poly[:, :1] * u + poly[:, 1:] * v
    m = len(pts)
    tris = np.stack([np.repeat(lift[None], m, 0), pts, np.roll(pts, -1, 0)], 1)  # a fan from the hit
    return tris, n


def cabin_for(spec):
    """The cabin (motion/cabin.py) of vehicle ``spec`` in the body frame on the ground."""
    return cabin_of(spec, 0.0)


def flash_geometry(events, ages, positions, headings, eye, px_per_rad: float):
    """The flashes of ``events`` (body frame) ``ages`` seconds old, on vehicles at ``positions`` (N, 3) with
    ``headings`` (N,) (the frame's poses of each event's vehicle, local frame): (centres (N, 3), radii (N,),
    colours (N, 3)) of the cores and the sparks as segments (N * RAYS, 2, 3) with their colours (N * RAYS, 3),
    all float32."""
    n = len(events)
    if not n:
        return (np.empty((0, 3), np.float32), np.empty(0, np.float32), np.empty((0, 3), np.float32),
                np.empty((0, 2, 3), np.float32), np.empty((0, 3), np.float32))
    p = body_to_local(events["point"], positions, headings)
    nrm = body_to_local(events["normal"], np.zeros((n, 3)), headings)
    u = np.clip(np.asarray(ages, np.float64) / FLASH_S, 0.0, 1.0)
    dist = np.maximum(np.linalg.norm(p - np.asarray(eye, np.float64), axis=1), 0.05)
    per_m = dist / float(px_per_rad)  # metres per pixel at the hit's distance
    glow = 1.0 - u  # fades out
    core = np.maximum(FLASH_M, FLASH_PX * per_m) * (1.0 - 0.6 * u)
    centres = p + 0.5 * core[:, None] * nrm  # a little off the surface, so the body does not hide it
    hot = np.array([HOT, HOT, 0.85 * HOT])  # GGUI shades particles (colour x light): over 1 saturates to white
    cols = hot[None] * (0.35 + 0.65 * glow[:, None])
    # sparks: RAYS directions in the surface's plane, spreading with age
    t1 = np.cross(nrm, np.array([0.0, 0.0, 1.0]))
    flat = np.linalg.norm(t1, axis=1) < 1e-6
    t1[flat] = np.cross(nrm[flat], np.array([1.0, 0.0, 0.0]))
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    ang = np.arange(RAYS) * 2.0 * math.pi / RAYS + events["rock"][:, None] * 0.7  # (n, RAYS)
    d = np.cos(ang)[..., None] * t1[:, None] + np.sin(ang)[..., None] * t2[:, None] + 0.6 * nrm[:, None]
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    reach = np.maximum(RAY_M, RAY_PX * per_m) * (0.35 + 0.65 * u)  # (n,)
    a = centres[:, None] + (0.3 * reach)[:, None, None] * d
    b = centres[:, None] + reach[:, None, None] * d
    segs = np.stack([a, b], axis=2).reshape(-1, 2, 3)
    spark = np.array([1.0, 0.85, 0.45])
    seg_cols = np.repeat(spark[None] * (0.4 + 0.6 * glow[:, None]), RAYS, axis=0)
    return (centres.astype(np.float32), core.astype(np.float32), cols.astype(np.float32),
            segs.astype(np.float32), seg_cols.astype(np.float32))
