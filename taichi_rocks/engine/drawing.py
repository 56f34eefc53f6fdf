"""What to draw of a World this frame, as the engine offers it to the renderer (render/kernels.py ``rocks_pass``):
Taichi functions over the rocks wherever they are, so that nothing outside engine/ reads the World's layout.

* the *listed* rocks: the World's rock arrays, every rock with full stepping and the active list (rocks in the
  air, sliding or just touched) with active stepping: :func:`listed_count`, :func:`listed_rock`;
* with active stepping (:func:`has_tiles`), the resting rocks in the ground tiles, slot by slot so that a
  renderer can cull whole tiles: :func:`slot_count` slots of :func:`slot_capacity` rocks each,
  :func:`slot_rocks` rocks in slot t, :func:`slot_bounds` the box every rock of slot t lies in (local frame),
  :func:`slot_rock` its k-th rock.

A renderer's kernel over a World is a world kernel (:func:`world_kernel`, engine/view.py: the World's data are
ndarrays, passed as its arguments). A rock is (centre, radius) in the kernels' local frame as f32, its phase (engine/rockfields.py codes) and its
id; a listed rock also has an orientation (:func:`listed_orientation`: the engine's with tumbling, the identity
without; :func:`has_orientations`). Flying rocks are always listed. The tiles' boxes need the floating origin's
shift in tiles, ``Simulation.tile_shift()`` (zeros without tiles), as an f32 2-vector. :func:`slot_total`
(Python) is the number of slots to size a renderer's list of visible slots by (0 without tiles).
"""

import taichi as ti

from .rockfields import RESTING
from .view import world_kernel  # noqa: F401 - a renderer's kernels over a World take it as engine/view.py says
from .world import IPar, Par

__all__ = ["world_kernel", "has_tiles", "has_orientations", "slot_total", "listed_count", "listed_rock", "listed_orientation",
           "slot_count", "slot_capacity", "slot_rocks", "slot_bounds", "slot_rock"]


def has_tiles(w) -> bool:
    """Whether resting rocks wait in tiles (active stepping); a compile-time value (``ti.static``)."""
    return bool(w.stored)


def has_orientations(w) -> bool:
    """Whether the rocks have orientations (the simulation tumbles them: engine/tumble.py); compile-time."""
    return any(f.name == "orient" for f in w.rocks)


def slot_total(w) -> int:
    """The tile store's slots (0 without tiles)."""
    return w.store_grid * w.store_grid if w.stored else 0


@ti.func
def listed_count(w: ti.template()):
    """Rocks in the World's rock arrays (every rock with full stepping, the active list with active stepping)."""
    return w.ipar[IPar.N_ROCKS]


@ti.func
def listed_rock(w: ti.template(), i):
    """Listed rock i: local centre and radius (f32), phase, id."""
    return ti.cast(w.pos[i], ti.f32), ti.cast(w.radius[i], ti.f32), w.phase[i], w.rock_id[i]


@ti.func
def listed_orientation(w: ti.template(), i):
    """Listed rock i's orientation, a unit quaternion (x, y, z, w; f32) from its own frame to the world's: the
    engine's with tumbling, else the identity."""
    q = ti.Vector([0.0, 0.0, 0.0, 1.0])
    if ti.static(has_orientations(w)):
        q = ti.cast(w.orient[i], ti.f32)
    return q


@ti.func
def slot_count(w: ti.template()):
    return w.store_grid * w.store_grid


@ti.func
def slot_capacity(w: ti.template()):
    return w.store_capacity


@ti.func
def slot_rocks(w: ti.template(), t):
    """Rocks in slot t (0: an empty slot)."""
    return w.ts_count[t]


@ti.func
def slot_bounds(w: ti.template(), t, tiles):
    """Where the rocks of an occupied slot t lie (``tiles``: the origin's shift in tiles, f32 2-vector): their
    centres in the XY box lo .. lo + s (local frame, f32) and, at rest, z in ground .. ground + 2 r_max, radii
    <= r_max. Returns (lo, s, ground, r_max)."""
    s = ti.cast(w.store_tile, ti.f32)
    key = w.ts_key[t]
    lo = (ti.Vector([ti.cast(key[0], ti.f32), ti.cast(key[1], ti.f32)]) - tiles) * s
    return lo, s, ti.cast(w.par[Par.GROUND_Z], ti.f32), ti.cast(w.par[Par.R_MAX], ti.f32)


@ti.func
def slot_rock(w: ti.template(), t, k):
    """Rock k (< slot_rocks) of slot t: local centre and radius (f32), phase (resting), id."""
    j = t * w.store_capacity + k
    return ti.cast(w.ts_pos[j], ti.f32), ti.cast(w.ts_radius[j], ti.f32), RESTING, w.ts_rock_id[j]
