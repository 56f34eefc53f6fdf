"""Activity-proportional stepping (``[sim] stepping = "active"``): a step visits only the rocks something happens
to. Resting rocks wait in ground tiles; the rocks in the air, sliding or about to be touched are in a compact
active list, which is the World's rock arrays (``pos``, ``vel``, ... and ``ipar[N_ROCKS]`` their count), so the
passes of "full" stepping run on it unchanged.

Tiles. The ground is cut into square tiles of edge s (a power of two metres: 64 m is a whole number of tiles, so
the floating origin's shifts, whole multiples of 64 m, move no tile boundary). A tile's key is its integer
coordinates relative to the origin's anchor, key = floor(p_local / s) + shift / s. Keys live in a G x G table
addressed modulo G (a toroidal grid, G s > 2R + 2s): the tiles the bed covers never share a slot, and the slots
the bed's rim leaves behind are taken by the tiles it reaches. Each slot holds up to C rocks stored together
(the rock fields declared ``stored`` in engine/rockfields.py, ``ts_<name>``: position, radius, static friction,
id, the step it was last launched at; a resting rock has no velocity, and a rock out of a tile gets each other
field's rest value), its key and its count. The copies between the active list and the tiles are loops over
that declaration.

One step (two kernel launches, :func:`active_step` and :func:`active_finish`; their loops run in order):
  1. classify the occupied tiles (one thread per slot), with the bed's new centre c, its move d (old centre
     c - d) and a margin eps for rounding:
     - rim: the tile reaches outside the new disk (farthest point > R) and into the trailing crescent, the
       half-plane (q - m).d < 2 R eps behind the midpoint m = c - d / 2 of the two centres: a rock inside the
       old disk and outside the new one is there (|q - c|^2 - |q - c + d|^2 = 2 (q - m).d). A bed that did not
       move has no crescent: no rim tiles;
     - gone: the tile lies wholly outside the new disk (a jump, or the rim passed it in one step);
     - tire: the tile meets a tire's query box (the XY box of its rays at the previous and the current step,
       the swept parallelogram's fourth corner and the tread's swept footprint, grown by r_max + eps);
  2. gather: the rocks of gone tiles move to the active list in bulk (a block reserved by one atomic add per
     tile); in rim tiles each rock is tested with the rock pass's own test (bed.outside_bed), in tire tiles
     also against the boxes of the tires that marked the tile, and only those that pass move, the others are
     compacted in place;
  3. the rock pass of "full" stepping over the active list: flight, recycling, counting for the hash;
  4. the hash build and the tire pass (unchanged, over the active list);
  5. settle: active rocks at rest go to their tile (atomic slot count; a full tile keeps the rock active);
  6. compaction of the active list (survivors above the new count fill the holes below it).
Same results as "full": every rock that "full" would change this step is in the active list when the rock pass
and the tire pass run, and each one goes through the same functions with the same arguments (the random
numbers are hashes of the rock's id and the step, the first tire in scene order wins a rock);
a resting rock in the tiles is not touched by a step of "full" either (no flight, inside the bed, under no
tire). Only the memory order of the rocks differs (``state()`` is by rock id). Cost per step: the active rocks,
the rim tiles' rocks (a band one tile wide along half the rim), the tire tiles' rocks and one pass over the G^2
slots; not N.
Every loop is parallel (atomic counters, parallel compaction, the set-up of step 1 one item per band line and
per tire, the tire pass over (query, cell) with per-rock claims, engine/tires.py). The hash's prefix sum over its
table (sized to the active list) is serial on the CPU and a parallel scan over blocks elsewhere
(engine/hashgrid.py). Nothing is read back: the rocks launched stay in
``tire_counts`` until asked for (Simulation.last_launches).

Loaded rocks (a new Simulation, a restored checkpoint) all start in the active list with the tiles empty: the
first step takes every rock through its rock pass, a step of "full", and its step 5 settles the resting ones.
After coasting (engine/kernels.py ``coast_pass``, over the active list), :func:`settle` runs steps 5 and 6 alone.
"""


import math
from dataclasses import dataclass

import taichi as ti

from . import changes, hashgrid, stepdata, tirerow, tires
from .bed import outside_bed
from .kernels import impacts_loop, rock_step
from .loops import top_loop
from .patch import footprint_box
from .view import world_kernel
from .world import A0, A1, B0, CENTRE, CLOCK, LEAD, MOVE, RAY_FIELDS, RESTING, \
    TILES, IPar, Par

__all__ = ["StoreSizing", "store_sizing", "active_step", "active_finish", "settle"]

ROCKS_PER_TILE = 32  # the tile edge is the power of two giving about this many rocks per tile
NONE, RIM, TIRE, MOVE_ALL = 0, 1, 2, 3  # tile classes of a step (a tile takes the highest that applies)

# What each offloaded task of the step's two kernels does, in launch order (Taichi's kernel profiler names
# tasks by index; engine/probes.py hands these to the benchmark): serial tasks run on one thread, the others
# are parallel loops. The impacts' pass adds two tasks to active_step, a parallel scan (off the CPU) four per
# level to active_finish: task_labels() gives every variant.
TASKS = {"active_step": ("frame rows, rim plan, counters (serial)", "set-up: band widths, tire rays and boxes",
                         "(serial: bounds)", "classify rim band and tire tiles", "(serial: bounds)",
                         "gather rocks from marked tiles", "(serial: bounds)",
                         "close marked tiles; rock pass: flight, recycle, hash count"),
         "active_finish": ("counters, hash scan (serial)", "hash scatter, tire pass: query boxes", "(serial: bounds)",
                           "tire pass: claims", "(serial: launch count, bounds)",
                           "launch claimed, settle, count survivors, clear hash", "(serial: bounds)",
                           "compaction: holes and movers", "(serial: bounds)", "compaction: copy",
                           "(serial: list length)")}
IMPACT_TASKS = ("(serial: bounds)", "impacts: flying rocks against the vehicles")
# The serial variant of the step (engine/loops.py): each kernel is one serial task, its loops one after another
SERIAL_TASKS = {"active_step": ("serial variant: frame rows, rim plan, set-up, classify, gather, rock pass, "
                                "impacts",),
                "active_finish": ("serial variant: hash scan, scatter, tire pass, launch, settle, compaction",)}


def task_labels(max_levels: int = 6) -> dict:
    """Kernel name -> the variants of its tasks' labels (one tuple each, of distinct lengths): the serial
    variant of the step (one task per kernel), and the parallel one with and without impacts, with the serial
    scan or the parallel one of 1 .. ``max_levels`` levels (engine/hashgrid.py)."""
    finish = [TASKS["active_finish"]]
    for levels in range(1, max_levels + 1):
        up = [x for k in range(levels) for x in (f"hash scan: up-sweep, level {k}", "(serial: bounds)")]
        down = [x for k in reversed(range(levels)) for x in (f"hash scan: down-sweep, level {k}", "(serial: bounds)")]
        up[-1], down[-1] = "(serial: top level's scan, bounds)", "(serial: total, bounds)"
        finish.append(("counters (serial)", *up, *down, *TASKS["active_finish"][1:]))
    return {"active_step": [SERIAL_TASKS["active_step"], TASKS["active_step"], TASKS["active_step"] + IMPACT_TASKS],
            "active_finish": [SERIAL_TASKS["active_finish"], *finish]}


# World.a_counts: the active rocks still listed after settling, the holes below their count and the listed
# rocks above it (compaction), the slots marked this step (mark()), the band's widest row and column and the
# largest tire box in tiles (rim_plan, tire_boxes)
SURVIVORS, HOLES, MOVERS, MARKED, WIDTH_ROWS, WIDTH_COLS, SPAN_X, SPAN_Y = range(8)

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


# ------------------------------------------------------------------------------------------------ tiles
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


@ti.func
def mark(w: ti.template(), sl, code):
    """Raise slot sl's class to ``code``; the first mark of a step lists the slot for the gather."""
    if ti.atomic_max(w.ts_sel[sl], code) == NONE:
        w.ts_list[ti.atomic_add(w.a_counts[MARKED], 1)] = sl


@ti.func
def rim_class(w: ti.template(), lo, hi, c, mid, d, radius, eps, check_all):
    """The class of the tile [lo, hi] (grown by eps) for the bed's rim (module docstring)."""
    sel = NONE
    far = ti.max(ti.abs(lo - c), ti.abs(hi - c))
    near = ti.max(ti.max(lo - c, c - hi), 0.0)
    if near.norm_sqr() > radius * radius:
        sel = MOVE_ALL
    elif far.norm_sqr() > radius * radius:
        if check_all != 0:
            sel = RIM
        else:  # the smallest (q - mid).d over the box is at a corner
            lead = ti.min((lo[0] - mid[0]) * d[0], (hi[0] - mid[0]) * d[0]) + ti.min(
                (lo[1] - mid[1]) * d[1], (hi[1] - mid[1]) * d[1])
            if lead < 2.0 * radius * eps + eps * d.norm():
                sel = RIM
    return sel


@ti.func
def classify_slot(w: ti.template(), sl, c, mid, d, shift_tiles, radius, eps, check_all):
    if w.ts_count[sl] > 0:
        key = w.ts_key[sl] - shift_tiles
        lo = ti.Vector([ti.cast(key[0], w.real), ti.cast(key[1], w.real)]) * w.store_tile - eps
        sel = rim_class(w, lo, lo + w.store_tile + 2.0 * eps, c, mid, d, radius, eps, check_all)
        if sel != NONE:
            mark(w, sl, sel)


@ti.func
def tire_box(w: ti.template(), plan: ti.template(), t, reach):
    """XY box (lo, hi) of everything tire t can hit this step: its rays, the swept parallelogram's fourth
    corner, the tread's footprint; grown by ``reach``."""
    lo, hi = tirerow.rays_box(w, t)
    q = tirerow.xy(w, t, A1) + tirerow.xy(w, t, B0) - tirerow.xy(w, t, A0)
    lo = ti.min(lo, q)
    hi = ti.max(hi, q)
    if ti.static(plan.patch):
        if tirerow.has_tread(w, t):
            f_lo, f_hi = footprint_box(w, t)
            lo = ti.min(lo, f_lo)
            hi = ti.max(hi, f_hi)
    return lo - reach, hi + reach


@ti.func
def band_span(w: ti.template(), c, kr, outer, inner, eps, side, a):
    """The tiles (first, last index along the line) of line ``kr`` (a row of tiles for ``a`` = 1, a column for
    ``a`` = 0) that the band between the circles |q - c| = inner and outer crosses on one ``side``."""
    s = w.store_tile
    across = c[1] if a == 1 else c[0]
    along = c[0] if a == 1 else c[1]
    lo = ti.cast(kr, w.real) * s - eps
    hi = lo + s + 2.0 * eps
    d_min = ti.max(ti.max(lo - across, across - hi), 0.0)
    d_max = ti.max(ti.abs(lo - across), ti.abs(hi - across))
    x_out = ti.sqrt(ti.max(outer * outer - d_min * d_min, 0.0))
    x_in = ti.sqrt(ti.max(inner * inner - d_max * d_max, 0.0))
    sg = 1.0 - 2.0 * side
    ka = ti.cast(ti.floor((along + sg * x_in) / s), ti.i32)
    kb = ti.cast(ti.floor((along + sg * x_out) / s), ti.i32)
    return ti.min(ka, kb), ti.max(ka, kb)


@ti.func
def band_radii(w: ti.template(), c, d):
    """The band's circles (outer, inner) and the rounding margin."""
    radius = w.par[Par.BED_RADIUS]
    eps = rounding_margin(w, c)
    return radius + d.norm() + eps, ti.max(radius - eps, 0.0), eps


@ti.func
def rim_plan(w: ti.template(), c, d, check_all):
    """Step 1's plan for the bed's rim (module docstring), as one flat index range: the slots to test when
    every slot is (``check_all`` or a move of more than 4 tiles), else the band of tiles the circle
    |q - c| = R crosses, widened by the move (a tile whose rocks were inside the old disk and are not all
    inside the new one lies in it); none for a bed that did not move. The band is walked by rows of tiles
    where the circle is steep (|y - c_y| <= 3/4 of its radius) and by columns elsewhere, each line as wide as
    the widest line of its kind (:func:`band_width`, one item per line and side of the set-up loop), a few
    tiles, not the width of the band's top row. A tile in no walked row has |y - c_y| > 3/4 r_out everywhere,
    so its band points have |x - c_x| < 3/4 r_out: its column is walked. Returns (every, lines per kind, first
    row, first column); O(1)."""
    s = w.store_tile
    outer, _, _ = band_radii(w, c, d)
    every, lines = 0, 0
    reach = 0.75 * outer
    k0 = ti.Vector([ti.cast(ti.floor((c[1] - reach) / s), ti.i32), ti.cast(ti.floor((c[0] - reach) / s), ti.i32)])
    if ti.static(w.recycles_rocks):
        if check_all != 0 or d.norm() > 4.0 * s:
            every = w.store_grid * w.store_grid
        elif d.norm() > 0.0:
            lines = ti.cast(ti.floor((c[1] + reach) / s), ti.i32) - k0[0] + 1  # as many columns: a square
    return every, lines, k0


@ti.func
def band_width(w: ti.template(), q, c, d, lines, k0):
    """Item q of the band's (kind, line, side) (kind 0 rows, 1 columns): its tiles, into the widest line of
    its kind (``a_counts[WIDTH_ROWS + kind]``, an atomic maximum)."""
    outer, inner, eps = band_radii(w, c, d)
    kind = q // (2 * lines)
    first = k0[0] if kind == 0 else k0[1]  # (no dynamic index into a local vector: SPIR-V)
    lo, hi = band_span(w, c, first + (q // 2) % lines, outer, inner, eps, q % 2, 1 - kind)
    ti.atomic_max(w.a_counts[WIDTH_ROWS + kind], hi - lo + 2)


@ti.func
def band_slot(w: ti.template(), q, c, d, shift_tiles, lines, width, k0):
    """The slot of item q of the band's lines (kind, line, side, tile along it), or -1: none there, or the
    slot holds another tile."""
    outer, inner, eps = band_radii(w, c, d)
    rows = lines * 2 * width[0]
    kind = 0 if q < rows else 1
    r = q if q < rows else q - rows
    wk = width[0] if kind == 0 else width[1]  # (no dynamic index into a local vector: Taichi 1.7.4's SPIR-V
    kr = (k0[0] if kind == 0 else k0[1]) + r // (2 * wk)  # code generator fails on it)
    lo, hi = band_span(w, c, kr, outer, inner, eps, (r // wk) % 2, 1 - kind)
    ka = lo + r % wk
    sl = -1
    if ka <= hi:
        key = ti.Vector([ka, kr]) if kind == 0 else ti.Vector([kr, ka])
        key += shift_tiles
        sl = slot_of(w, key)
        if not same_key(w.ts_key[sl], key):
            sl = -1
    return sl


@ti.func
def take_tire(w: ti.template(), plan: ti.template(), k, t, c, shift_tiles):
    """Step 1 for tire t of step row ``k``: its ray row into ``w.ray`` (the layout every tire function reads,
    in the World's precision), its query box to ``w.tire_box`` and its tiles (first and last key) to
    ``w.tire_keys``; the largest box's size in tiles into ``a_counts[SPAN_X]``, ``[SPAN_Y]`` (atomic maxima)."""
    for f in range(RAY_FIELDS):
        w.ray[t, f] = ti.cast(w.step_rays[k, t, f], w.real)
    reach = w.par[Par.R_MAX] + rounding_margin(w, c)
    g = w.store_grid
    lo, hi = tire_box(w, plan, t, reach)
    on = tirerow.near_bed(w, t)
    w.tire_box[t] = ti.Vector([lo[0], lo[1], hi[0], hi[1]]) if on else ti.Vector([1.0, 1.0, -1.0, -1.0])
    k_lo = tile_key(w, lo, shift_tiles)
    k_hi = ti.min(tile_key(w, hi, shift_tiles), k_lo + g - 1)
    key = ti.Vector([k_lo[0], k_lo[1], k_hi[0], k_hi[1]]) if on else ti.Vector([0, 0, -1, -1])
    w.tire_keys[t] = key
    ti.atomic_max(w.a_counts[SPAN_X], key[2] - key[0] + 1)
    ti.atomic_max(w.a_counts[SPAN_Y], key[3] - key[1] + 1)


@ti.func
def classify_tire_tile(w: ti.template(), q, span_x, span_y):
    """Item q of (tire, tile of the largest box): mark the occupied tile under tire t's box, noting the tire
    (bit t mod 32 of ``w.ts_tires``)."""
    t = q // (span_x * span_y)
    a = (q // span_y) % span_x
    b = q % span_y
    k = w.tire_keys[t]
    if k[0] + a <= k[2] and k[1] + b <= k[3]:
        key = ti.Vector([k[0] + a, k[1] + b])
        sl = slot_of(w, key)
        if w.ts_count[sl] > 0 and same_key(w.ts_key[sl], key):
            ti.atomic_or(w.ts_tires[sl], 1 << (t & 31))
            mark(w, sl, TIRE)


@ti.func
def classify(w: ti.template(), plan: ti.template(), k, c, d, shift_tiles, check_all):
    """Step 1 of step row ``k`` in two parallel tasks: the set-up (one item per band line and side: the
    widest line of each kind, rim_plan; one per tire: its rays taken in and its box, take_tire), then the
    rim's slots or band and the tires' tiles, one flat loop over all their items (Taichi runs only top-level
    loops in parallel, each a task with its own start-up; and on Vulkan (Taichi 1.7.4) an atomic on one
    address inside an inner loop whose trip count differs between threads loses iterations, so no loop here
    has a varying inner loop around an atomic)."""
    every, lines, k0 = rim_plan(w, c, d, check_all)
    for m in ti.static((WIDTH_ROWS, WIDTH_COLS, SPAN_X, SPAN_Y)):
        w.a_counts[m] = 0
    n_tires = 0
    if ti.static(plan.splash):
        n_tires = w.n_tires
    top_loop(plan)
    for q in range(4 * lines + n_tires):
        if q < 4 * lines:
            band_width(w, q, c, d, lines, k0)
        else:
            if ti.static(plan.splash):
                take_tire(w, plan, k, q - 4 * lines, c, shift_tiles)
    width = ti.Vector([w.a_counts[WIDTH_ROWS], w.a_counts[WIDTH_COLS]])
    span_x, span_y = w.a_counts[SPAN_X], w.a_counts[SPAN_Y]
    n_band = lines * 2 * (width[0] + width[1])
    n_tire = n_tires * span_x * span_y
    radius = w.par[Par.BED_RADIUS]
    eps = rounding_margin(w, c)
    top_loop(plan)
    for q in range(every + n_band + n_tire):
        if q < every + n_band:
            sl = q
            if q >= every:  # (not a conditional expression: Taichi evaluates both of its sides)
                sl = band_slot(w, q - every, c, d, shift_tiles, lines, width, k0)
            if sl >= 0:
                classify_slot(w, sl, c, c - 0.5 * d, d, shift_tiles, radius, eps, check_all)
        else:
            if ti.static(plan.splash):
                classify_tire_tile(w, q - every - n_band, span_x, span_y)


@ti.func
def under_a_tire(w: ti.template(), p, bits):
    """Is the point p in the query box of one of the tires whose bits (t mod 32) are set?"""
    hit = False
    for t in range(w.n_tires):
        if not hit and (bits >> (t & 31)) & 1 != 0:
            b = w.tire_box[t]
            hit = b[0] <= p[0] <= b[2] and b[1] <= p[1] <= b[3]
    return hit


@ti.func
def to_active(w: ti.template(), j, a):
    """Copy stored rock j (store index) to active index a, at rest: every carried rock field, from the tiles
    or (not stored) its rest value (engine/rockfields.py)."""
    for f in ti.static(w.rocks):
        if ti.static(f.stored):
            ti.static(getattr(w, f.name))[a] = ti.static(getattr(w, f.store_name))[j]
        elif ti.static(f.carried):
            g = ti.static(getattr(w, f.name))
            if ti.static(f.n > 1):
                g[a] = ti.Vector(ti.static([f.rest] * f.n), dt=g.dtype)
            else:
                g[a] = f.rest


@ti.func
def store_copy(w: ti.template(), src, dst):
    """Stored rock src to store index dst (every stored field)."""
    for f in ti.static(w.rocks):
        if ti.static(f.stored):
            g = ti.static(getattr(w, f.store_name))
            g[dst] = g[src]


@ti.func
def to_store(w: ti.template(), i, j):
    """Active rock i to store index j (every stored field)."""
    for f in ti.static(w.rocks):
        if ti.static(f.stored):
            ti.static(getattr(w, f.store_name))[j] = ti.static(getattr(w, f.name))[i]


@ti.func
def gather(w: ti.template(), plan: ti.template(), c):
    """Step 2, one flat loop over (marked tile, rock): a gone tile's rocks all move to the active list, a rim or
    tire tile's those that leave (see classify on inner loops); each rock that moves gets id -1 in its tile."""
    cap = w.store_capacity
    radius = w.par[Par.BED_RADIUS]
    ground = w.par[Par.GROUND_Z]
    top_loop(plan)
    for k, j in ti.ndrange(w.a_counts[MARKED], cap):
        t = w.ts_list[k]
        if j < w.ts_count[t]:
            sel = w.ts_sel[t]
            leave = True
            if sel != MOVE_ALL:
                p = w.ts_pos[t * cap + j]
                leave = outside_bed(p, c, radius, ground)
                if ti.static(w.n_tires > 0):
                    if sel == TIRE and not leave:
                        leave = under_a_tire(w, p, w.ts_tires[t])
            if leave:
                to_active(w, t * cap + j, ti.atomic_add(w.ipar[IPar.N_ROCKS], 1))
                w.ts_rock_id[t * cap + j] = -1


@ti.func
def close_tile(w: ti.template(), k):
    """After step 2: marked tile k's remaining rocks compacted in place, its marks cleared (an item of the rock
    pass's loop in active_step: the two touch different fields, and one loop is one parallel task less)."""
    cap = w.store_capacity
    t = w.ts_list[k]
    keep = 0
    for j in range(w.ts_count[t]):
        if w.ts_rock_id[t * cap + j] >= 0:
            if keep != j:
                store_copy(w, t * cap + j, t * cap + keep)
            keep += 1
    w.ts_count[t] = keep
    w.ts_sel[t] = NONE
    if ti.static(w.n_tires > 0):
        w.ts_tires[t] = 0


@ti.func
def settle_rocks(w: ti.template(), shift_tiles, clear_hash: ti.template(), plan: ti.template(), step):
    """Step 5: active rocks at rest join their tile (they are inside the bed: the rock pass recycled those
    outside); one whose tile is full (or, never in a bed, taken by another key) stays active. Settled rocks
    get id -1 in the active list; those still listed are counted (SURVIVORS, for the compaction). With
    ``clear_hash`` (after the tire pass's claims, ``plan`` its switches), the same loop first launches each
    claimed rock (engine/tires.py launch_if_claimed: the rock's own thread, so before its settling) and
    clears the hash's counts for the next step (no barrier is needed between the two: both only follow the
    claims)."""
    cap = w.store_capacity
    n = w.ipar[IPar.N_ROCKS]
    total = n
    if ti.static(clear_hash):
        total = ti.max(n, hashgrid.table_n(w) + 1)
    top_loop(plan)
    for i in range(total):
        if i < n:
            if ti.static(clear_hash):
                tires.launch_if_claimed(w, plan, i, step)
            changes.note(w, i)  # what a reader of changes() sees: this step's state, before the rock leaves
            if w.phase[i] == RESTING:
                key = tile_key(w, w.pos[i], shift_tiles)
                sl = slot_of(w, key)
                if w.ts_count[sl] == 0:
                    w.ts_key[sl] = key
                if same_key(w.ts_key[sl], key):
                    k = ti.atomic_add(w.ts_count[sl], 1)
                    if k >= cap:  # full: undo (the count never drops below cap again, so slots stay distinct)
                        ti.atomic_sub(w.ts_count[sl], 1)
                    else:
                        to_store(w, i, sl * cap + k)
                        w.rock_id[i] = -1
            if w.rock_id[i] >= 0:
                ti.atomic_add(w.a_counts[SURVIVORS], 1)
        if ti.static(clear_hash):
            if i <= hashgrid.table_n(w):
                w.cell_start[i] = 0


@ti.func
def active_copy(w: ti.template(), src, dst):
    """Active rock src to active index dst (every carried rock field)."""
    for f in ti.static(w.rocks):
        if ti.static(f.carried):
            g = ti.static(getattr(w, f.name))
            g[dst] = g[src]


@ti.func
def compact(w: ti.template(), plan: ti.template()):
    """Step 6, after settle_rocks counted the survivors: the active rocks still listed (id >= 0) end up in
    0 .. count - 1: those above the new count fill the holes below it (atomic lists of both, paired by their
    order in the lists)."""
    cnt = ti.static(w.a_counts)
    n = w.ipar[IPar.N_ROCKS]
    keep = cnt[SURVIVORS]
    top_loop(plan)
    for i in range(n):
        alive = w.rock_id[i] >= 0
        if i < keep and not alive:
            w.a_hole[ti.atomic_add(cnt[HOLES], 1)] = i
        elif i >= keep and alive:
            w.a_mover[ti.atomic_add(cnt[MOVERS], 1)] = i
    top_loop(plan)
    for k in range(cnt[HOLES]):
        active_copy(w, w.a_mover[k], w.a_hole[k])
    w.ipar[IPar.N_ROCKS] = keep


@ti.func
def reset_counts(w: ti.template()):
    for k in ti.static((SURVIVORS, HOLES, MOVERS)):
        w.a_counts[k] = 0


# ------------------------------------------------------------------------------------------------ kernels
@ti.func
def finish(w: ti.template(), plan: ti.template(), shift_tiles, step):
    """Steps 4 to 6: the hash build and the tire pass over the active list (the rocks it launched stay on the
    device: ``tire_counts[LAUNCHED]``), settling, compaction."""
    w.a_counts[MARKED] = 0
    reset_counts(w)
    if ti.static(plan.splash):
        hashgrid.scan_counts(w, plan)
        tires.scatter_and_launch(w, plan, step, False)  # settle_rocks launches the claimed rocks
    settle_rocks(w, shift_tiles, plan.splash, plan, step)
    compact(w, plan)


@world_kernel
def active_step(w: ti.template(), plan: ti.template(), k: ti.i32, step: ti.i32, check_all: ti.i32):
    """Steps 1 to 3 of active stepping (module docstring), its inputs row ``k`` of the batch on the device
    (engine/stepdata.py): tiles classified and gathered, the rock pass over the active list. ``check_all``:
    test every rim tile's rocks against the new disk whatever the move (the first step after rocks were
    loaded). Two kernels, not one: Taichi 1.7.4 compiles the two in about two thirds of the time it takes for
    them fused (measured by ``bench --only activity``: compile times), for one more launch of three scalars."""
    if ti.static(plan.impacts):
        stepdata.take_bodies(w, k)
    c = stepdata.frame_row(w, k, CENTRE)
    m = stepdata.frame_row(w, k, MOVE)
    d = stepdata.frame_row(w, k, LEAD)
    st = ti.cast(w.step_frame[k, TILES], ti.i32)
    h = ti.cast(w.step_frame[k, CLOCK][0], w.real)
    fr = stepdata.step_frame(w, h, c, m, d, c)  # no tire mask: its corner (grid) is unused
    classify(w, plan, k, c, m, st, check_all)
    gather(w, plan, c)
    if ti.static(plan.impacts):
        w.fly_count[None] = 0
    marked = w.a_counts[MARKED]
    top_loop(plan)
    for q in range(marked + w.ipar[IPar.N_ROCKS]):
        if q < marked:
            close_tile(w, q)
        else:
            rock_step(w, plan, q - marked, fr, step, False)
    if ti.static(plan.impacts):  # the step's time and poses from its batch row (engine/stepdata.py)
        impacts_loop(w, plan, fr, step, False, w.body_rows, 0)


@world_kernel
def active_finish(w: ti.template(), plan: ti.template(), k: ti.i32, step: ti.i32):
    """Steps 4 to 6 (finish) of step row ``k``: no value comes back (a returned value waits for the device)."""
    finish(w, plan, ti.cast(w.step_frame[k, TILES], ti.i32), step)


@world_kernel
def settle(w: ti.template(), tiles: vec2):
    """Steps 5 and 6 alone, after coasting."""
    reset_counts(w)
    settle_rocks(w, ti.cast(tiles, ti.i32), False, None, 0)
    compact(w, None)
