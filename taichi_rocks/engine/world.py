"""The Taichi fields of one simulation, allocated once from a Scene, and nothing else.

Rock state is structure-of-arrays (one field per quantity, declared in engine/rockfields.py) in the bed's
*local* frame: world position = ``origin`` (float64, host) + local position (f32 or f64). Fields of a pass are
allocated only when the scene asks for that pass: no hash table without splashing tires, no ray buffers without
tires. :func:`field_specs` lists every field of a layout; the World allocates exactly that list, and the memory
estimate (engine/layout.py) adds it up.
"""


import math
import warnings
from dataclasses import dataclass
from typing import Optional

import numpy as np
import taichi as ti
from taichi.lang.field import Field
from taichi.lang.matrix import MatrixField

from ..config.environment import PARALLEL_SCAN, parallel_scan_wanted  # noqa: F401 - PARALLEL_SCAN re-exported
from ..config.plan import Plan
from .events import N_INT, N_REAL, EventBuffer
from .transfer import entries, entry_index, most_entries
from .trees import FieldTrees, Pool  # noqa: F401 - FieldTrees also imported from here
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
# With impacts, the rows of a step's poses of each vehicle stones hit (engine/impact_pass.py pose_rows)
POSE_ROWS = 7

# The per-step inputs of active stepping on the device, a lookahead batch of up to BATCH_ROWS steps at a time
# (engine/stepdata.py): ``step_rays[k, t, :]`` (float64, the layout above, kernels' frame) and
# ``step_frame[k, r]`` (2-vectors, float64), rows CENTRE, MOVE, LEAD, GRID, TILES (the origin's shift in tiles)
# and CLOCK (dt, and with impacts the step's start time); with impacts ``step_bodies[k, r]`` (2-vectors, float64:
# the pose rows of the step, engine/impact_pass.py batch_pose_rows).
BATCH_ROWS = 64
CENTRE, MOVE, LEAD, GRID, TILES, CLOCK = range(6)
FRAME_ROWS = 6

_FRAME_TYPES = {}


def frame_type(real):
    """A step's frame as one struct in the World's precision ``real``, what the rock pass reads: ``h``, the time
    step (s), and the 2-vectors (local frame, m) ``centre``, the bed's new centre, ``move``, its move this step,
    ``lead``, the bed's direction of travel (a unit vector), and ``grid``, the tire mask's corner (scope
    "tires")."""
    key = str(real)
    if key not in _FRAME_TYPES:
        v = ti.types.vector(2, real)
        _FRAME_TYPES[key] = ti.types.struct(h=real, centre=v, move=v, lead=v, grid=v)
    return _FRAME_TYPES[key]


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


SCAN_BLOCK = 32  # slots per block of the parallel prefix sum (engine/hashgrid.py block_scan)


def scan_level_sizes(table: int) -> tuple:
    """The block sums of the hash's parallel prefix sum over ``table`` slots, one field per level: level k
    holds ceil(table / 32^(k + 1)) sums, and the last level (at most 32 sums) is scanned by one thread."""
    sizes, m = [], int(table)
    while m > SCAN_BLOCK:
        m = -(-m // SCAN_BLOCK)
        sizes.append(m)
    return tuple(sizes)


def scan_in_parallel(requested: Optional[bool] = None) -> bool:
    """Does a World's hash build scan its counts in parallel (engine/hashgrid.py block_scan)? As ``requested``,
    else as ``TAICHI_ROCKS_PARALLEL_SCAN`` says ("1" or "0"; another value: ValueError, config/environment.py),
    else off the CPU only: one GPU thread pays some 15 ns per slot for a serial scan, a CPU core about 1 ns."""
    if requested is not None:
        return bool(requested)
    env = parallel_scan_wanted()
    if env is not None:
        return env
    if ti.lang.impl.get_runtime().prog is None:  # Taichi not started (a memory estimate made before): the CPU's
        return False
    return ti.lang.impl.current_cfg().arch not in (ti.x64, ti.arm64)


def field_specs(n: int, real: str, *, hash_table: int = 0, hash_entries: int = 0, n_tires: int = 0,
                substeps: int = 1, ray_capacity: int = 0, reorder: bool = False, tiles=None, store=None,
                rocks=None, bodies=None, events: int = 0, drawn: bool = False, parallel_scan: bool = False,
                **_switches) -> list[FieldSpec]:
    """Every field of the World of this layout (``real``: "f32" | "f64"; the arguments are World's), in the
    order they are allocated: the one list both the World and the memory estimate (engine/layout.py) read.
    ``rocks``: the rock fields (engine/rockfields.py ``present``; default: those of this layout's mode);
    ``bodies``: (vehicles hit, their parts) with impacts, and ``events`` the event buffer's capacity; ``drawn``:
    the mirror of each rock's drawn state that ``Simulation.changes()`` reads (engine/changes.py);
    ``parallel_scan``: the block sums of the hash's parallel prefix sum (:func:`scan_level_sizes`)."""
    cap = max(n, 1)  # Taichi fields cannot be empty
    hashed = hash_table > 0
    rocks = default_rock_fields(hashed, store is not None) if rocks is None else rocks
    out = [FieldSpec(f.name, f.dtype, f.n, (cap,)) for f in rocks]
    out += [FieldSpec("par", "real", 1, (Par.COUNT,)), FieldSpec("ipar", "i32", 1, (IPar.COUNT,)),
            FieldSpec("launches", "i64", 1, ()), FieldSpec("recycles", "i64", 1, ())]
    if hashed:
        # cell_start[s] .. cell_start[s + 1] is slot s's range of `entries` after a build
        out += [FieldSpec("cell_start", "i32", 1, (hash_table + 1,)),
                FieldSpec("entries", "i32", 1, (max(hash_entries, 1),)),
                FieldSpec("claim", "i32", 1, (cap,)),  # the tire pass: the first tire to launch a rock (0: none)
                FieldSpec("tire_counts", "i32", 1, (TIRE_COUNTS,))]
        if parallel_scan:
            out += [FieldSpec(f"scan_sums{k}", "i32", 1, (m,)) for k, m in enumerate(scan_level_sizes(hash_table))]
    if hashed and tiles is not None:  # scope "tires": the mask's tiles, the rocks listed on them
        out += [FieldSpec("tile_mask", "i32", 1, tuple(int(t) for t in tiles)), FieldSpec("listed", "i32", 1, (cap,)),
                FieldSpec("n_listed", "i32", 1, ())]
    if n_tires > 0:
        n_rays = n_tires * substeps
        out += [FieldSpec("ray", "real", 1, (n_tires, RAY_FIELDS)),
                FieldSpec("ray_cells", "i32", 3, (n_rays, max(ray_capacity, 1))),
                FieldSpec("ray_cell_count", "i32", 1, (n_rays,)),
                FieldSpec("tire_cells", "i32", 3, (n_rays, 2))]  # the tire pass: each query's cells (first, last)
    if reorder:  # the re-sort's buffers: one per (dtype, components) of the carried rock fields
        out += [FieldSpec(tmp_name(f), f.dtype, f.n, (cap,)) for f in _distinct_kinds(rocks)]
    if store is not None:
        out += _store_specs(store, cap, n_tires, rocks)
    if bodies is not None:
        out += _impact_specs(bodies, n_tires, events, cap)
        if store is not None:  # active stepping: the batch's pose rows beside its step_frame
            out.append(FieldSpec("step_bodies", "f64", 2, (BATCH_ROWS, POSE_ROWS * max(int(bodies[0]), 1))))
    if drawn:
        out += _drawn_specs(cap, rocks)
    out.append(FieldSpec("health_out", "i32", 1, (6,)))  # the runtime guard's counts (Simulation.check_health)
    return out


def _drawn_specs(cap: int, rocks) -> list[FieldSpec]:
    """The mirror of the drawn state by rock id, and the ids listed since the last read (engine/changes.py)."""
    out = [FieldSpec("drawn_pos", "real", 3, (cap,)), FieldSpec("drawn_phase", "i32", 1, (cap,))]
    if any(f.name == "orient" for f in rocks):
        out.append(FieldSpec("drawn_orient", "real", 4, (cap,)))
    return out + [FieldSpec("drawn_flag", "i32", 1, (cap,)), FieldSpec("drawn_list", "i32", 1, (cap,)),
                  FieldSpec("drawn_count", "i32", 1, ())]


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


def _impact_specs(bodies, n_tires: int, events: int, cap: int) -> list[FieldSpec]:
    """The impacts pass's fields (engine/impact_pass.py): ``bodies`` = (T vehicles hit, P parts in all); the
    tires' vehicles (the thrower of what they launch); the event buffer (engine/events.py) of ``events``; the
    list of the rocks that flew in a step (engine/kernels.py impacts_loop), room for all ``cap``."""
    t, p = (max(int(x), 1) for x in bodies)
    return [FieldSpec("tire_vehicle", "i32", 1, (max(n_tires, 1),)),  # the vehicle of each splashing tire
            FieldSpec("target_vehicle", "i32", 1, (t,)),  # target k is this vehicle (scene index)
            FieldSpec("target_parts", "i32", 2, (t,)),  # its parts: first, count
            FieldSpec("target_box", "real", 6, (t,)),  # its body's box (lo, hi), body frame
            FieldSpec("part_box", "real", 6, (p,)),  # each part's box (lo, hi), body frame
            FieldSpec("part_planes", "real", 1, (p, 6, 4)),  # outward face planes (n, d)
            FieldSpec("part_corners", "real", 1, (p, 8, 3)),
            FieldSpec("part_labels", "i32", 1, (p, 6, 2)),  # per face: LABELS index ahead of / behind the split
            FieldSpec("part_split", "real", 1, (p,)),
            FieldSpec("body_rows", "f64", 2, (1 + POSE_ROWS * t,)),  # a step's time and poses (active stepping)
            FieldSpec("ev_ints", "i32", 1, (max(int(events), 1), N_INT)),
            FieldSpec("ev_reals", "real", 1, (max(int(events), 1), N_REAL)),
            FieldSpec("ev_count", "i32", 1, ()),
            FieldSpec("fly_index", "i32", 1, (cap,)),  # a rock that flew this step
            FieldSpec("fly_x0", "real", 3, (cap,)),  # its position and velocity at the step's start
            FieldSpec("fly_v0", "real", 3, (cap,)),
            FieldSpec("fly_count", "i32", 1, ())]


A_COUNTS = 8  # active stepping's counters (engine/active.py)
# World.tire_counts (engine/tires.py): the tire pass's spans (the longest ray in cells, or the largest swept box
# in cells per axis), the fullest hash slot's count (the scan's), the rocks launched in the last tire pass
SPAN_A, SPAN_B, SPAN_C, MAX_OCC, LAUNCHED = range(5)
TIRE_COUNTS = 8


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
    no "spin" or "impacts" ones."""
    return present(Plan(splash=hashed), "active" if stored else "full")


@ti.data_oriented
class World:
    """All fields of one simulation. ``n`` rocks; ``n_tires`` splashing rear tires. The fields are those of
    :func:`field_specs`; ``rocks`` the rock fields (engine/rockfields.py), each an attribute of its name."""

    def __init__(self, n: int, real, *, hash_table: int = 0, hash_entries: int = 0, n_tires: int = 0,
                 substeps: int = 1, ray_capacity: int = 0, reorder: bool = False, tiles=None,
                 tile_size: float = 1.0, store=None, rocks=None, bodies=None, events: int = 0,
                 drawn: bool = False, parallel_scan: Optional[bool] = None):
        self.n = n
        self.drawn = bool(drawn)  # the mirror changes() reads (engine/changes.py)
        self.stored = store is not None  # active stepping's tile store (below)
        self.real = real
        self.vec3 = ti.types.vector(3, real)
        self.frame_type = frame_type(real)  # a step's frame inside the kernels (engine/stepdata.py step_frame)
        self.hashed = hash_table > 0
        self.rocks = default_rock_fields(self.hashed, self.stored) if rocks is None else tuple(rocks)
        if self.hashed:
            self.table_size = hash_table
            self.entry_capacity = max(hash_entries, 1)
        # the hash's prefix sum: in parallel over blocks of slots (off the CPU) or serial (compile-time switch)
        self.scan_levels = len(scan_level_sizes(hash_table)) if self.hashed and scan_in_parallel(parallel_scan) else 0
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
        # impacts (engine/impact_pass.py): the bodies stones hit (compile-time counts) and the event buffer
        self.impacts = bodies is not None
        if self.impacts:
            self.n_targets, self.n_parts = (int(x) for x in bodies)
        trees = FieldTrees()
        for spec in field_specs(n, "f64" if real == ti.f64 else "f32", hash_table=hash_table,
                                hash_entries=hash_entries, n_tires=n_tires, substeps=substeps,
                                ray_capacity=ray_capacity, reorder=reorder, tiles=tiles, store=store,
                                rocks=self.rocks, bodies=bodies, events=events, drawn=drawn,
                                parallel_scan=self.scan_levels > 0):
            setattr(self, spec.name, trees.place(spec, real))
        trees.finalize()
        self.trees = trees  # destroyed by the pool when the process runs short of trees (_evict)
        if self.impacts:
            self.events = EventBuffer(max(int(events), 1), real, fields=(self.ev_ints, self.ev_reals, self.ev_count))
        self.owner = None  # weak reference to the Simulation using these fields (see acquire)

    def fields(self) -> list:
        """Every Taichi field of this World."""
        return [v for v in vars(self).values() if isinstance(v, Field)]

    def set_params(self, par: np.ndarray, ipar: Optional[np.ndarray] = None) -> None:
        """The scene's parameters into ``par``, and into ``ipar`` unless None (its counts, which the kernels
        update, then stay as they are), in one launch: one small kernel to compile per World, not the two of
        ``from_numpy``. The values are copied in the fields' dtypes, so the bits are those of ``from_numpy``."""
        n_int = 0 if ipar is None else len(ipar)
        if len(par) != self.par.shape[0] or n_int not in (0, self.ipar.shape[0]):
            raise ValueError(f"{len(par)} real and {n_int} integer parameters for fields of {self.par.shape[0]} "
                             f"and {self.ipar.shape[0]}")
        ints = np.zeros(1, np.int32) if ipar is None else np.ascontiguousarray(ipar, np.int32)
        _put_params(self.par, self.ipar, np.ascontiguousarray(par, self.np_real()), ints, n_int)

    def np_real(self):
        return np.float64 if self.real == ti.f64 else np.float32

    def np_dtype(self, f):
        """The NumPy dtype of rock field ``f`` (engine/rockfields.py) in this World."""
        return self.np_real() if f.dtype == "real" else np.int32


@ti.kernel
def _put_params(par: ti.template(), ipar: ti.template(), p: ti.types.ndarray(ndim=1), k: ti.types.ndarray(ndim=1),
                n_int: ti.i32):
    for i in range(p.shape[0]):
        par[i] = p[i]
    for i in range(n_int):
        ipar[i] = k[i]


@ti.func
def _zero_value(f: ti.template()):
    if ti.static(not isinstance(f, MatrixField)):
        return ti.cast(0, f.dtype)
    elif ti.static(f.m > 1):
        return ti.Matrix.zero(f.dtype, f.n, f.m)
    else:
        return ti.Vector.zero(f.dtype, f.n)


@ti.func
def _zero_at(f: ti.template(), i):
    """Element ``i`` (row-major, transfer.entry_index) of field ``f`` set to zero: a literal zero, not
    f[I] * 0 (without fast math NaN * 0 is NaN and -x * 0 is -0.0, so a World handed on would keep what its
    last owner left there)."""
    if ti.static(len(f.shape) == 0):
        if i == 0:
            f[None] = _zero_value(f)
    else:
        f[entry_index(i, ti.static(tuple(f.shape)))] = _zero_value(f)


@ti.kernel
def _zero_fields(w: ti.template()):
    # one parallel loop over the largest field's elements, zeroing the element of that index in every field that
    # has one: a kernel of one task compiles in a fraction of the time of a loop per field (each loop is a task
    # of its own, 10-20 ms of compiling apiece, 35-54 fields in a World), and it runs once per reuse of a World
    for i in range(ti.static(most_entries(w.fields()))):
        for f in ti.static(w.fields()):
            if i < ti.static(entries(f)):
                _zero_at(f, i)


_POOL = Pool()


def acquire(owner, n: int, real, **layout) -> World:
    """A World for ``owner`` (a Simulation): one of the same layout that its previous owner released (was
    garbage-collected), with every field zeroed, or else a new one.

    Every new World compiles every kernel again (its fields are template arguments: ~2-4 s on a 2-core CPU).
    Re-using released Worlds makes the second and later Simulations of a layout start at once: notebooks
    re-running a cell, parameter sweeps, tests. Two live Simulations never share a World. Released Worlds
    stay until the process runs short of SNode trees (engine/trees.py :class:`Pool`)."""
    layout = dict(layout, parallel_scan=scan_in_parallel(layout.get("parallel_scan")))  # fixed now: part of the key
    key = (int(n), str(real), tuple(sorted((k, v if not isinstance(v, list) else tuple(v)) for k, v in layout.items())))
    return _POOL.lease(owner, key, lambda: World(n, real, **layout), _zero)


def _zero(w: World) -> None:
    with warnings.catch_warnings():  # a static loop over every field: Taichi warns past 32 of them
        warnings.simplefilter("ignore", SyntaxWarning)
        _zero_fields(w)
