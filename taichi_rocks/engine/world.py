"""The Taichi fields of one simulation, allocated once from a Scene, and nothing else.

Rock state is structure-of-arrays (one field per quantity) in the bed's *local* frame: world position =
``origin`` (float64, host) + local position (f32 or f64). Fields of a pass are allocated only when the scene
asks for that pass: no hash table without splashing tires, no ray buffers without tires.
"""


import weakref

import numpy as np
import taichi as ti
from taichi.lang.field import Field
from taichi.lang.util import to_numpy_type

from .params import IPar, Par  # the indices of World.par and World.ipar (also imported from here)

# Rock phases.
RESTING, FLYING, SLIDING = 0, 1, 2

# Hash primes of Teschner et al. 2003, "Optimized Spatial Hashing for Collision Detection of Deformable
# Objects", VMV.
P1, P2, P3 = 73856093, 19349663, 83492791


# Layout of World.ray[t, :], one row per splashing rear tire: the ray (tire centre a, bottom b) at the
# previous step and now, the wheel's velocity, its heading, its tread speed omega * R, and 1 if the tire is
# near the bed (0: parked far away, its rays degenerate and high above the bed). Then the tread: half its
# width and half the contact patch's length, the tire radius, the fender angle (rad), the mud flap's lower
# edge (m; < 0: none) and the swept footprint's convex hull (engine/patch.py: 8 XY vertices, counter-clockwise).
A0, B0, A1, B1, VEL, FWD, SPIN, ACTIVE = 0, 3, 6, 9, 12, 15, 17, 18
HALF_W, HALF_L, TIRE_R, FENDER, FLAP, HULL = 19, 20, 21, 22, 23, 24
HULL_VERTICES = 8
RAY_FIELDS = HULL + 2 * HULL_VERTICES


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


class _Trees:
    """Allocates fields in SNode trees of one element size each (a tree per size: 4-byte, 8-byte, ...).

    Why not all in one tree: Taichi's SPIR-V backends (Vulkan) pack the fields of a tree end to end, sorted
    by size, with no alignment padding, and index a 64-bit element at byte offset o as element o >> 3. A
    64-bit field landing at 4 mod 8 (after fields of an odd number of 32-bit words) is thus read and
    written 4 bytes too low, over its neighbour, silently (Taichi 1.7.4; the LLVM backends, CPU and CUDA,
    align their layouts). The i64 launch counter did: in minimal.toml's layout it shared 8 bytes with the
    last ``ray_cell_count`` entry, so on Vulkan launches_total read that ray's cell count plus the step's
    launches, and each launch bumped the count. In a tree whose fields all have one element size every
    offset is a multiple of that size."""

    def __init__(self):
        self._builders: dict[int, ti.FieldsBuilder] = {}

    def _place(self, f, dtype, shape):
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        size = np.dtype(to_numpy_type(dtype)).itemsize
        if size not in self._builders:
            self._builders[size] = ti.FieldsBuilder()
        fb = self._builders[size]
        fb.dense(ti.axes(*range(len(shape))), shape).place(f)
        return f

    def field(self, dtype, shape):
        return self._place(ti.field(dtype), dtype, shape)

    def vector(self, n: int, dtype, shape):
        return self._place(ti.Vector.field(n, dtype), dtype, shape)

    def finalize(self) -> None:
        for fb in self._builders.values():
            fb.finalize()


@ti.data_oriented
class World:
    """All fields of one simulation. ``n`` rocks; ``n_tires`` splashing rear tires."""

    def __init__(self, n: int, real, *, hash_table: int = 0, hash_entries: int = 0, n_tires: int = 0,
                 substeps: int = 1, ray_capacity: int = 0, reorder: bool = False, tiles=None,
                 tile_size: float = 1.0, store=None):
        self.n = n
        self.stored = store is not None  # active stepping's tile store (below)
        self.real = real
        cap = max(n, 1)  # Taichi fields cannot be empty
        trees = _Trees()
        vec3 = ti.types.vector(3, real)
        self.vec3 = vec3
        self.pos = trees.vector(3, real, cap)
        self.vel = trees.vector(3, real, cap)
        self.radius = trees.field(real, cap)
        self.friction = trees.field(real, cap)
        self.rock_id = trees.field(ti.i32, cap)
        self.phase = trees.field(ti.i32, cap)
        self.par = trees.field(real, Par.COUNT)
        self.ipar = trees.field(ti.i32, IPar.COUNT)
        self.launches = trees.field(ti.i64, ())
        self.recycles = trees.field(ti.i64, ())  # rocks moved to the leading edge so far (bed.py)
        self.hashed = hash_table > 0
        if self.hashed:
            self.table_size = hash_table
            self.entry_capacity = max(hash_entries, 1)
            # cell_start[s] .. cell_start[s + 1] is slot s's range of `entries` after a build.
            self.cell_start = trees.field(ti.i32, hash_table + 1)
            self.entries = trees.field(ti.i32, self.entry_capacity)
            self.slot = trees.field(ti.i32, cap)  # centre-cell slot of each rock (centre insert)
            self.hit_step = trees.field(ti.i32, cap)  # last step a rock was launched
        # scope "tires": a coarse XY mask around the tires' query regions; only rocks on marked tiles are
        # hashed, listed in `listed` (compile-time switch: `masked` is a Python attribute)
        self.masked = self.hashed and tiles is not None
        if self.masked:
            self.tiles = tuple(int(t) for t in tiles)
            self.tile_size = float(tile_size)
            self.tile_mask = trees.field(ti.i32, self.tiles)
            self.listed = trees.field(ti.i32, cap)
            self.n_listed = trees.field(ti.i32, ())
        self.n_tires = n_tires
        self.substeps = substeps
        if n_tires > 0:
            self.n_rays = n_tires * substeps
            self.ray_capacity = ray_capacity
            # per tire (layout in tires.py): ray a0, b0 at the previous step, a1, b1 now, wheel velocity,
            # heading, spin speed omega * R
            self.ray = trees.field(real, (n_tires, RAY_FIELDS))
            self.ray_cells = trees.vector(3, ti.i32, (self.n_rays, max(ray_capacity, 1)))
            self.ray_cell_count = trees.field(ti.i32, self.n_rays)
        self.reorder = reorder
        if reorder:
            self.tmp_vec = trees.vector(3, real, cap)
            self.tmp_real = trees.field(real, cap)
            self.tmp_int = trees.field(ti.i32, cap)
        # active stepping (engine/active.py): resting rocks in ground tiles; the rock arrays above are the
        # active list (ipar[N_ROCKS] rocks). ``store``: (tile edge, slots per axis, rocks per slot, recycle?)
        if self.stored:
            self._store_fields(trees, store, cap, real)
        self.health_out = trees.field(ti.i32, 6)  # the runtime guard's counts (Simulation.check_health)
        trees.finalize()
        self.owner = None  # weak reference to the Simulation using these fields (see acquire)

    def _store_fields(self, trees, store, cap: int, real) -> None:
        """Active stepping's tile store (engine/active.py): ``store`` = (tile edge, slots per axis, rocks per
        slot, recycle?); ``cap``: the active list's capacity."""
        tile, grid, capacity, recycle = store
        self.store_tile, self.store_grid, self.store_capacity = float(tile), int(grid), int(capacity)
        self.recycles_rocks = bool(recycle)
        slots = self.store_grid * self.store_grid
        self.ts_pos = trees.vector(3, real, slots * self.store_capacity)
        self.ts_radius = trees.field(real, slots * self.store_capacity)
        self.ts_friction = trees.field(real, slots * self.store_capacity)
        self.ts_id = trees.field(ti.i32, slots * self.store_capacity)
        if self.hashed:
            self.ts_hit = trees.field(ti.i32, slots * self.store_capacity)  # last launch step (hit_step)
        self.ts_count = trees.field(ti.i32, slots)
        self.ts_key = trees.vector(2, ti.i32, slots)
        self.ts_sel = trees.field(ti.i32, slots)
        self.a_hole = trees.field(ti.i32, cap)
        self.a_mover = trees.field(ti.i32, cap)
        self.ts_list = trees.field(ti.i32, slots)  # the slots marked this step
        if self.n_tires > 0:
            self.ts_tires = trees.field(ti.i32, slots)  # which tires marked a slot (bit t mod 32)
            self.tire_box = trees.vector(4, real, self.n_tires)  # each tire's query box (lo, hi) this step
            self.tire_keys = trees.vector(4, ti.i32, self.n_tires)  # and its tiles (first and last key)
        self.a_counts = trees.field(ti.i32, 6)

    def fields(self) -> list:
        """Every Taichi field of this World."""
        return [v for v in vars(self).values() if isinstance(v, Field)]

    def set_params(self, par: np.ndarray, ipar: np.ndarray) -> None:
        self.par.from_numpy(par.astype(np.float64 if self.real == ti.f64 else np.float32))
        self.ipar.from_numpy(ipar.astype(np.int32))

    def np_real(self):
        return np.float64 if self.real == ti.f64 else np.float32

    def load_rocks(self, pos: np.ndarray, radius: np.ndarray, friction: np.ndarray) -> None:
        """Rocks 0..n-1 at rest at ``pos`` ((max(n, 1), 3), local frame), in id order, never launched
        (hit step -1); the padding slot of an empty World gets radius 1."""
        n, cap = len(radius), max(len(radius), 1)
        pad = lambda a, fill=0: np.concatenate([a, np.full(cap - n, fill, dtype=a.dtype)])
        npr = self.np_real()
        self.pos.from_numpy(pos.astype(npr))
        self.vel.from_numpy(np.zeros((cap, 3), npr))
        self.radius.from_numpy(pad(radius.astype(npr), 1))
        self.friction.from_numpy(pad(friction.astype(npr)))
        self.rock_id.from_numpy(pad(np.arange(n, dtype=np.int32)))
        self.phase.from_numpy(np.zeros(cap, np.int32))
        if self.hashed:
            self.hit_step.from_numpy(np.full(cap, -1, np.int32))


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
