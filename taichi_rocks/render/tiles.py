"""Culling the resting rocks of active stepping (``[sim] stepping = "active"``) by the tiles they wait in.

Under active stepping the engine lists only the active rocks; the resting ones wait in ground tiles, which the
engine offers slot by slot (engine/drawing.py). The rock pass (:func:`.splat.rocks_pass`) draws the listed
rocks rock by rock, then the tiles: one parallel loop over the slots keeps the occupied tiles whose rocks may be
in view (:func:`tile_in_view`), compacted into a :class:`Visible` list by an atomic counter, then one parallel
loop over (visible tile, rock of the tile) runs the same per-rock test and drawing as the listed rocks.

A tile's rocks have their centres in an XY box of edge s (``drawing.slot_bounds``) and, at rest,
z = ground + r <= ground + r_max: the box's bounding sphere, grown by r_max, holds every one of their spheres.
The per-rock test is a sphere against the frustum's side planes and the near plane (signed distances,
1-Lipschitz) plus the centre's distance against the draw distance; so a tile whose sphere fails the same tests
holds no rock that passes them, and skipping it changes no pixel. The rounding margin keeps that true in f32.
"""

import taichi as ti

from ..engine.trees import FieldTrees

__all__ = ["Visible", "tile_in_view"]


@ti.data_oriented
class Visible:
    """The tile store's slots in view in the last rock pass: ``slots[:count]`` (``slots`` has one entry per
    slot of the store, at least one)."""

    def __init__(self, n_slots: int, trees: FieldTrees = None):
        t = FieldTrees.given(trees, self)
        self.slots = t.scalar(ti.i32, max(int(n_slots), 1))
        self.count = t.scalar(ti.i32)


@ti.func
def tile_in_view(lo, s, ground, r_max, cam, fr):
    """True unless no rock (centre in the XY box lo .. lo + s, z in ground .. ground + 2 r_max, radius <= r_max)
    can pass the rock pass's view test (near plane, side planes, draw distance): the test of the box's bounding
    sphere grown by r_max, and by a margin for f32 rounding."""
    half = 0.5 * s
    c = ti.Vector([lo[0] + half, lo[1] + half, ground + r_max])
    d = c - cam.eye
    margin = 1e-3 + 1e-5 * (ti.abs(c[0]) + ti.abs(c[1]) + ti.abs(c[2]) + ti.abs(cam.eye[0]) + ti.abs(cam.eye[1])
                            + ti.abs(cam.eye[2]) + fr.far)
    rb = ti.sqrt(2.0 * half * half + r_max * r_max) + r_max + margin
    z = d.dot(cam.fwd)
    x = d.dot(cam.right)
    y = d.dot(cam.up)
    reach = fr.far + rb
    return z > fr.near - rb and d.norm_sqr() < reach * reach and ti.abs(x) < z * fr.tan_x + rb * fr.sec_x and \
        ti.abs(y) < z * fr.tan_y + rb * fr.sec_y
