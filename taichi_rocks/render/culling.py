"""The rocks of a frame, host side: the rock pass (render/splat.py :func:`.splat.rocks_pass`) run over buckets
big enough for what it compacts, and the rocks it left for GGUI declared in the 3D layer; offscreen in two parts,
the compaction before GGUI draws and the splats after (render/splat.py).

The pass culls every rock to the view; in "splat" mode the resting ones go into the background layer's buffers,
and what GGUI draws is compacted by an atomic counter into a bucket of a power-of-two capacity: flying rocks of
MESH_PX pixels and more as oriented rock meshes (render/tumbling.py, if the simulation tumbles its rocks), the
others as particles. The count may pass the capacity: the pass then runs again with a bucket that holds it
(buckets start at the last frame's count plus a quarter, so that happens when the spray grows).
"""

from __future__ import annotations

import numpy as np
import taichi as ti

from ..engine import drawing
from . import kernels as K
from .buffers import bucket, mesh_bucket
from .looks import AMBIENT, SUN_COLOR
from .settings import camera_basis, vec
from .splat import ALL, SPLAT, Pass, rocks_pass
from .sunlight import shade_of
from .tumbling import expand, shared_prototypes
from .vbo import declare_mesh, host_buffer

__all__ = ["RockLayer"]


class RockLayer:
    """The rocks of one renderer (``n_rocks`` of them) in its buffers ``fields`` (render/buffers.py
    FrameFields). ``last_count``: rocks the last pass compacted for GGUI particles, ``last_meshes``: rock meshes
    (the most of a level of detail), ``tiles_in_view``: tiles of the store the last pass visited (active
    stepping; 0 without a store), ``drawn``: (bucket, count, mesh bucket, meshes per level) of the last pass."""

    def __init__(self, fields, n_rocks: int, oriented: bool):
        self.fields = fields
        self.n_rocks = int(n_rocks)
        self.protos = shared_prototypes() if oriented else None
        self.drawn = None
        self.last_count = 0
        self.last_meshes = 0
        self.tiles_in_view = 0
        self.identity = host_buffer((1, 4, 4))  # one identity model matrix, as GGUI's wrapper hands it over
        self.identity[0] = np.eye(4, dtype=np.float32)

    def cull(self, sim, settings, views, eye, fwd, right, up, sun, part: int = ALL) -> int:
        """Cull ``sim``'s rocks to the view (``eye`` and the basis; ``sun``: towards the sun); splat the resting
        ones ("splat" mode) and compact those GGUI draws into a bucket. Return how many GGUI draws. ``part``
        (render/splat.py): ALL of it, or only the compaction (COMPACT), or then only the splats (SPLAT: not into
        the pixels GGUI drew, ``buffers.cover``; the buckets of the COMPACT part before)."""
        n = self.n_rocks
        if n == 0:
            self.drawn, self.last_count = None, 0
            return 0
        w, h = settings.resolution
        cam = camera_basis(eye, fwd, right, up)
        size = K.Sizing(lod_px=settings.lod_pixels, radius_scale=h / w)  # GGUI 1.7.4 draws particles w/h too large
        light = K.Light(sun=vec(sun), ambient=ti.Vector(AMBIENT), sun_color=ti.Vector(SUN_COLOR))
        shade = shade_of(sun, views.ground_z - float(sim.origin[2]))
        step = Pass(tiles=ti.Vector([float(x) for x in sim.tile_shift()]), part=part)
        frustum, f = views.frustum(settings.draw_distance), self.fields
        if part == SPLAT:
            rocks, count, meshes, n_meshes = self.drawn
            rocks_pass(sim.world, f.buf, rocks, meshes, cam, frustum, size, light, shade, f.visible, step)
            self.tiles_in_view = int(f.visible.count[None]) if drawing.has_tiles(sim.world) else 0
            return count + sum(n_meshes)
        self.drawn = None
        need = max(int(self.last_count * 1.25), 1)
        need_meshes = max(self.last_meshes, 1)
        oriented = drawing.has_orientations(sim.world)
        while True:
            rocks, meshes = bucket(f, need, n), mesh_bucket(f, need_meshes, n, oriented)
            rocks_pass(sim.world, f.buf, rocks, meshes, cam, frustum, size, light, shade, f.visible, step)
            count = int(f.buf.count[None])
            n_meshes = tuple(int(c) for c in f.buf.mesh_count.to_numpy())  # per level of detail
            if count <= rocks.cap and max(n_meshes) <= meshes.cap:
                break
            need, need_meshes = max(count, need), max(max(n_meshes), need_meshes)
            if part == ALL and (settings.rocks == "splat" or settings.shadows):  # splats in the buffers: clear them
                K.clear_buffers(f.buf)
        if any(n_meshes):
            if self.protos is None:
                self.protos = shared_prototypes()
            expand(meshes, self.protos, *n_meshes, *meshes.vbo)
        self.last_count, self.last_meshes = count, max(n_meshes)
        if part == ALL:
            self.tiles_in_view = int(f.visible.count[None]) if drawing.has_tiles(sim.world) else 0
        self.drawn = (rocks, count, meshes, n_meshes)
        return count + sum(n_meshes)

    def declare(self, scene) -> None:
        """Declare the rocks of the last pass in GGUI ``scene``: particles, then meshes."""
        if self.drawn is None:
            return
        rocks, count, meshes, n_meshes = self.drawn
        if count > 0:
            scene.particles(rocks.pos, 0.03, per_vertex_color=rocks.col, per_vertex_radius=rocks.rad,
                            index_count=count)
        self._declare_meshes(scene, meshes, n_meshes)

    def _declare_meshes(self, scene, meshes, counts) -> None:
        """The flying rocks' meshes (:mod:`.tumbling`), a mesh per level of detail, their vertices transformed in
        a kernel and already in GGUI's layout: handed to GGUI's own scene as the wrapper's ``mesh_instance``
        would (one identity instance; see render/renderer.py), minus its repacking of the whole field."""
        for lod, n in enumerate(counts):
            if n > 0:
                declare_mesh(scene, meshes.vertices(lod, n), self.identity)
