"""The Taichi fields of one simulation, allocated once from a Scene, and nothing else.

Rock state is structure-of-arrays (one field per quantity) in the bed's *local* frame: world position =
``origin`` (float64, host) + local position (f32 or f64). Fields of a pass are allocated only when the scene
asks for that pass: no hash table without splashing tires, no ray buffers without tires.
"""


import math
import weakref

import numpy as np
import taichi as ti
from taichi.lang.field import Field

# Rock phases.
RESTING, FLYING, SLIDING = 0, 1, 2

# Hash primes of Teschner et al. 2003, "Optimized Spatial Hashing for Collision Detection of Deformable
# Objects", VMV.
P1, P2, P3 = 73856093, 19349663, 83492791


# Layout of World.ray[t, :], one row per splashing rear tire: the ray (tire centre a, bottom b) at the
# previous step and now, the wheel's velocity, its heading, its tread speed omega * R, and 1 if the tire is
# near the bed (0: parked far away, its rays degenerate and high above the bed).
A0, B0, A1, B1, VEL, FWD, SPIN, ACTIVE = 0, 3, 6, 9, 12, 15, 17, 18
RAY_FIELDS = 19


class Par:
    """Indices of the static physics parameters in ``World.par`` (values come from the scene)."""

    GRAVITY = 0
    GROUND_Z = 1
    BED_RADIUS = 2
    RESTITUTION = 3
    GROUND_FRICTION = 4
    REST_SPEED = 5
    CELL = 6
    ANGLE_MIN = 7
    ANGLE_MAX = 8
    SPREAD = 9
    LINEAR_DRAG = 10  # 9 mu_air / (2 rho): Stokes drag acceleration is -LINEAR_DRAG / r^2 * v
    QUAD_DRAG = 11  # 3 rho_air C_d / (8 rho): quadratic drag acceleration is -QUAD_DRAG / r * |v| v
    R_MAX = 12
    TIE_EPS = 13
    MARGIN = 14  # reach of a tire's query beyond its ray in XY (scope "tires" mask)
    COUNT = 15


class IPar:
    """Indices of the static integer parameters in ``World.ipar``."""

    SEED = 0
    DILATE = 1
    N_ROCKS = 2
    COUNT = 3


def next_prime(n: int) -> int:
    """Smallest prime >= n (n small enough for trial division: table sizes are < 1e9)."""
    n = max(2, int(n))

    def is_prime(m: int) -> bool:
        if m < 4:
            return m >= 2
        if m % 2 == 0:
            return False
        f = 3
        while f * f <= m:
            if m % f == 0:
                return False
            f += 2
        return True

    while not is_prime(n):
        n += 1
    return n


@ti.data_oriented
class World:
    """All fields of one simulation. ``n`` rocks; ``n_tires`` splashing rear tires."""

    def __init__(self, n: int, real, *, hash_table: int = 0, hash_entries: int = 0, n_tires: int = 0,
                 substeps: int = 1, ray_capacity: int = 0, reorder: bool = False, tiles=None,
                 tile_size: float = 1.0):
        self.n = n
        self.real = real
        cap = max(n, 1)  # Taichi fields cannot be empty
        vec3 = ti.types.vector(3, real)
        self.vec3 = vec3
        self.pos = ti.Vector.field(3, real, shape=cap)
        self.vel = ti.Vector.field(3, real, shape=cap)
        self.radius = ti.field(real, shape=cap)
        self.friction = ti.field(real, shape=cap)
        self.rock_id = ti.field(ti.i32, shape=cap)
        self.phase = ti.field(ti.i32, shape=cap)
        self.par = ti.field(real, shape=Par.COUNT)
        self.ipar = ti.field(ti.i32, shape=IPar.COUNT)
        self.launches = ti.field(ti.i64, shape=())
        self.recycles = ti.field(ti.i64, shape=())  # rocks moved to the leading edge so far (bed.py)
        self.hashed = hash_table > 0
        if self.hashed:
            self.table_size = hash_table
            self.entry_capacity = max(hash_entries, 1)
            # cell_start[s] .. cell_start[s + 1] is slot s's range of `entries` after a build.
            self.cell_start = ti.field(ti.i32, shape=hash_table + 1)
            self.entries = ti.field(ti.i32, shape=self.entry_capacity)
            self.slot = ti.field(ti.i32, shape=cap)  # centre-cell slot of each rock (centre insert)
            self.hit_step = ti.field(ti.i32, shape=cap)  # last step a rock was launched
        # scope "tires": a coarse XY mask around the tires' query regions; only rocks on marked tiles are
        # hashed, listed in `listed` (compile-time switch: `masked` is a Python attribute)
        self.masked = self.hashed and tiles is not None
        if self.masked:
            self.tiles = tuple(int(t) for t in tiles)
            self.tile_size = float(tile_size)
            self.tile_mask = ti.field(ti.i32, shape=self.tiles)
            self.listed = ti.field(ti.i32, shape=cap)
            self.n_listed = ti.field(ti.i32, shape=())
        self.n_tires = n_tires
        self.substeps = substeps
        if n_tires > 0:
            self.n_rays = n_tires * substeps
            self.ray_capacity = ray_capacity
            # per tire (layout in tires.py): ray a0, b0 at the previous step, a1, b1 now, wheel velocity,
            # heading, spin speed omega * R
            self.ray = ti.field(real, shape=(n_tires, RAY_FIELDS))
            self.ray_cells = ti.Vector.field(3, ti.i32, shape=(self.n_rays, max(ray_capacity, 1)))
            self.ray_cell_count = ti.field(ti.i32, shape=self.n_rays)
        self.reorder = reorder
        if reorder:
            self.tmp_vec = ti.Vector.field(3, real, shape=cap)
            self.tmp_real = ti.field(real, shape=cap)
            self.tmp_int = ti.field(ti.i32, shape=cap)
        self.health_out = ti.field(ti.i32, shape=6)  # the runtime guard's counts (Simulation.check_health)
        self.owner = None  # weak reference to the Simulation using these fields (see acquire)

    def fields(self) -> list:
        """Every Taichi field of this World."""
        return [v for v in vars(self).values() if isinstance(v, Field)]

    def set_params(self, par: np.ndarray, ipar: np.ndarray) -> None:
        self.par.from_numpy(par.astype(np.float64 if self.real == ti.f64 else np.float32))
        self.ipar.from_numpy(ipar.astype(np.int32))

    def np_real(self):
        return np.float64 if self.real == ti.f64 else np.float32


@ti.kernel
def _zero_fields(w: ti.template()):
    for f in ti.static(w.fields()):
        for I in ti.grouped(f):
            f[I] = f[I] * 0


_POOL: dict = {}


def acquire(owner, n: int, real, **layout) -> World:
    """A World for ``owner`` (a Simulation): one of the same layout that its previous owner released (was
    garbage-collected), with every field zeroed, or else a new one.

    Taichi never frees fields, and every new World compiles every kernel again (its fields are template
    arguments: ~2-4 s on a 2-core CPU). Re-using released Worlds keeps memory bounded and makes the second
    and later Simulations of a layout start at once: notebooks re-running a cell, parameter sweeps, tests.
    Two live Simulations never share a World."""
    key = (int(n), str(real), tuple(sorted((k, v if not isinstance(v, list) else tuple(v)) for k, v in layout.items())))
    for w in _POOL.get(key, ()):
        if w.owner is None or w.owner() is None:
            _zero_fields(w)
            w.owner = weakref.ref(owner)
            return w
    w = World(n, real, **layout)
    w.owner = weakref.ref(owner)
    _POOL.setdefault(key, []).append(w)
    return w


def dilation_cells(r_max: float, cell: float) -> int:
    """Cells to dilate a centre-insert query by: a rock whose centre is within r_max of a point lies in a
    cell at most floor(r_max / cell) + 1 away per axis (the + 1 covers floor() on both sides and
    rounding when r_max / cell is an integer)."""
    return int(math.floor(r_max / cell * (1.0 + 1e-6))) + 1 if r_max > 0 else 1
