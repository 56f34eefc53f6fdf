"""Hits drawn (GGUI): the flashes of the impacts and the marks they leave, from render/marks.py's state of the
impacts seen so far.

Each frame the renderer hands this layer the simulation (:meth:`HitLayer.update`: its ``impacts()`` since the
last frame, into :class:`.marks.Hits`, whose time going back hides the hits after it) and then has it declare
its renderables (:meth:`HitLayer.draw`): the flashes' cores as GGUI particles (lit spheres, in hot colours) and
their sparks as GGUI lines (unlit, SPARK_PX pixels wide), made anew each frame (render/flashes.py: a flash
lasts a few frames) straight into GGUI's vertex buffers (render/vbo.py), and the marks: each windscreen mark and
paint chip made once, when its hit first shows (render/markstore.py), uploaded once (render/markmesh.py) and
posed with its vehicle each frame by a kernel, all in one mesh. What a frame costs here is what is new, and a
parallel pass over the marks shown.

Nothing is allocated or declared before a first hit: a run without impacts draws what it drew before.
"""

from __future__ import annotations

import numpy as np

from .flashes import flash_geometry
from .markmesh import MarkMesh, Sight, body_bounds
from .marks import Hits, to_body_frame
from .markstore import MarkStore
from .vbo import VBO_STRIDE, declare_lines, declare_particles, host_buffer

__all__ = ["HitLayer", "SPARK_PX"]

SPARK_PX = 3.0


def _flash_buffer(n: int, user: str) -> np.ndarray:
    """A vertex buffer (render/vbo.py) for ``n`` flash vertices: its first n rows, of a power-of-two capacity."""
    cap = 64
    while cap < n:
        cap *= 2
    return host_buffer((cap, VBO_STRIDE), user)[:n]


class HitLayer:
    """The hits of one renderer's simulation (``hits``: render/marks.py Hits) and their marks (``store``:
    render/markstore.py MarkStore; ``mesh``: render/markmesh.py MarkMesh, made with the first mark)."""

    def __init__(self, scene):
        self.hits = Hits.of_scene(scene)
        follow = getattr(scene.bed, "follow", None) or scene.vehicles[0].name
        self.player = scene.vehicle_index(follow)  # the vehicle the HUD counts the hits of
        self.store = MarkStore(scene.vehicles)
        self._vehicles = scene.vehicles
        self.mesh = None

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
            cores = _flash_buffer(len(c), "flash.cores")
            cores[:, :3], cores[:, 3], cores[:, 8:11], cores[:, 11] = c, r * radius_scale, col, 1.0
            declare_particles(scene, cores)
            sparks = _flash_buffer(2 * len(seg), "flash.sparks")
            sparks[:, :3], sparks[:, 8:11], sparks[:, 11] = seg.reshape(-1, 3), np.repeat(seg_col, 2, axis=0), 1.0
            declare_lines(scene, sparks, SPARK_PX)
        self.store.sync(hits)
        shown = self.store.shown(hits.t)
        if not shown.glass and not shown.chips:
            return
        if self.mesh is None:
            self.mesh = MarkMesh(self.store.cabins, body_bounds(self._vehicles))
        self.mesh.upload(self.store)
        self.mesh.draw(scene, shown, pos, head, sight)
