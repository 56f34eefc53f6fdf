"""The Taichi fields of one simulation, allocated once from a Scene, and nothing else.

Rock state is structure-of-arrays (one field per quantity, declared in engine/rockfields.py) in the bed's
*local* frame: world position = ``origin`` (float64, host) + local position (f32 or f64). Fields of a pass are
allocated only when the scene asks for that pass: no hash table without splashing tires, no ray buffers without
tires. :func:`field_specs` lists every field of a layout; the World allocates exactly that list, and the memory
estimate (engine/layout.py) adds it up.
"""


import math
import weakref
from dataclasses import dataclass
from typing import Optional

import numpy as np
import taichi as ti

from ..config.environment import PARALLEL_SCAN, parallel_scan_wanted  # noqa: F401 - PARALLEL_SCAN re-exported
from ..config.plan import Plan
from .events import N_INT, N_REAL, EventBuffer, record_type
from .params import IPar, Par  # the indices of World.par and World.ipar (also imported from here)
from .rockfields import FLYING, RESTING, SLIDING, present  # noqa: F401 - the phase codes, re-exported
from .view import GROUP_NAMES, GROUPS, REAL_SIZES, SIZES
from .worlddata import HostField, Layout, Placement, copy_launchers, group_dtype, group_of, np_group_dtype

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


# fields whose dimensions past the first depend on the World's sizes (the tire mask's tiles, a ray's cells): the
# kernels read them at run time; every other field's are the layout's (tests/engine/test_world.py checks it)
SIZED_TAILS = frozenset({"tile_mask", "ray_cells"})
SCAN_LEVELS = 5  # the parallel scan's levels, whatever the table (32^6 slots at most): sizes stay out of a layout


def scan_level_sizes(table: int) -> tuple:
    """The block sums of the hash's parallel prefix sum over ``table`` slots, one field per level: level k
    holds ceil(table / 32^(k + 1)) sums (at least one), SCAN_LEVELS levels, and the last (at most 32 sums) is
    scanned by one thread; a level of one block scans as one, so levels beyond the table's need change no
    sum."""
    if int(table) > SCAN_BLOCK ** (SCAN_LEVELS + 1):
        raise ValueError(f"a hash table of {table} slots: more than the parallel scan's {SCAN_LEVELS} levels hold")
    return tuple(max(1, -(-int(table) // SCAN_BLOCK ** (k + 1))) for k in range(SCAN_LEVELS))


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
            FieldSpec("launches", "i64", 1, ()), FieldSpec("recycles", "i64", 1, ()),
            FieldSpec("origin_move", "f64", 2, (3,))]  # the floating origin's move (engine/origin.py)
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


class World:
    """All the data of one simulation, in the ndarray groups of engine/view.py (``groups``, in its order) at the
    places of a :class:`~taichi_rocks.engine.worlddata.Placement`; ``layout`` says how kernels read them (the
    key they compile by: the same for every World of the same fields and switches, whatever its sizes). Each
    field of :func:`field_specs` is an attribute of its name, a
    :class:`~taichi_rocks.engine.worlddata.HostField` (``to_numpy``, ``from_numpy``, ``fill``, ``[i]``); ``n``
    rocks; ``n_tires`` splashing rear tires; ``rocks`` the rock fields (engine/rockfields.py)."""

    def __init__(self, n: int, real, *, hash_table: int = 0, hash_entries: int = 0, n_tires: int = 0,
                 substeps: int = 1, ray_capacity: int = 0, reorder: bool = False, tiles=None,
                 tile_size: float = 1.0, store=None, rocks=None, bodies=None, events: int = 0,
                 drawn: bool = False, parallel_scan: Optional[bool] = None):
        self.n = n
        self.drawn = bool(drawn)  # the mirror changes() reads (engine/changes.py)
        self.stored = store is not None  # active stepping's tile store (below)
        self.real = real
        self.vec3 = vector_type(3, real)
        self.frame_type = frame_type(real)  # a step's frame inside the kernels (engine/stepdata.py step_frame)
        self.hashed = hash_table > 0
        self.rocks = default_rock_fields(self.hashed, self.stored) if rocks is None else tuple(rocks)
        self.table_size = int(hash_table)
        self.entry_capacity = max(int(hash_entries), 1) if self.hashed else 0
        # the hash's prefix sum: in parallel over blocks of slots (off the CPU) or serial (compile-time switch);
        # always SCAN_LEVELS levels, whatever the table (a level of one block scans as one): sizes stay out of
        # the layout
        self.scan_levels = SCAN_LEVELS if self.hashed and scan_in_parallel(parallel_scan) else 0
        # scope "tires": a coarse XY mask around the tires' query regions; only rocks on marked tiles are
        # hashed, listed in `listed` (compile-time switch: `masked`)
        self.masked = self.hashed and tiles is not None
        self.tiles = tuple(int(t) for t in tiles) if self.masked else (0, 0)
        self.tiles_x, self.tiles_y = self.tiles
        self.tile_size = float(tile_size) if self.masked else 0.0
        self.n_tires = n_tires
        self.substeps = substeps
        self.n_rays = n_tires * substeps
        self.ray_capacity = int(ray_capacity) if n_tires > 0 else 0
        self.reorder = reorder
        # active stepping (engine/active.py): resting rocks in ground tiles; the rock arrays are the active
        # list (ipar[N_ROCKS] rocks). ``store``: (tile edge, slots per axis, rocks per slot, recycle?)
        self.store_tile, self.store_grid, self.store_capacity, self.recycles_rocks = 0.0, 0, 0, False
        if self.stored:
            tile, grid, capacity, recycle = store
            self.store_tile, self.store_grid, self.store_capacity = float(tile), int(grid), int(capacity)
            self.recycles_rocks = bool(recycle)
        # impacts (engine/impact_pass.py): the bodies stones hit (compile-time counts) and the event buffer
        self.impacts = bodies is not None
        self.n_targets, self.n_parts = (int(x) for x in bodies) if self.impacts else (0, 0)
        self.event_capacity = max(int(events), 1) if self.impacts else 0
        self.event_record = record_type(real) if self.impacts else None  # (engine/events.py, w.events.record)
        specs = field_specs(n, "f64" if real == ti.f64 else "f32", hash_table=hash_table, hash_entries=hash_entries,
                            n_tires=n_tires, substeps=substeps, ray_capacity=ray_capacity, reorder=reorder,
                            tiles=tiles, store=store, rocks=self.rocks, bodies=bodies, events=events, drawn=drawn,
                            parallel_scan=self.scan_levels > 0)
        self.layout = Layout(tuple((sp.name, *group_of(sp.dtype, sp.n), len(sp.shape),
                                    None if sp.name in SIZED_TAILS else tuple(sp.shape[1:])) for sp in specs),
                             tuple((k, getattr(self, k)) for k in STATICS))
        sizes = {k: getattr(self, k) for k in SIZES}
        place = Placement(specs, sizes, {k: getattr(self, k) for k in REAL_SIZES})
        np_real = self.np_real()
        # (Taichi fills a new ndarray with zeros: every field starts as a new Taichi field did)
        self.groups = tuple(ti.ndarray(group_dtype(g, real), place.lengths[g]) for g in GROUP_NAMES)
        self.placement = place
        by_group = dict(zip(GROUP_NAMES, self.groups))
        copies = copy_launchers()  # the fields' copies at the cost of their launch (engine/launcher.py)
        for sp in specs:
            group, row, offset, shape = place.at[sp.name]
            width = GROUPS[group][1]
            setattr(self, sp.name, HostField(sp.name, by_group[group], offset, row, shape,
                                             np_group_dtype(group, np_real), width, copies))
        self._head = HostField("head", by_group["i1"], 0, 0, (len(place.head),), np.int32, 1)
        self._head.from_numpy(place.head)
        self._real_head = HostField("real head", by_group["r1"], 0, 0, (len(place.real_head),), np_real, 1)
        self._real_head.from_numpy(place.real_head.astype(np_real))
        if self.impacts:
            self.events = EventBuffer(self.event_capacity, real, world=self)
        self.owner = None  # weak reference to the Simulation using these fields (see acquire)

    def fields(self) -> list:
        """Every field of this World (HostFields)."""
        return [v for v in vars(self).values() if isinstance(v, HostField) and not v.name.endswith("head")]

    def nbytes(self) -> int:
        """Bytes of the World's groups on the device (its fields, the table of where they lie, row alignment)."""
        return self.placement.nbytes("f64" if self.real == ti.f64 else "f32")

    def set_params(self, par: np.ndarray, ipar: Optional[np.ndarray] = None) -> None:
        """The scene's parameters into ``par``, and into ``ipar`` unless None (its counts, which the kernels
        update, then stay as they are). The values are copied in the fields' dtypes, so the bits are those of
        ``from_numpy``."""
        n_int = 0 if ipar is None else len(ipar)
        if len(par) != self.par.shape[0] or n_int not in (0, self.ipar.shape[0]):
            raise ValueError(f"{len(par)} real and {n_int} integer parameters for fields of {self.par.shape[0]} "
                             f"and {self.ipar.shape[0]}")
        self.par.from_numpy(np.ascontiguousarray(par, self.np_real()))
        if ipar is not None:
            self.ipar.from_numpy(np.ascontiguousarray(ipar, np.int32))

    def np_real(self):
        return np.float64 if self.real == ti.f64 else np.float32

    def np_dtype(self, f):
        """The NumPy dtype of rock field ``f`` (engine/rockfields.py) in this World."""
        return self.np_real() if f.dtype == "real" else np.int32


# the World's attributes kernels read at compile time (its layout's statics; engine/view.py View)
STATICS = ("real", "vec3", "frame_type", "hashed", "scan_levels", "masked", "n_tires", "substeps", "n_rays",
           "reorder", "stored", "recycles_rocks", "impacts", "n_targets", "n_parts", "rocks", "drawn", "event_record")
_TYPES: dict = {}


def vector_type(n: int, real):
    """One Taichi vector type object per (n, precision): a layout's statics compare equal across Worlds."""
    return _TYPES.setdefault(("vec", n, str(real)), ti.types.vector(n, real))


def acquire(owner, n: int, real, **layout) -> World:
    """A World for ``owner`` (a Simulation): a new one (its ndarrays zeroed). Its kernels compile once per layout
    and switches, not per World (engine/view.py): a second Simulation of another rock count starts without
    compiling."""
    layout = dict(layout, parallel_scan=scan_in_parallel(layout.get("parallel_scan")))
    w = World(n, real, **layout)
    w.owner = weakref.ref(owner)
    return w
