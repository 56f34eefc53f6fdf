"""A renderer's buffers and their pool: the fields a frame is drawn with, leased by their sizes from one
:class:`~taichi_rocks.engine.trees.Pool` and given back when the renderer closes (or is garbage-collected).

A new set of fields costs seconds of compiling (the rock pass, the ground pass, the uploads and GGUI's copies are
compiled for the fields they touch): the next Renderer of the same sizes on a pooled World (engine/world.py)
takes a free set and starts with its kernels compiled.

:class:`FrameFields`, per resolution, rock mode, shadows and tile store: the background image, splat buffers
and shadows (:class:`.kernels.Buffers`), the tile store's slots in view (:class:`.tiles.Visible`), the compact
buckets of the rocks drawn as particles and as meshes (power-of-two capacities, made when first needed:
:func:`bucket`, :func:`mesh_bucket`), and the overlays' lines. (The vehicles and the marks draw from GGUI's own
vertex buffers, render/vbo.py: no fields.)
"""

from __future__ import annotations

from types import SimpleNamespace


from ..engine.trees import FieldTrees, Pool
from . import kernels as K
from .overlays import Overlays
from .tiles import Visible
from .tumbling import MeshBucket

__all__ = ["MIN_BUCKET", "MIN_MESHES", "MAX_CARS", "POOL", "FrameFields", "lease_frame", "bucket", "mesh_bucket"]

MIN_BUCKET = 4096
MIN_MESHES = 1024  # rocks drawn as meshes per level of detail: the first bucket (the default scene's flying rocks
# in view of a few pixels are ~300-550 at 720p)
MAX_CARS = 32  # vehicles casting a shadow


class FrameFields:
    """A renderer's buffers for a resolution, rock mode, shadows and tile store (see the module docstring)."""

    def __init__(self, w: int, h: int, splat: bool, shadows: bool, n_slots: int):
        self.trees, self.owner = FieldTrees(), None
        self.buf = K.Buffers(w, h, splat, MAX_CARS, shadows, self.trees)
        self.visible = Visible(n_slots, self.trees)
        self.buckets, self.mesh_buckets, self.mesh_cap = {}, {}, MIN_MESHES
        self.overlays = Overlays(SimpleNamespace(), self.trees)


POOL = Pool()


def lease_frame(owner, w, h, splat, shadows, n_slots) -> FrameFields:
    """A free set of buffers of these sizes, cleared, or a new one."""
    return POOL.lease(owner, (w, h, splat, shadows, n_slots), lambda: FrameFields(w, h, splat, shadows, n_slots),
                      lambda f: K.clear_buffers(f.buf))


def bucket(f: FrameFields, need: int, n_rocks: int) -> K.Bucket:
    """``f``'s bucket for ``need`` rocks drawn as particles: the smallest power-of-two capacity from MIN_BUCKET
    (at most the rock count), made when first needed."""
    cap = MIN_BUCKET
    while cap < need:
        cap *= 2
    cap = min(cap, max(n_rocks, 1))
    if cap not in f.buckets:
        f.buckets[cap] = K.Bucket(cap, f.trees)
    return f.buckets[cap]


def mesh_bucket(f: FrameFields, need: int, n_rocks: int, oriented: bool) -> MeshBucket:
    """``f``'s bucket for ``need`` rock meshes per level; without orientations (``oriented`` False: nothing to
    turn them by) a one-rock bucket that the rock pass compiles out: flying rocks stay particles."""
    if not oriented:
        if 0 not in f.mesh_buckets:
            f.mesh_buckets[0] = MeshBucket(1, on=False, trees=f.trees)
        return f.mesh_buckets[0]
    cap = f.mesh_cap  # only ever grows: each capacity compiles the rock pass anew (seconds)
    while cap < need:
        cap *= 2
    f.mesh_cap = cap = min(cap, max(n_rocks, 1))
    if cap not in f.mesh_buckets:
        f.mesh_buckets[cap] = MeshBucket(cap, trees=f.trees)
    return f.mesh_buckets[cap]
