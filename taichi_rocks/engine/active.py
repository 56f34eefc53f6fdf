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


import taichi as ti

from . import changes, hashgrid, stepdata, tires
from .bed import outside_bed
from .classify import HOLES, MARKED, MOVE_ALL, MOVERS, NONE, SURVIVORS, TIRE, classify, under_a_tire
from .kernels import impacts_loop, rock_step
from .loops import top_loop
from .tiles import ROCKS_PER_TILE, StoreSizing, same_key, slot_of, store_sizing, tile_key, vec2  # noqa: F401
from .view import world_kernel
from .world import CENTRE, CLOCK, LEAD, MOVE, RESTING, TILES, IPar, Par

__all__ = ["StoreSizing", "store_sizing", "active_step", "active_finish", "settle"]


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
