"""Hits drawn (GGUI): the flashes of the impacts and the marks they leave, from render/marks.py's state of the
impacts seen so far.

Each frame the renderer hands this layer the simulation (:meth:`HitLayer.update`: its ``impacts()`` since the
last frame, into :class:`.marks.Hits`, whose time going back hides the hits after it) and then has it declare
its renderables (:meth:`HitLayer.draw`): the flashes' cores as GGUI particles (lit spheres, in hot colours) and
their sparks as GGUI lines (unlit, SPARK_PX pixels wide), made anew each frame (render/flashes.py: a flash
lasts a few frames), and the marks: each windscreen mark and paint chip made once, when its hit first shows
(render/markstore.py), uploaded once (render/markmesh.py) and posed with its vehicle each frame by a kernel, all
in one mesh. What a frame costs here is what is new, and a parallel pass over the marks shown.

Nothing is allocated or declared before a first hit: a run without impacts draws what it drew before.
"""

from __future__ import annotations

import numpy as np
import taichi as ti

from ..engine.trees import FieldTrees, Pool
from .flashes import flash_geometry
from .markmesh import MarkMesh, Sight, body_bounds
from .marks import Hits, to_body_frame
from .markstore import MarkStore

__all__ = ["HitLayer", "SPARK_PX"]

SPARK_PX = 3.0


class _Fields:
    """A flash buffer's fields for ``cap`` entries: positions, colours and (``rad``) radii, leased from
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

    pos = property(lambda self: self._f.pos)
    col = property(lambda self: self._f.col)
    rad = property(lambda self: self._f.rad)

    def put(self, pos: np.ndarray, col: np.ndarray, rad: np.ndarray = None) -> int:
        """Upload ``pos``, ``col`` and ``rad``; return the count."""
        n = len(pos)
        if self._f is None or self.pos.shape[0] < n:
            cap = 64
            while cap < n:
                cap *= 2
            self.close()
            self._f = _POOL.lease(self, ("hits", cap, rad is not None), lambda: _Fields(cap, rad is not None))
        cap = self.pos.shape[0]
        pad = lambda a, shape: np.concatenate([a, np.zeros((cap - n,) + shape, np.float32)]).astype(np.float32)
        self.pos.from_numpy(pad(pos, (3,)))
        self.col.from_numpy(pad(col, (3,)))
        if rad is not None:
            self.rad.from_numpy(pad(rad, ()))
        return n

    def close(self) -> None:
        if self._f is not None:
            _POOL.give_back(self._f, self)
        self._f = None


class HitLayer:
    """The hits of one renderer's simulation (``hits``: render/marks.py Hits), their marks (``store``:
    render/markstore.py MarkStore; ``mesh``: render/markmesh.py MarkMesh, made with the first mark) and the
    flashes' GGUI buffers."""

    def __init__(self, scene):
        self.hits = Hits.of_scene(scene)
        follow = getattr(scene.bed, "follow", None) or scene.vehicles[0].name
        self.player = scene.vehicle_index(follow)  # the vehicle the HUD counts the hits of
        self.store = MarkStore(scene.vehicles)
        self._vehicles = scene.vehicles
        self.mesh = None
        self._cores, self._sparks = _Buffer(), _Buffer()

    def close(self) -> None:
        """Retire the flashes' fields (engine/trees.py)."""
        for b in (self._cores, self._sparks):
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

    def draw(self, scene, poses, origin, sight: Sight, radius_scale: float) -> None:
        """Declare the frame's flashes and marks in GGUI ``scene``: ``poses`` the vehicles' (world), ``origin``
        the local frame's, ``sight`` the camera's (render/markmesh.py Sight), ``radius_scale`` the particle size
        correction (render/renderer.py)."""
        hits = self.hits
        if not len(hits.events):
            return
        pos = np.array([np.asarray(p.position, np.float64) - origin for p in poses])
        head = np.array([p.heading for p in poses], np.float64)
        ev, age = hits.flashing(hits.t)
        if len(ev):
            v = ev["vehicle"]
            c, r, col, seg, seg_col = flash_geometry(ev, age, pos[v], head[v], sight.eye, sight.px_per_rad)
            n = self._cores.put(c, col, r * radius_scale)
            scene.particles(self._cores.pos, 0.02, per_vertex_color=self._cores.col,
                            per_vertex_radius=self._cores.rad, index_count=n)
            n = self._sparks.put(seg.reshape(-1, 3), np.repeat(seg_col, 2, axis=0))
            scene.lines(self._sparks.pos, SPARK_PX, per_vertex_color=self._sparks.col, vertex_count=n)
        self.store.sync(hits)
        shown = self.store.shown(hits.t)
        if not shown.glass and not shown.chips:
            return
        if self.mesh is None:
            self.mesh = MarkMesh(self.store.cabins, body_bounds(self._vehicles))
        self.mesh.upload(self.store)
        self.mesh.draw(scene, shown, pos, head, sight)
