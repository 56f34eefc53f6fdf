"""The Taichi fields of one simulation, allocated once from a Scene, and nothing else.

Rock state is structure-of-arrays (one field per quantity, declared in engine/rockfields.py) in the bed's
*local* frame: world position = ``origin`` (float64, host) + local position (f32 or f64). Fields of a pass are
allocated only when the scene asks for that pass: no hash table without splashing tires, no ray buffers without
tires. :func:`field_specs` lists every field of a layout; the World allocates exactly that list, and the memory
estimate (engine/layout.py) adds it up.
"""


import math
import warnings
import weakref
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import taichi as ti
from taichi.lang.field import Field
from taichi.lang.util import to_numpy_type

from .params import IPar, Par  # the indices of World.par and World.ipar (also imported from here)
from .rockfields import FLYING, RESTING, SLIDING, present  # noqa: F401 - the phase codes, re-exported

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

# The per-step inputs of active stepping on the device, a lookahead batch of up to BATCH_ROWS steps at a time
# (engine/stepdata.py): ``step_rays[k, t, :]`` (float64, the layout above, kernels' frame) and
# ``step_frame[k, r]`` (2-vectors, float64), rows CENTRE, MOVE, LEAD, GRID, TILES (the origin's shift in tiles)
# and CLOCK (dt, 0).
BATCH_ROWS = 64
CENTRE, MOVE, LEAD, GRID, TILES, CLOCK = range(6)
FRAME_ROWS = 6


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
        """A scalar field of a Taichi ``dtype`` over ``shape`` (fields outside a World's layout: test buffers)."""
        return self._place(ti.field(dtype), dtype, shape)

    def place(self, spec, real):
        """The field of a :class:`FieldSpec` (``real``: the World's Taichi precision)."""
        dtype = real if spec.dtype == "real" else {"i32": ti.i32, "i64": ti.i64, "f64": ti.f64}[spec.dtype]
        f = ti.field(dtype) if spec.n == 1 else ti.Vector.field(spec.n, dtype)
        return self._place(f, dtype, spec.shape)

    def finalize(self) -> None:
        for fb in self._builders.values():
            fb.finalize()


@dataclass(frozen=True)
class FieldSpec:
    """One Taichi field of a World: ``n`` components (1: a scalar field) of ``dtype`` ("real": the World's
    precision, "i32", "i64", "f64") over ``shape``."""

    name: str
    dtype: str
    n: int
    shape: tuple

    def nbytes(self, real: str) -> int:
        size = {"f32": 4, "f64": 8, "i32": 4, "i64": 8}[real if self.dtype == "real" else self.dtype]
        return size * self.n * math.prod(self.shape)


def field_specs(n: int, real: str, *, hash_table: int = 0, hash_entries: int = 0, n_tires: int = 0,
                substeps: int = 1, ray_capacity: int = 0, reorder: bool = False, tiles=None, store=None,
                rocks=None, **_switches) -> list[FieldSpec]:
    """Every field of the World of this layout (``real``: "f32" | "f64"; the arguments are World's), in the
    order they are allocated: the one list both the World and the memory estimate (engine/layout.py) read.
    ``rocks``: the rock fields (engine/rockfields.py ``present``; default: those of this layout's mode)."""
    cap = max(n, 1)  # Taichi fields cannot be empty
    hashed = hash_table > 0
    rocks = default_rock_fields(hashed, store is not None) if rocks is None else rocks
    out = [FieldSpec(f.name, f.dtype, f.n, (cap,)) for f in rocks]
    out += [FieldSpec("par", "real", 1, (Par.COUNT,)), FieldSpec("ipar", "i32", 1, (IPar.COUNT,)),
            FieldSpec("launches", "i64", 1, ()), FieldSpec("recycles", "i64", 1, ())]
    if hashed:
        # cell_start[s] .. cell_start[s + 1] is slot s's range of `entries` after a build
        out += [FieldSpec("cell_start", "i32", 1, (hash_table + 1,)),
                FieldSpec("entries", "i32", 1, (max(hash_entries, 1),))]
    if hashed and tiles is not None:  # scope "tires": the mask's tiles, the rocks listed on them
        out += [FieldSpec("tile_mask", "i32", 1, tuple(int(t) for t in tiles)), FieldSpec("listed", "i32", 1, (cap,)),
                FieldSpec("n_listed", "i32", 1, ())]
    if n_tires > 0:
        n_rays = n_tires * substeps
        out += [FieldSpec("ray", "real", 1, (n_tires, RAY_FIELDS)),
                FieldSpec("ray_cells", "i32", 3, (n_rays, max(ray_capacity, 1))),
                FieldSpec("ray_cell_count", "i32", 1, (n_rays,))]
    if reorder:  # the re-sort's buffers: one per (dtype, components) of the carried rock fields
        out += [FieldSpec(tmp_name(f), f.dtype, f.n, (cap,)) for f in _distinct_kinds(rocks)]
    if store is not None:
        out += _store_specs(store, cap, n_tires, rocks)
    out.append(FieldSpec("health_out", "i32", 1, (6,)))  # the runtime guard's counts (Simulation.check_health)
    return out


def _store_specs(store, cap: int, n_tires: int, rocks) -> list[FieldSpec]:
    """Active stepping's tile store (engine/active.py): ``store`` = (tile edge, slots per axis, rocks per slot,
    recycle?); ``cap``: the active list's capacity."""
    _, grid, capacity, _ = store
    slots = int(grid) * int(grid)
    out = [FieldSpec(f.store_name, f.dtype, f.n, (slots * int(capacity),)) for f in rocks if f.stored]
    out += [FieldSpec("ts_count", "i32", 1, (slots,)), FieldSpec("ts_key", "i32", 2, (slots,)),
            FieldSpec("ts_sel", "i32", 1, (slots,)), FieldSpec("a_hole", "i32", 1, (cap,)),
            FieldSpec("a_mover", "i32", 1, (cap,)),
            FieldSpec("ts_list", "i32", 1, (slots,))]  # the slots marked this step
    if n_tires > 0:
        out += [FieldSpec("ts_tires", "i32", 1, (slots,)),  # which tires marked a slot (bit t mod 32)
                FieldSpec("tire_box", "real", 4, (n_tires,)),  # each tire's query box (lo, hi) this step
                FieldSpec("tire_keys", "i32", 4, (n_tires,))]  # and its tiles (first and last key)
    out.append(FieldSpec("a_counts", "i32", 1, (A_COUNTS,)))
    # the step inputs of a lookahead batch (engine/stepdata.py); more per-step inputs go beside these
    out.append(FieldSpec("step_frame", "f64", 2, (BATCH_ROWS, FRAME_ROWS)))
    if n_tires > 0:
        out.append(FieldSpec("step_rays", "f64", 1, (BATCH_ROWS, n_tires, RAY_FIELDS)))
    return out


A_COUNTS = 8  # active stepping's counters (engine/active.py)


def tmp_name(f) -> str:
    """The re-sort buffer of rock fields of f's dtype and components."""
    return f"tmp_{f.dtype}x{f.n}"


def _distinct_kinds(rocks) -> list:
    seen = {}
    for f in rocks:
        if f.carried:
            seen.setdefault(tmp_name(f), f)
    return list(seen.values())


def default_rock_fields(hashed: bool, stored: bool) -> tuple:
    """The rock fields of a World built without an explicit list: those of its mode, "splash" ones if hashed,
    no "spin" ones."""
    return present(SimpleNamespace(splash=hashed, spin=False), "active" if stored else "full")


@ti.data_oriented
class World:
    """All fields of one simulation. ``n`` rocks; ``n_tires`` splashing rear tires. The fields are those of
    :func:`field_specs`; ``rocks`` the rock fields (engine/rockfields.py), each an attribute of its name."""

    def __init__(self, n: int, real, *, hash_table: int = 0, hash_entries: int = 0, n_tires: int = 0,
                 substeps: int = 1, ray_capacity: int = 0, reorder: bool = False, tiles=None,
                 tile_size: float = 1.0, store=None, rocks=None):
        self.n = n
        self.stored = store is not None  # active stepping's tile store (below)
        self.real = real
        self.vec3 = ti.types.vector(3, real)
        self.hashed = hash_table > 0
        self.rocks = default_rock_fields(self.hashed, self.stored) if rocks is None else tuple(rocks)
        if self.hashed:
            self.table_size = hash_table
            self.entry_capacity = max(hash_entries, 1)
        # scope "tires": a coarse XY mask around the tires' query regions; only rocks on marked tiles are
        # hashed, listed in `listed` (compile-time switch: `masked` is a Python attribute)
        self.masked = self.hashed and tiles is not None
        if self.masked:
            self.tiles = tuple(int(t) for t in tiles)
            self.tile_size = float(tile_size)
        self.n_tires = n_tires
        self.substeps = substeps
        if n_tires > 0:
            self.n_rays = n_tires * substeps
            self.ray_capacity = ray_capacity
        self.reorder = reorder
        # active stepping (engine/active.py): resting rocks in ground tiles; the rock arrays are the active
        # list (ipar[N_ROCKS] rocks). ``store``: (tile edge, slots per axis, rocks per slot, recycle?)
        if self.stored:
            tile, grid, capacity, recycle = store
            self.store_tile, self.store_grid, self.store_capacity = float(tile), int(grid), int(capacity)
            self.recycles_rocks = bool(recycle)
        trees = _Trees()
        for spec in field_specs(n, "f64" if real == ti.f64 else "f32", hash_table=hash_table,
                                hash_entries=hash_entries, n_tires=n_tires, substeps=substeps,
                                ray_capacity=ray_capacity, reorder=reorder, tiles=tiles, store=store,
                                rocks=self.rocks):
            setattr(self, spec.name, trees.place(spec, real))
        trees.finalize()
        self.owner = None  # weak reference to the Simulation using these fields (see acquire)

    def fields(self) -> list:
        """Every Taichi field of this World."""
        return [v for v in vars(self).values() if isinstance(v, Field)]

    def set_params(self, par: np.ndarray, ipar: np.ndarray) -> None:
        self.par.from_numpy(par.astype(np.float64 if self.real == ti.f64 else np.float32))
        self.ipar.from_numpy(ipar.astype(np.int32))

    def np_real(self):
        return np.float64 if self.real == ti.f64 else np.float32

    def np_dtype(self, f):
        """The NumPy dtype of rock field ``f`` (engine/rockfields.py) in this World."""
        return self.np_real() if f.dtype == "real" else np.int32


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
            with warnings.catch_warnings():  # a static loop over every field: Taichi warns past 32 of them
                warnings.simplefilter("ignore", SyntaxWarning)
                _zero_fields(w)
            w.owner = weakref.ref(owner)
            return w
    w = World(n, real, **layout)
    w.owner = weakref.ref(owner)
    _POOL.setdefault(key, []).append(w)
    return w
