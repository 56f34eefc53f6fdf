"""Hits drawn (GGUI): the flashes of the impacts and the marks they leave on windscreens, from render/marks.py's
state of the impacts seen so far.

Each frame the renderer hands this layer the simulation (:meth:`HitLayer.update`: its ``impacts()`` since the
last frame, into :class:`.marks.Hits`, whose time going back forgets the hits after it) and then has it declare
its renderables (:meth:`HitLayer.draw`): the flashes' cores as GGUI particles (lit spheres, in hot colours) and
their sparks as GGUI lines, and every vehicle's windscreen marks as lines lying GLASS_GAP off the glass on the
camera's side (inside the cabin from the driver's seat, where the glass is not drawn; outside otherwise).
Lines are drawn unlit, at a width in pixels (MARK_PX, SPARK_PX), so a mark reads the same in any light.

Nothing is allocated or declared before a first hit: a run without impacts draws what it drew before. Buffers
grow in powers of two; past MAX_SEGMENTS mark segments the oldest marks are left out.
"""

from __future__ import annotations

import numpy as np
import taichi as ti

from ..engine.trees import FieldTrees, Pool
from .marks import Hits, body_to_local, cabin_for, flash_geometry, glass_side, to_body_frame

__all__ = ["HitLayer", "MARK_COLOR", "MARK_PX", "SPARK_PX", "MAX_SEGMENTS"]

MARK_COLOR = (0.93, 0.95, 0.97)  # a crack or a chip scatters light: pale, nearly white
MARK_PX = 2.0  # pixels: the width of a mark's lines
SPARK_PX = 3.0
MAX_SEGMENTS = 1 << 15


class _Fields:
    """A hit buffer's fields for ``cap`` entries: positions, colours and (``rad``) radii, leased from
    :data:`_POOL` by the size (engine/trees.py Pool): the next buffer of that size uploads into them with its
    copies compiled. Only the first count entries of an upload are drawn, and every upload writes every entry."""

    def __init__(self, cap: int, rad: bool):
        self.trees, self.owner = FieldTrees(), None
        self.pos, self.col = self.trees.vector(3, ti.f32, cap), self.trees.vector(3, ti.f32, cap)
        self.rad = self.trees.scalar(ti.f32, cap) if rad else None


_POOL = Pool()


class _Buffer:
    """A GGUI vertex buffer and its colours that grows in powers of two (at least 64 entries)."""

    def __init__(self):
        self._f = None  # its fields, leased from the pool (given back when the buffer grows or closes)
        self._colours = None  # the key of the colours uploaded, if the caller gave one

    pos = property(lambda self: self._f.pos)
    col = property(lambda self: self._f.col)
    rad = property(lambda self: self._f.rad)

    def put(self, pos: np.ndarray, col: np.ndarray, rad: np.ndarray = None, colour_key=None) -> int:
        """Upload ``pos``, ``col`` (skipped if ``colour_key`` is that of the last upload: an upload is a launch)
        and ``rad``; return the count."""
        n = len(pos)
        if self._f is None or self.pos.shape[0] < n:
            self._colours = None
            cap = 64
            while cap < n:
                cap *= 2
            self.close()
            self._f = _POOL.lease(self, ("hits", cap, rad is not None), lambda: _Fields(cap, rad is not None))
        cap = self.pos.shape[0]
        pad = lambda a, shape: np.concatenate([a, np.zeros((cap - n,) + shape, np.float32)]).astype(np.float32)
        self.pos.from_numpy(pad(pos, (3,)))
        if colour_key is None or colour_key != self._colours:
            self.col.from_numpy(pad(col, (3,)))
            self._colours = colour_key
        if rad is not None:
            self.rad.from_numpy(pad(rad, ()))
        return n

    def close(self) -> None:
        if self._f is not None:
            _POOL.give_back(self._f, self)
        self._f = None


class HitLayer:
    """The hits of one renderer's simulation (``hits``: render/marks.py Hits) and their GGUI buffers."""

    def __init__(self, scene):
        self.hits = Hits.of_scene(scene)
        follow = getattr(scene.bed, "follow", None) or scene.vehicles[0].name
        self.player = scene.vehicle_index(follow)  # the vehicle the HUD counts the hits of
        self._specs = scene.vehicles
        self._cabins = {}
        self._cores, self._sparks, self._marks = _Buffer(), _Buffer(), _Buffer()

    def close(self) -> None:
        """Retire the GGUI buffers' fields (engine/trees.py)."""
        for b in (self._cores, self._sparks, self._marks):
            b.close()

    def update(self, sim) -> int:
        """Take ``sim``'s impacts since the last frame (none without impacts); the clock is ``sim.time``."""
        events = sim.impacts() if sim.plan.impacts else ()
        if len(events):
            events = to_body_frame(events, float(sim.scene.world.ground_z) - float(sim.origin[2]))
        return self.hits.update(events if len(events) else self.hits.events[:0], sim.time)

    def counts(self) -> dict:
        """The player's hits so far by damage class (the view's HUD)."""
        return self.hits.counts(self.player)

    def _cabin(self, i: int):
        if i not in self._cabins:
            self._cabins[i] = cabin_for(self._specs[i])
        return self._cabins[i]

    def draw(self, scene, poses, origin, eye, px_per_rad: float, radius_scale: float, inside=None) -> None:
        """Declare the frame's flashes and marks in GGUI ``scene``: ``poses`` the vehicles' (world), ``origin``
        the local frame's, ``eye`` the camera (local), ``radius_scale`` the particle size correction
        (render/renderer.py), ``inside`` the vehicle whose cabin the camera looks out of (or None)."""
        hits = self.hits
        if not len(hits.events):
            return
        pos = np.array([np.asarray(p.position, np.float64) - origin for p in poses])
        head = np.array([p.heading for p in poses], np.float64)
        ev, age = hits.flashing(hits.t)
        if len(ev):
            v = ev["vehicle"]
            c, r, col, seg, seg_col = flash_geometry(ev, age, pos[v], head[v], eye, px_per_rad)
            n = self._cores.put(c, col, r * radius_scale)
            scene.particles(self._cores.pos, 0.02, per_vertex_color=self._cores.col,
                            per_vertex_radius=self._cores.rad, index_count=n)
            n = self._sparks.put(seg.reshape(-1, 3), np.repeat(seg_col, 2, axis=0))
            scene.lines(self._sparks.pos, SPARK_PX, per_vertex_color=self._sparks.col, vertex_count=n)
        self._draw_marks(scene, pos, head, inside)

    def _draw_marks(self, scene, pos, head, inside) -> None:
        segs = []
        for i in np.unique(self.hits.marks()["vehicle"]):
            cab = self._cabin(int(i))
            s = glass_side(self.hits.windscreen_segments(int(i), cab), cab, inside == int(i))
            if len(s):
                k = len(s) * 2
                segs.append(body_to_local(s.reshape(-1, 3), np.repeat(pos[i][None], k, 0), np.full(k, head[i])))
        if not segs:
            return
        pts = np.concatenate(segs)[-2 * MAX_SEGMENTS:]
        n = self._marks.put(pts, np.tile(np.array(MARK_COLOR, np.float32), (len(pts), 1)), colour_key=len(pts))
        scene.lines(self._marks.pos, MARK_PX, per_vertex_color=self._marks.col, vertex_count=n)
