"""Flying rocks as tumbling rock meshes, not spheres.

A flying rock in view whose projected radius is at least :data:`MESH_PX` pixels is drawn as one of
:data:`PROTOTYPES` low-poly rocks (motion/rockshapes.py ``rock_prototype``, the shapes of the export's
instances: 80 flat-shaded triangles; below :data:`FINE_PX` pixels the same rock on 20 triangles), chosen by a
hash of its id (config/streams.py LOOK_PROTOTYPE), scaled by its radius and turned by its orientation
(engine/tumble.py, read through engine/drawing.py ``listed_orientation``). The rock pass (render/splat.py
``rocks_pass``) compacts such rocks into a :class:`MeshBucket` (centre, radius, orientation, colour,
prototype; one list per level of detail); :func:`expand` then writes every one's triangles into the bucket's
vertex buffers, which GGUI draws as one mesh per level. GGUI 1.7.4's ``mesh_instance`` lights the
untransformed mesh (see render/vehicles.py), so the vertices and normals are transformed here rather than by
instance matrices, and its Python wrapper repacks the whole vertex field into a new buffer of its layout every
frame (its capacity, not the rocks drawn: 10-20 ms at 720p on lavapipe), so the buffers are written here in
that layout and handed over cut to the rocks drawn (render/culling.py ``RockLayer._declare_meshes``):

    p' = c + r R(q) p,    n' = R(q) n,    R(q) p = p + 2 w (v x p) + 2 v x (v x p)    for q = (v, w), |q| = 1.

Smaller rocks stay GGUI particles: below a couple of pixels a sphere and a stone look alike, and a mesh that
small would fall between pixel centres. The flying rocks in view of the default scene are a few hundred at 720p
(about 550, 460 of them from 1.5 pixels, 50 from 6): lavapipe's cost is in the triangles, hence the coarse
level for the many small ones.

Without orientations (a Simulation built without tumbling: config/plan.py ``spin_on``) there is nothing to turn
the meshes by: the rock pass compiles them out (a :class:`MeshBucket` with ``on=False``) and every flying rock
is a particle, as before. A stone that lands goes from its mesh to the splat of the resting rocks
(render/rocklook.py ``rock_shape``: an outline of the same size, not the same silhouette).
"""

import numpy as np
import taichi as ti

from ..config.streams import LOOK_PROTOTYPE
from ..engine.trees import FieldTrees
from ..motion.rockshapes import flat_triangles
from .rocklook import _unit
from .vbo import VBO_STRIDE, host_buffer

__all__ = ["MESH_PX", "FINE_PX", "PROTOTYPES", "VERTICES", "LODS", "MeshBucket", "Prototypes", "prototype_of",
           "rotate", "expand", "shared_prototypes"]

MESH_PX = 1.5  # flying rocks at least this many pixels in radius are meshes, smaller ones particles
FINE_PX = 5.0  # from this many pixels on, the 80-triangle prototype; below it the 20-triangle one
PROTOTYPES = 8  # rock shapes the renderer draws (variants 0 .. 7 of rock_prototype)
FINE, COARSE = 0, 1  # the levels of detail
VERTICES = (240, 60)  # per rock and level: 80 or 20 triangles, 3 points each (flat shading)
LODS = 2


@ti.data_oriented
class Prototypes:
    """The prototypes' triangles, flat, per level of detail: ``pos[lod]``, ``nrm[lod]`` (PROTOTYPES x
    VERTICES[lod] points and normals, f32)."""

    def __init__(self):
        self.pos, self.nrm = [], []
        self._trees = FieldTrees(owner=self)
        for lod in range(LODS):
            pos, nrm = zip(*(flat_triangles(k, coarse=lod == COARSE) for k in range(PROTOTYPES)))
            assert all(len(p) == VERTICES[lod] for p in pos)
            for out, data in ((self.pos, pos), (self.nrm, nrm)):
                f = self._trees.vector(3, ti.f32, PROTOTYPES * VERTICES[lod])
                f.from_numpy(np.concatenate(data))
                out.append(f)


_SHARED: dict = {}


def shared_prototypes() -> "Prototypes":
    """The process's one :class:`Prototypes` for the running Taichi runtime: the triangles never change, and
    building their fields again for every Renderer (from_numpy into new fields) crashed Taichi 1.7.4 after
    many Renderers and Worlds in one process (a segfault in the copy's kernel launch)."""
    prog = id(ti.lang.impl.get_runtime().prog)
    if _SHARED.get("prog") != prog:
        _SHARED.update(prog=prog, protos=Prototypes())
    return _SHARED["protos"]


@ti.data_oriented
class MeshBucket:
    """At most ``cap`` rocks per level of detail drawn as meshes: their centres, radii, orientations, colours and
    prototypes (level l's at l cap .. l cap + count[l] - 1), and per level the vertex buffer of their triangles,
    ``vbo[l]``: VERTICES[l] points per rock in the layout GGUI draws from (:data:`VBO_STRIDE` float32: position,
    normal, texture coordinates, colour RGBA), host memory that GGUI reads without a copy of its own.
    ``on=False``: a placeholder for a simulation without orientations (the rock pass compiles the meshes out)."""

    def __init__(self, cap: int, on: bool = True, trees: FieldTrees = None):
        self.cap = int(cap)  # read at compile time
        self.on = bool(on)  # read at compile time: False, a placeholder the rock pass never writes
        n = LODS * cap
        t = FieldTrees.given(trees, self)
        self.pos = t.vector(3, ti.f32, n)
        self.rad = t.scalar(ti.f32, n)
        self.quat = t.vector(4, ti.f32, n)
        self.col = t.vector(3, ti.f32, n)
        self.proto = t.scalar(ti.i32, n)
        self.vbo = [host_buffer((cap * v, VBO_STRIDE)) for v in VERTICES]

    def vertices(self, lod: int, n: int) -> np.ndarray:
        """The vertex buffer of level ``lod``'s first ``n`` rocks (a view)."""
        return self.vbo[lod][:n * VERTICES[lod]]


@ti.func
def prototype_of(rid):
    """Which prototype rock ``rid`` is drawn as (stable across frames)."""
    return ti.min(ti.cast(_unit(rid, LOOK_PROTOTYPE.first) * PROTOTYPES, ti.i32), PROTOTYPES - 1)


@ti.func
def rotate(q, p):
    """R(q) p for a unit quaternion q = (x, y, z, w)."""
    v = ti.Vector([q[0], q[1], q[2]])
    t = 2.0 * v.cross(p)
    return p + q[3] * t + v.cross(t)


@ti.func
def put(mb: ti.template(), count, p, r, pr, q, col, rid):
    """Append one rock of ``pr`` pixels to its level's list (``count``: the two counters; a count may exceed the
    capacity: the caller then draws again with a bigger bucket)."""
    lod = FINE if pr >= FINE_PX else COARSE
    j = ti.atomic_add(count[lod], 1)
    if j < mb.cap:
        k = lod * mb.cap + j
        mb.pos[k] = p
        mb.rad[k] = r
        mb.quat[k] = q
        mb.col[k] = col
        mb.proto[k] = prototype_of(rid)


@ti.func
def _write(mb: ti.template(), pos: ti.template(), nrm: ti.template(), vbo: ti.template(), lod: ti.template(), n):
    nv = ti.static(VERTICES[lod])
    for j, k in ti.ndrange(n, nv):
        i = lod * mb.cap + j
        q = mb.quat[i]
        q = q / ti.max(q.norm(), 1e-12)
        src = mb.proto[i] * nv + k
        out = j * nv + k
        p = mb.pos[i] + mb.rad[i] * rotate(q, pos[src])
        nn = rotate(q, nrm[src])
        c = mb.col[i]
        for a in ti.static(range(3)):
            vbo[out, a] = p[a]
            vbo[out, 3 + a] = nn[a]
            vbo[out, 8 + a] = c[a]
        vbo[out, 11] = 1.0


@ti.kernel
def expand(mb: ti.template(), protos: ti.template(), n_fine: ti.i32, n_coarse: ti.i32,
           fine: ti.types.ndarray(dtype=ti.f32, ndim=2), coarse: ti.types.ndarray(dtype=ti.f32, ndim=2)):
    """The triangles of the bucket's rocks into its vertex buffers (``fine``, ``coarse``: ``mb.vbo``), per level
    (module docstring)."""
    _write(mb, protos.pos[FINE], protos.nrm[FINE], fine, FINE, n_fine)
    _write(mb, protos.pos[COARSE], protos.nrm[COARSE], coarse, COARSE, n_coarse)
