"""Dust ([effects] dust; config/effects/dust.py DRAWS) drawn as soft, translucent GGUI particles.

GGUI's particles have no alpha, so translucency is approximated: each particle's colour is the dust colour
blended by its opacity alpha towards what lies behind it, taken as the mean of the horizon's haze and the
ground's colour (c = alpha c_dust + (1 - alpha) c_behind: a thin veil over a road seen from a vehicle), and its radius shrinks as it fades (r = size (0.4 + 0.6 alpha)); particles
below ``MIN_ALPHA`` are not drawn. The buffers grow to the pool's capacity on first use.
"""

import numpy as np
import taichi as ti

from ..engine.trees import FieldTrees
from .camera import to_gl
from .looks import GROUND_A, GROUND_B, rgb

__all__ = ["DustLayer", "draw_dust", "dust_looks"]

MIN_ALPHA = 0.03


def dust_looks(opacity, table, haze) -> tuple:
    """(colours (K, 3) f32, radii (K,) f32) of particles of ``opacity`` (see the module docstring)."""
    a = np.asarray(opacity, np.float32)[:, None]
    behind = (np.asarray(haze, np.float32) + 0.5 * (np.asarray(GROUND_A, np.float32) + GROUND_B)) / 2.0
    col = a * np.asarray(rgb(table.color), np.float32) + (1.0 - a) * behind
    rad = float(table.size) * (0.4 + 0.6 * a[:, 0])
    return col.astype(np.float32), rad.astype(np.float32)


class DustLayer:
    """The GGUI buffers of one renderer's dust."""

    def __init__(self, capacity: int):
        self.capacity = int(capacity)
        trees = FieldTrees(owner=self)
        self.pos = trees.vector(3, ti.f32, self.capacity)
        self.col = trees.vector(3, ti.f32, self.capacity)
        self.rad = trees.scalar(ti.f32, self.capacity)
        self._trees = trees

    def draw(self, scene, sim, origin, haze) -> int:
        """Declare ``sim``'s dust in the GGUI ``scene``; return the particles drawn."""
        d = sim.effect_arrays().get("dust")
        if d is None:
            return 0
        keep = np.flatnonzero(d["opacity"] >= MIN_ALPHA)[: self.capacity]
        if not len(keep):
            return 0
        col, rad = dust_looks(d["opacity"][keep], sim.scene.dust, haze)
        pos = np.zeros((self.capacity, 3), np.float32)
        pos[:len(keep)] = to_gl(d["positions"][keep], origin)
        cbuf = np.zeros((self.capacity, 3), np.float32)
        cbuf[:len(keep)] = col
        rbuf = np.zeros(self.capacity, np.float32)
        rbuf[:len(keep)] = rad
        self.pos.from_numpy(pos)
        self.col.from_numpy(cbuf)
        self.rad.from_numpy(rbuf)
        scene.particles(self.pos, float(sim.scene.dust.size), per_vertex_color=self.col, per_vertex_radius=self.rad,
                        index_count=len(keep))
        return len(keep)


def draw_dust(layer, scene, sim, origin, haze):
    """The renderer's one call: draw ``sim``'s dust (nothing without [effects] dust) into the GGUI ``scene``
    with ``layer`` (None: made on first use); return the layer for the next frame."""
    if "dust" not in sim.plan.effects:
        return layer
    if layer is None:
        layer = DustLayer(sim.scene.dust.capacity)
    layer.draw(scene, sim, origin, haze)
    return layer
