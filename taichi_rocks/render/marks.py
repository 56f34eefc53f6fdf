"""Hits you can see, host side (NumPy, no Taichi calls): the impacts seen so far, kept by time so that going back
in time hides them again, and what the marks' shapes share.

State (:class:`Hits`): the events (engine/events.py ``EVENT_DTYPE``) the simulation reported, their points moved
into the body frame the renderer draws in (motion/bodies.py: on the ground, :func:`to_body_frame`), in time
order, and the time of the frame shown. :meth:`Hits.update` adds a frame's events and sets that time (an event
seen again, as after a restore that steps the same steps again, is kept once: its key is (step, rock,
vehicle)). Only the hits up to the time shown count, flash and mark: a scrub back, the view playing round to
frame 0 or a restart hides the later ones, and a scrub forward past a saved state (whose steps are not stepped
again) shows them again, as the run is deterministic. What changes the future (a runtime parameter, a rebuild)
forgets the hits after the time (:meth:`Hits.clear_after`). :meth:`Hits.counts` counts a vehicle's hits by
damage class (config/impacts.py DAMAGE_CLASSES), the view's HUD.

The hits that leave a mark (:meth:`Hits.marks`): chips and cracks on the windscreen (render/glassmarks.py) and
on the painted parts, the bonnet and the front (:data:`PAINTED`; render/paintchips.py). New hits come after the
ones held (the simulation reports them as it steps), so the state grows at its end; every other change (a hit
older than the newest sorted in, hits forgotten) is logged in ``changes``: the first of the hits leaving a mark
that it changed, from which on the marks made of them (render/markstore.py) are made again. Every query of the
time shown is a binary search: a frame costs what is new.

A mark's shape is drawn from a hash of (rock, step) (:func:`mark_rng`), so it is the same in every run, and sized
by its severity s in [0, 1] (:func:`severity`): where the hit's measure (normal energy 1/2 m u_n^2 or normal
momentum m u_n, as [impacts] damage_by) lies in its damage class, log scale.
"""

from __future__ import annotations

import math

import numpy as np

from ..config.impacts import DAMAGE_CLASSES
from ..engine.events import EVENT_DTYPE
from ..motion.bodies import LABELS

__all__ = ["Hits", "to_body_frame", "body_to_local", "severity", "mark_rng", "leaves_mark", "clip_convex",
           "FLASH_S", "WINDSCREEN", "PAINTED", "CHIP", "CRACK", "CRACK_DECADE"]

WINDSCREEN = LABELS.index("windscreen")
PAINTED = tuple(LABELS.index(p) for p in ("bonnet", "front_bumper"))  # parts whose paint a hit chips
MARK, CHIP, CRACK = (DAMAGE_CLASSES.index(c) for c in ("mark", "chip", "crack"))
FLASH_S = 0.13  # s a flash lasts (4 frames at 30 frames/s; render/flashes.py)
CRACK_DECADE = 10.0  # a crack's measure this many times its threshold is the largest crack


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


def leaves_mark(ev: np.ndarray) -> np.ndarray:
    """Per event: does it leave a mark (a chip or a crack on the windscreen or a painted part)?"""
    return ((ev["part"] == WINDSCREEN) | np.isin(ev["part"], PAINTED)) & (ev["damage"] >= CHIP)


class _Rows:
    """Events in a buffer that grows in powers of two: appending costs what is appended."""

    def __init__(self):
        self._buf, self.n = np.empty(64, EVENT_DTYPE), 0

    @property
    def all(self) -> np.ndarray:
        return self._buf[:self.n]

    def append(self, ev: np.ndarray) -> None:
        if self.n + len(ev) > len(self._buf):
            cap = len(self._buf)
            while cap < self.n + len(ev):
                cap *= 2
            self._buf = np.concatenate([self._buf[:self.n], np.empty(cap - self.n, EVENT_DTYPE)])
        self._buf[self.n:self.n + len(ev)] = ev
        self.n += len(ev)

    def set(self, ev: np.ndarray) -> None:
        self.n = 0
        self.append(ev)

    def upto(self, t: float) -> int:
        """How many of them happened at or before time ``t``."""
        return int(np.searchsorted(self.all["time"], t, side="right"))


class Hits:
    """The impacts seen up to time ``t`` (see the module docstring). ``thresholds``: (chip, crack) in the unit of
    ``measure`` ("energy" or "momentum": config/impacts.py ``Impacts.thresholds``), which size the marks."""

    def __init__(self, thresholds=(0.0055, 0.14), measure: str = "energy"):
        self.thresholds = (float(thresholds[0]), float(thresholds[1]))
        self.measure = measure
        self.t = 0.0
        self.changes = []  # per change other than new hits after the newest: the first marked hit it changed
        self._all, self._marked = _Rows(), _Rows()
        self._seen = set()  # the keys of self.events

    @classmethod
    def of_scene(cls, scene) -> Hits:
        return cls(scene.impacts.thresholds(), scene.impacts.damage_by)

    events = property(lambda self: self._all.all, doc="every hit seen, in time order (shown or not)")
    marked = property(lambda self: self._marked.all, doc="the hits of :attr:`events` that leave a mark")

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
        if not len(ev):
            return 0
        ev = ev[np.argsort(ev["time"], kind="stable")]
        if self._all.n and ev["time"][0] < self._all.all["time"][-1]:  # older than the newest: sorted in
            marked = ev[leaves_mark(ev)]
            if len(marked):  # the marked hits after its time come later now
                self.changes.append(self._marked.upto(float(marked["time"][0])))
            every = np.concatenate([self.events, ev])
            self._all.set(every[np.argsort(every["time"], kind="stable")])
            self._marked.set(self.events[leaves_mark(self.events)])
        else:
            self._all.append(ev)
            self._marked.append(ev[leaves_mark(ev)])
        return len(ev)

    def shown(self) -> np.ndarray:
        """The hits up to the time shown."""
        return self.events[:self._all.upto(self.t)]

    def clear_after(self, t: float) -> None:
        """Forget the events after time ``t`` (their future changed: a runtime parameter, a rebuild)."""
        keep = self._all.upto(float(t))
        if keep < self._all.n:
            self._seen -= set(_keys(self.events[keep:]))
            self._all.n = keep
            self._marked.n = self._marked.upto(float(t))
            self.changes.append(self._marked.n)
        self.t = min(self.t, float(t))

    def clear(self) -> None:
        self._all.n = self._marked.n = 0
        self._seen = set()
        self.t = 0.0
        self.changes.append(0)

    def counts(self, vehicle: int) -> dict:
        """Hits on ``vehicle`` so far, by damage class: {"mark": n, "chip": n, "crack": n}."""
        ev = self.shown()
        ev = ev[ev["vehicle"] == int(vehicle)]
        n = np.bincount(ev["damage"].astype(np.int64), minlength=len(DAMAGE_CLASSES))
        return {c: int(n[k]) for k, c in enumerate(DAMAGE_CLASSES)}

    def flashing(self, t: float) -> tuple:
        """(events, ages in s) of the flashes at time ``t``: the hits of the last FLASH_S seconds."""
        ev = self.shown()
        ev = ev[int(np.searchsorted(ev["time"], float(t) - 2.0 * FLASH_S)):]  # the rest are long past
        age = float(t) - ev["time"]
        sel = (age >= 0.0) & (age < FLASH_S)
        return ev[sel], age[sel]

    def marks(self) -> np.ndarray:
        """The hits shown that left a mark: chips and cracks on part "windscreen" (on the glass) and on the
        painted parts (:data:`PAINTED`: the paint chipped)."""
        return self.marked[:self._marked.upto(self.t)]


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


def mark_rng(e) -> np.random.Generator:
    """A generator seeded by the hit (rock, step): the same mark in every run."""
    return np.random.default_rng([int(e["rock"]) & 0xFFFFFFFF, int(e["step"]) & 0xFFFFFFFF, 22])


def clip_convex(poly: np.ndarray, edges) -> np.ndarray:
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
