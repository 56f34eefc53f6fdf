"""Hits drawn (GGUI): the flashes of the impacts and the marks they leave on windscreens, from render/marks.py's
state of the impacts seen so far.

Each frame the renderer hands this layer the simulation (:meth:`HitLayer.update`: its ``impacts()`` since the
last frame, into :class:`.marks.Hits`, whose time going back forgets the hits after it) and then has it declare
its renderables (:meth:`HitLayer.draw`): the flashes' cores as GGUI particles (lit spheres, in hot colours) and
their sparks as GGUI lines (unlit, SPARK_PX pixels wide), and every vehicle's marks as one mesh: the windscreen
marks as ribbons on the glass (render/marks.py ``glass_ribbons``: MARK_PX pixels wide, clipped to the glass, so
no pixel of a mark falls off it), GLASS_GAP off it on the camera's side (inside the cabin from the
driver's seat, where the glass is not drawn; outside otherwise), and the paint chips on the bonnet and the front
(render/marks.py ``paint_chip``). A mesh is depth-tested and lit like the bodies (GGUI: colour * (ambient + sun *
max(n . l, 0))): the glass's marks face the sun (n = the sun's direction, l about that) and are given MARK_COLOR
/ (ambient + sun), so a crack reads the same pale colour in any light, as light scattered in the glass; a paint
chip is lit as the face it lies on.

Nothing is allocated or declared before a first hit: a run without impacts draws what it drew before. Buffers
grow in powers of two; past MAX_SEGMENTS mark segments the oldest marks are left out.
"""

from __future__ import annotations

import math

import numpy as np
import taichi as ti

from ..engine.trees import FieldTrees, Pool
from .looks import AMBIENT, SUN_COLOR
from .marks import Hits, body_faces, body_to_local, cabin_for, flash_geometry, glass_ribbons, to_body_frame

__all__ = ["HitLayer", "MARK_COLOR", "PAINT_CHIP_COLOR", "MARK_PX", "SPARK_PX", "MAX_TRIANGLES"]

MARK_COLOR = (0.93, 0.95, 0.97)  # a crack or a chip scatters light: pale, nearly white
PAINT_CHIP_COLOR = (0.60, 0.60, 0.58)  # chipped paint: the grey primer and metal under it
MARK_PX = 2.0  # pixels: the width of a mark's ribbons (where the glass's margin allows)
SPARK_PX = 3.0
MAX_TRIANGLES = 1 << 16  # past this many, the oldest marks of a vehicle are left out


class _Fields:
    """A hit buffer's fields for ``cap`` entries: positions, colours, (``rad``) radii and (``mesh``) normals and
    one model matrix (the identity: a mesh drawn as an instance, see render/renderer.py), leased from
    :data:`_POOL` by the size (engine/trees.py Pool): the next buffer of that size uploads into them with its
    copies compiled. Only the first count entries of an upload are drawn, and every upload writes every entry."""

    def __init__(self, cap: int, rad: bool, mesh: bool = False):
        self.trees, self.owner = FieldTrees(), None
        self.pos, self.col = self.trees.vector(3, ti.f32, cap), self.trees.vector(3, ti.f32, cap)
        self.rad = self.trees.scalar(ti.f32, cap) if rad else None
        self.nrm = self.trees.vector(3, ti.f32, cap) if mesh else None
        self.model = self.trees.matrix(4, 4, ti.f32, 1) if mesh else None
        if mesh:
            self.model.from_numpy(np.eye(4, dtype=np.float32)[None])


_POOL = Pool()


class _Buffer:
    """A GGUI vertex buffer and its colours that grows in powers of two (at least 64 entries); ``mesh``: with
    normals and a model matrix."""

    def __init__(self, mesh: bool = False):
        self._f = None  # its fields, leased from the pool (given back when the buffer grows or closes)
        self._colours = None  # the key of the colours uploaded, if the caller gave one
        self._normals = None  # the same for the normals
        self._mesh = bool(mesh)

    pos = property(lambda self: self._f.pos)
    col = property(lambda self: self._f.col)
    rad = property(lambda self: self._f.rad)
    nrm = property(lambda self: self._f.nrm)
    model = property(lambda self: self._f.model)

    def put(self, pos: np.ndarray, col: np.ndarray, rad: np.ndarray = None, colour_key=None,
            nrm: np.ndarray = None, normal_key=None) -> int:
        """Upload ``pos``, ``col`` (skipped if ``colour_key`` is that of the last upload: an upload is a launch),
        ``rad`` and ``nrm`` (skipped likewise for ``normal_key``); return the count."""
        n = len(pos)
        if self._f is None or self.pos.shape[0] < n:
            self._colours = self._normals = None
            cap = 64
            while cap < n:
                cap *= 2
            self.close()
            key, mesh = ("hits", cap, rad is not None, self._mesh), self._mesh
            self._f = _POOL.lease(self, key, lambda: _Fields(cap, rad is not None, mesh))
        cap = self.pos.shape[0]
        pad = lambda a, shape: np.concatenate([a, np.zeros((cap - n,) + shape, np.float32)]).astype(np.float32)
        self.pos.from_numpy(pad(pos, (3,)))
        if colour_key is None or colour_key != self._colours:
            self.col.from_numpy(pad(col, (3,)))
            self._colours = colour_key
        if rad is not None:
            self.rad.from_numpy(pad(rad, ()))
        if nrm is not None and (normal_key is None or normal_key != self._normals):
            self.nrm.from_numpy(pad(nrm, (3,)))
            self._normals = normal_key
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
        self._cabins, self._faces = {}, {}
        self._cores, self._sparks, self._marks = _Buffer(), _Buffer(), _Buffer(mesh=True)

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

    def _body_faces(self, i: int):
        if i not in self._faces:
            self._faces[i] = body_faces(self._specs[i])
        return self._faces[i]

    def draw(self, scene, poses, origin, eye, px_per_rad: float, radius_scale: float, inside=None,
             sun=(0.0, 0.0, 1.0)) -> None:
        """Declare the frame's flashes and marks in GGUI ``scene``: ``poses`` the vehicles' (world), ``origin``
        the local frame's, ``eye`` the camera (local), ``px_per_rad`` its pixels per radian, ``radius_scale`` the
        particle size correction (render/renderer.py), ``inside`` the vehicle whose cabin the camera looks out
        of (or None), ``sun`` the unit vector towards the sun (the marks on glass face it)."""
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
        self._draw_marks(scene, pos, head, inside, eye, px_per_rad, sun)

    def _draw_marks(self, scene, pos, head, inside, eye, px_per_rad, sun) -> None:
        """Every vehicle's marks as one mesh: the glass's ribbons first, then the paint chips (see the module
        docstring)."""
        glass, paint, paint_n = [], [], []
        for i in np.unique(self.hits.marks()["vehicle"]):
            i = int(i)
            at = lambda p: body_to_local(p.reshape(-1, 3), np.repeat(pos[i][None], p.size // 3, 0),
                                         np.full(p.size // 3, head[i]))
            cab = self._cabin(i)
            s = self.hits.windscreen_segments(i, cab)
            if len(s):
                c, sn = math.cos(head[i]), math.sin(head[i])
                e = np.asarray(eye, np.float64) - pos[i]
                eye_body = (c * e[0] + sn * e[1], -sn * e[0] + c * e[1], e[2])
                t = glass_ribbons(s, cab, inside == i, eye_body, px_per_rad, MARK_PX)
                glass.append(at(t).reshape(-1, 3, 3))
            t, tn = self.hits.paint_chips(i, self._body_faces(i))
            if len(t):
                paint.append(at(t).reshape(-1, 3, 3))
                paint_n.append(np.repeat(at(tn) - at(np.zeros_like(tn)), 3, 0))
        g = np.concatenate(glass)[-MAX_TRIANGLES:] if glass else np.empty((0, 3, 3))
        p = np.concatenate(paint)[-(MAX_TRIANGLES - len(g)):] if paint and len(g) < MAX_TRIANGLES \
            else np.empty((0, 3, 3))
        if not len(g) and not len(p):
            return
        lit = np.array(MARK_COLOR) / (np.array(AMBIENT) + np.array(SUN_COLOR))  # facing the sun: MARK_COLOR
        ng, npaint = 3 * len(g), 3 * len(p)
        cols = np.concatenate([np.tile(lit, (ng, 1)), np.tile(PAINT_CHIP_COLOR, (npaint, 1))])
        nrms = np.concatenate([np.tile(np.asarray(sun, np.float64), (ng, 1)),
                               np.concatenate(paint_n)[-npaint:] if npaint else np.empty((0, 3))])
        # the normals change with the sun and the headings, and with the chips drawn (the colours with the counts)
        marks = self.hits.marks()
        same = (ng, npaint, tuple(np.asarray(sun, np.float64).tolist()), tuple(np.asarray(head).tolist()),
                marks["step"].tobytes(), marks["rock"].tobytes())
        n = self._marks.put(np.concatenate([g, p]).reshape(-1, 3), cols, colour_key=(ng, npaint), nrm=nrms,
                            normal_key=same)
        m = self._marks
        scene.mesh_instance(m.pos, normals=m.nrm, per_vertex_color=m.col, transforms=m.model, vertex_count=n)
