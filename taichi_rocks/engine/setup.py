"""Setting a simulation up from a Scene: the initial rocks, the hash sizing and the packing of the parameters
into ``World.par`` / ``World.ipar``. No Taichi field is written here.

Initial rocks: radius uniform in [r_min, r_max], static friction uniform in the scene's range, position
uniform over the bed's disk (radius R sqrt(u), angle uniform), resting on the ground; all drawn from one
NumPy generator seeded with the scene's seed, in that order. With tumbling (the Plan's ``spin``), orientations
uniform over rotations, from counter-based uniforms of (seed, rock id) (``initial_orientations``).

Hash sizing (Teschner et al. 2003: a table of about as many slots as entries, prime):
    entries   centre insert: one per rock; AABB insert: sum over rocks of (floor(2 r / l (1 + 1e-5) + 1e-3)
              + 2)^3, an upper bound of the cells a rock's AABB touches, so the scatter cannot overflow;
    expected  centre: n; AABB: sum of (2 r / l + 1)^3, the mean cells touched; with scope "tires" scaled by
              the hashed share of the bed (a tire's query region is about (2 margin + 2 tile + v dt)^2);
    table     the smallest prime >= expected (>= 1024 with the tire mask), or the scene's table_size.

The parameters: engine/params.py declares each one (its scene key or derivation); ``scene_params`` packs
them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config.streams import INITIAL_ORIENTATION
from .params import Source, dilation_cells, pack_source
from .randomness import uniform01_np
from .world import next_prime


# ---------------------------------------------------------------------------------------------------
# Initial rocks

@dataclass(frozen=True)
class InitialRocks:
    """The scene's rocks before the first step: radius, friction and polar position in the bed (rho in
    [0, 1] of the bed radius, theta), each an array of n."""

    radius: np.ndarray
    friction: np.ndarray
    rho: np.ndarray
    theta: np.ndarray

    def resting_positions(self, centre, bed_radius: float, ground_z: float) -> np.ndarray:
        """(max(n, 1), 3) positions on the ground (``ground_z``) around the bed centre ``centre`` (XY), in
        the frame ``centre`` is given in; the padding row of an empty bed is zero."""
        n = len(self.radius)
        local = np.zeros((max(n, 1), 3))
        local[:n, 0] = centre[0] + bed_radius * self.rho * np.cos(self.theta)
        local[:n, 1] = centre[1] + bed_radius * self.rho * np.sin(self.theta)
        local[:n, 2] = ground_z + self.radius
        return local


def initial_rocks(scene) -> InitialRocks:
    """The scene's rocks, drawn from its seed (see the module docstring)."""
    bed = scene.bed
    n = int(bed.rocks)
    r_min, r_max = (float(x) for x in bed.rock_radius)
    rng = np.random.default_rng(scene.seed)
    radius = rng.uniform(r_min, r_max, n) if r_max > r_min else np.full(n, r_min)
    friction = rng.uniform(*bed.static_friction, n)
    rho = np.sqrt(rng.uniform(0.0, 1.0, n))  # uniform over the disk's area
    theta = rng.uniform(0.0, 2.0 * np.pi, n)
    return InitialRocks(radius, friction, rho, theta)


def initial_orientations(seed: int, n: int) -> np.ndarray:
    """(n, 4) unit quaternions (x, y, z, w), uniform over rotations (Shoemake's method), of rocks 0 .. n-1
    before the first step: counter-based uniforms of (seed, rock, 0) (config/streams.py INITIAL_ORIENTATION),
    so they depend on nothing else drawn."""
    ids = np.arange(n)
    u1, u2, u3 = (uniform01_np(seed & 0x7FFFFFFF, ids, 0, INITIAL_ORIENTATION.id(k)).astype(np.float64)
                  for k in range(3))
    a, b = np.sqrt(1.0 - u1), np.sqrt(u1)
    return np.stack([a * np.sin(2 * np.pi * u2), a * np.cos(2 * np.pi * u2), b * np.sin(2 * np.pi * u3),
                     b * np.cos(2 * np.pi * u3)], axis=1)


# ---------------------------------------------------------------------------------------------------
# Hash sizing

@dataclass(frozen=True)
class HashSizing:
    """Sizes of the hash and of the tire mask (scope "tires"), decided once from the scene and its rocks."""

    table: int  # slots (0: no hash)
    entries: int  # capacity of the (rock, cell) list
    tiles: tuple | None  # the mask's tiles per axis (None: every rock is hashed, or no hash)
    tile: float  # m: edge of a mask tile
    margin: float  # m: reach of a tire's query beyond its ray in XY
    grid_half: float  # m: half the mask's side, centred on the bed


def entry_capacity(radius, cell: float, center: bool) -> int:
    """(rock, cell) pairs the hash can hold: an upper bound by construction (module docstring)."""
    if center:
        return len(radius)
    per_axis = np.floor(2.0 * radius / cell * (1.0 + 1e-5) + 1e-3).astype(np.int64) + 2
    return int(np.sum(per_axis ** 3))


def expected_entries(radius, cell: float, center: bool) -> int:
    """(rock, cell) pairs a build of every rock makes on average."""
    if center:
        return len(radius)
    return int(np.sum((2.0 * radius / cell + 1.0) ** 3))


def tire_reach(r_max: float, cell: float) -> float:
    """How far beyond its ray (in XY) a tire's query can find a rock: r_max plus the dilated cells."""
    return r_max + (dilation_cells(r_max, cell) + 1) * cell


def hash_sizing(scene, plan, radius, n_tires: int) -> HashSizing:
    """The hash and mask sizes of a scene (see the module docstring); ``radius``: the rocks' radii."""
    bed, cell = scene.bed, plan.cell_size
    tile = max(0.5, 4.0 * cell)
    margin = tire_reach(float(bed.rock_radius[1]), cell)
    if plan.patch:  # the tread's footprint reaches its half-diagonal beyond the ray
        margin += max((math.hypot(0.5 * v.tire_width, 0.5 * v.contact_length) for v in scene.vehicles if v.splash),
                      default=0.0)
    half = bed.radius + 2.0 * tile
    if not plan.splash:
        return HashSizing(table=0, entries=0, tiles=None, tile=tile, margin=margin, grid_half=half)
    entries = entry_capacity(radius, cell, plan.center)
    expected = expected_entries(radius, cell, plan.center)
    tiles = None
    if plan.active:  # the hash holds the active list: flying rocks, the tires' tiles, the recycled ones
        side = 2.0 * margin + 2.0 * tile + 60.0 * float(scene.sim.dt)
        under = n_tires * side * side * len(radius) / (math.pi * bed.radius ** 2)
        expected = max(1, int(min(expected, under + 0.01 * expected)))
    elif not plan.scope_all:
        side = int(math.ceil(2.0 * half / tile))
        tiles = (side, side)
        reach = 2.0 * margin + 2.0 * tile + 60.0 * float(scene.sim.dt)
        share = min(1.0, n_tires * reach * reach / (math.pi * bed.radius ** 2))
        expected = max(1, int(expected * share))
    ts = scene.sim.hash.table_size
    table = next_prime(max(expected, 1024 if (tiles or plan.active) else 1)) if ts == "auto" else int(ts)
    return HashSizing(table=table, entries=entries, tiles=tiles, tile=tile, margin=margin, grid_half=half)


# ---------------------------------------------------------------------------------------------------
# Parameters

def scene_params(scene, plan, sizing: HashSizing, ground_z: float):
    """``World.par`` (float64) and ``World.ipar`` (int64) of a scene, as engine/params.py declares them:
    ``ground_z`` is the ground's height in the kernels' local frame."""
    return pack_source(Source(scene, plan, sizing, ground_z))
