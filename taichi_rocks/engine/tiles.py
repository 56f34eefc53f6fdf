"""Active stepping's ground tiles (engine/active.py): how big a tile and the store are for a scene, and where a
point's tile lies in the store.

A tile's key is its integer coordinates relative to the origin's anchor, key = floor(p_local / s) + shift / s
(s a power of two, so the floating origin's whole multiples of 64 m move no tile boundary); keys live in a
G x G table addressed modulo G (a toroidal grid, G s > 2 R + 2 s). The sizing (``store_sizing``) is the
host's; the rest are the kernels' functions."""

import math
from dataclasses import dataclass

import taichi as ti

from .world import Par

__all__ = ["ROCKS_PER_TILE", "StoreSizing", "store_sizing", "tile_key", "same_key", "slot_of", "rounding_margin",
           "vec2"]

ROCKS_PER_TILE = 32  # the tile edge is the power of two giving about this many rocks per tile

vec2 = ti.types.vector(2, ti.f64)


@dataclass(frozen=True)
class StoreSizing:
    """The tile store of a scene: tile edge (m), slots per axis, rocks per slot."""

    tile: float
    grid: int
    capacity: int


def store_sizing(n: int, bed_radius: float) -> StoreSizing:
    """Tile edge s: the power of two (1/64 m .. 64 m) nearest to sqrt(ROCKS_PER_TILE / density); G: the
    smallest grid with G s >= 2 R + 3 s; C: the mean count m plus room for Poisson scatter and landing rocks
    (1.25 m + 3 sqrt(m) + 8; a rock finding its tile full stays in the active list)."""
    area = math.pi * bed_radius ** 2
    density = max(n, 1) / area
    s = 2.0 ** round(math.log2(math.sqrt(ROCKS_PER_TILE / density)))
    s = min(64.0, max(1.0 / 64.0, s))
    grid = int(math.ceil(2.0 * bed_radius / s)) + 3
    m = density * s * s
    cap = int(math.ceil(1.25 * m + 3.0 * math.sqrt(m) + 8.0))
    return StoreSizing(tile=s, grid=grid, capacity=cap)


@ti.func
def tile_key(w: ti.template(), p, shift_tiles):
    """Anchor-relative integer key of the tile holding the local point p."""
    inv = 1.0 / w.store_tile  # a power of two: exact
    return ti.Vector([ti.cast(ti.floor(p[0] * inv), ti.i32), ti.cast(ti.floor(p[1] * inv), ti.i32)]) + shift_tiles


@ti.func
def same_key(a, b):
    return a[0] == b[0] and a[1] == b[1]


@ti.func
def slot_of(w: ti.template(), key):
    g = w.store_grid
    return ((key[0] % g + g) % g) * g + ((key[1] % g + g) % g)


@ti.func
def rounding_margin(w: ti.template(), c):
    """A margin (m) for the tile tests: 1 mm plus many float spacings at the bed's distance from the origin."""
    eps = ti.static(1.2e-7 if w.real == ti.f32 else 2.3e-16)
    return 1e-3 + 64.0 * eps * (ti.abs(c[0]) + ti.abs(c[1]) + w.par[Par.BED_RADIUS])
