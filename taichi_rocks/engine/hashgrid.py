"""Spatial hash of the rocks, rebuilt every step, and the cells a tire ray crosses.

Cell of a point:  (i, j, k) = (floor(x / l), floor(y / l), floor(z / l)).
Slot of a cell:   hash = (i*p1 xor j*p2 xor k*p3) mod n,  p1, p2, p3 = 73856093, 19349663, 83492791
                  (Teschner et al. 2003). The products wrap around in 32-bit unsigned arithmetic (a negative
                  index is its two's complement) and the modulo is unsigned, so every slot is in [0, n) for
                  negative cells and for cells far from the origin alike.
Build:            count per slot -> inclusive prefix sum -> scatter with a decrementing cursor, so
                  ``cell_start[s] .. cell_start[s+1]`` lists the rocks of slot s. The table holds every
                  (rock, cell) pair: nothing can overflow. Two insert modes:
                  "aabb"   - every cell the rock's AABB [c - r, c + r] touches (the original design);
                  "center" - only the cell of the rock's centre; queries then visit the cells within
                             D = floor(r_max / l) + 1 of each cell a ray crosses. Both find the same hits.
Ray cells:        3D DDA (Amanatides & Woo 1987), with two safety rules: the number of steps per axis is
                  fixed by the end cell (no rounding can run past it), and near-ties between axes visit
                  both neighbours (supercover), so a segment grazing an edge or corner misses no cell.
"""


import taichi as ti

from . import tirerow
from .loops import top_loop
from .world import FLYING, MAX_OCC, SCAN_BLOCK, IPar, P1, P2, P3, Par
from .view import world_kernel


@ti.func
def cell_of(p, cell):
    """Integer cell of a point (a 3-vector), cell edge `cell`."""
    return ti.cast(ti.floor(p / cell), ti.i32)


@ti.func
def hash_cell(c, n):
    """Teschner hash of an integer cell, in [0, n): 32-bit wrap-around products, unsigned modulo."""
    h = (ti.cast(c[0], ti.u32) * ti.u32(P1)) ^ (ti.cast(c[1], ti.u32) * ti.u32(P2)) ^ (
        ti.cast(c[2], ti.u32) * ti.u32(P3))
    return ti.cast(h % ti.cast(n, ti.u32), ti.i32)


@ti.func
def aabb_cells(p, r, cell):
    """First and last cell of the AABB of a sphere."""
    return cell_of(p - r, cell), cell_of(p + r, cell)


@ti.func
def table_n(w: ti.template()):
    """Slots of the table in use: its size, or with active stepping the runtime size ``ipar[TABLE]`` (<= the
    size; the simulation fits it to the active list)."""
    n = w.table_size
    if ti.static(w.stored):
        n = w.ipar[IPar.TABLE]
    return n


# ---------------------------------------------------------------------------------------------------
# Build: count (fused into the rock pass by the simulation), scan, scatter.

@ti.func
def near_a_tire(w: ti.template(), p, grid_origin):
    """Scope "tires": is the rock on a tile of the mask (tiles around every tire's query region)?"""
    inv = 1.0 / w.tile_size  # a compile-time constant: a multiply, not a division, per rock
    tx = ti.cast(ti.floor((p[0] - grid_origin[0]) * inv), ti.i32)
    ty = ti.cast(ti.floor((p[1] - grid_origin[1]) * inv), ti.i32)
    near = False
    if 0 <= tx < w.tiles[0] and 0 <= ty < w.tiles[1]:
        near = w.tile_mask[tx, ty] != 0
    return near


@ti.func
def mark_tire_tiles(w: ti.template(), grid_origin):
    """Scope "tires": clear the tile mask, then mark the tiles of every active tire's query region (the XY
    box of its ray at the previous and the current step, grown by the query's reach)."""
    for tx, ty in ti.ndrange(w.tiles[0], w.tiles[1]):
        w.tile_mask[tx, ty] = 0
    margin = w.par[Par.MARGIN]
    ti.loop_config(serialize=True)
    for t in range(w.n_tires):
        if tirerow.near_bed(w, t):
            lo, hi = tirerow.rays_box(w, t)
            # one more tile on each side: the per-rock lookup rounds differently (it multiplies)
            t_lo = ti.cast(ti.floor((lo - margin - grid_origin) / w.tile_size), ti.i32) - 1
            t_hi = ti.cast(ti.floor((hi + margin - grid_origin) / w.tile_size), ti.i32) + 1
            for a in range(ti.max(t_lo[0], 0), ti.min(t_hi[0], w.tiles[0] - 1) + 1):
                for b in range(ti.max(t_lo[1], 0), ti.min(t_hi[1], w.tiles[1] - 1) + 1):
                    w.tile_mask[a, b] = 1


@ti.func
def count_rock(w: ti.template(), i, center: ti.template(), grid_origin):
    """Add rock i to the per-slot counts (cell_start doubles as the count array). With a mask, rocks
    away from every tire are skipped and the others listed for the scatter."""
    take = True
    if ti.static(w.masked):
        take = near_a_tire(w, w.pos[i], grid_origin)
        if take:
            w.listed[ti.atomic_add(w.n_listed[None], 1)] = i
    if take:
        cell = w.par[Par.CELL]
        p = w.pos[i]
        if ti.static(center):
            s = hash_cell(cell_of(p, cell), table_n(w))
            w.slot[i] = s
            ti.atomic_add(w.cell_start[s], 1)
        else:
            lo, hi = aabb_cells(p, w.radius[i], cell)
            for a in range(lo[0], hi[0] + 1):
                for b in range(lo[1], hi[1] + 1):
                    for c in range(lo[2], hi[2] + 1):
                        ti.atomic_add(w.cell_start[hash_cell(ti.Vector([a, b, c]), table_n(w))], 1)


@ti.func
def clear_all(w: ti.template(), plan: ti.template()):
    top_loop(plan)
    for s in range(table_n(w) + 1):
        w.cell_start[s] = 0
    if ti.static(w.masked):
        w.n_listed[None] = 0


@world_kernel
def clear_counts(w: ti.template()):
    clear_all(w, None)


@world_kernel
def count_all(w: ti.template(), center: ti.template(), gx: ti.f64, gy: ti.f64):
    """Count pass alone (the simulation fuses it into the rock pass; kept for tests and profiling)."""
    g = ti.Vector([ti.cast(gx, w.real), ti.cast(gy, w.real)])
    if ti.static(w.masked):
        mark_tire_tiles(w, g)
    for i in range(w.ipar[IPar.N_ROCKS]):
        count_rock(w, i, center, g)


@ti.func
def scan_counts(w: ti.template(), plan: ti.template()):
    """Inclusive prefix sum of the counts of the table's slots in use, in place; cell_start[n] = total; the
    fullest slot's count to ``tire_counts[MAX_OCC]`` (the tire pass's places per slot, engine/tires.py).

    Serial on the CPU (about a nanosecond per slot), in parallel over blocks of slots elsewhere
    (:func:`block_scan`; ``World.scan_levels``). ti.algorithms.PrefixSumExecutor is not used: it refuses the CPU
    backend, and on Vulkan it relies on the subgroup size (on Mesa lavapipe it gives wrong sums past 63 slots).
    The sums are integers: both ways give the same bits.
    """
    if ti.static(w.scan_levels > 0):
        block_scan(w, plan)
    else:
        n = table_n(w)
        most = w.cell_start[0]
        ti.loop_config(serialize=True)
        for s in range(1, n):
            most = ti.max(most, w.cell_start[s])
            w.cell_start[s] += w.cell_start[s - 1]
        w.cell_start[n] = w.cell_start[n - 1]
        w.tire_counts[MAX_OCC] = most


def scan_level(w, k: int):
    """Level k of the parallel scan (compile time): the slots' counts (k = 0), else level k - 1's block sums."""
    return w.cell_start if k == 0 else getattr(w, "scan_sums" + str(k - 1))


@ti.func
def level_count(n, k: ti.template()):
    """Entries of level k of the parallel scan over n slots: ceil(n / 32^k) (level 0: the slots)."""
    size = ti.static(SCAN_BLOCK ** k)
    return (n + size - 1) // size


@ti.func
def scan_blocks(src: ti.template(), dst: ti.template(), m, counts: ti.template(), slots: ti.template(),
                plan: ti.template()):
    """Up-sweep of one level: each block of 32 entries of ``src`` (m in use) scanned in place by one thread, its
    total to ``dst``; on the slots' level (``slots``), the largest count to ``counts[MAX_OCC]``."""
    top_loop(plan)
    for b in range((m + SCAN_BLOCK - 1) // SCAN_BLOCK):
        total = 0
        top = 0
        for j in ti.static(range(SCAN_BLOCK)):
            i = b * SCAN_BLOCK + j
            if i < m:
                v = src[i]
                top = ti.max(top, v)
                total += v
                src[i] = total
        dst[b] = total
        if ti.static(slots):
            ti.atomic_max(counts[MAX_OCC], top)


@ti.func
def block_scan(w: ti.template(), plan: ti.template()):
    """The parallel inclusive scan (Blelloch's two sweeps over blocks, 1990, with blocks of 32 and one thread
    per block): up-sweep, each level's blocks scanned in place and their totals one level up
    (``scan_sums<k>``, world.scan_level_sizes); the last level (at most 32 sums) by one thread; down-sweep,
    each entry past its level's first block adds the scanned total of the blocks before its own. Every loop is
    parallel but that last one; the serial work is at most 32 additions whatever the table."""
    n = table_n(w)
    w.tire_counts[MAX_OCC] = 0
    for k in ti.static(range(w.scan_levels)):
        scan_blocks(ti.static(scan_level(w, k)), ti.static(scan_level(w, k + 1)), level_count(n, k),
                    w.tire_counts, ti.static(k == 0), plan)
    last = ti.static(scan_level(w, w.scan_levels))
    ti.loop_config(serialize=True)
    for i in range(1, level_count(n, w.scan_levels)):
        last[i] += last[i - 1]
    for k in ti.static(list(reversed(range(w.scan_levels)))):
        src, sums = ti.static(scan_level(w, k), scan_level(w, k + 1))
        top_loop(plan)
        for i in range(SCAN_BLOCK, level_count(n, k)):
            src[i] += sums[i // SCAN_BLOCK - 1]
    w.cell_start[n] = w.cell_start[n - 1]


@world_kernel
def inclusive_scan(w: ti.template()) -> ti.i32:
    """The scan alone; returns the number of (rock, cell) entries."""
    scan_counts(w, None)
    return w.cell_start[table_n(w)]


@ti.func
def scatter_rock(w: ti.template(), i, center: ti.template()):
    if ti.static(center):
        e = ti.atomic_sub(w.cell_start[w.slot[i]], 1) - 1
        w.entries[e] = i
    else:
        lo, hi = aabb_cells(w.pos[i], w.radius[i], w.par[Par.CELL])
        for a in range(lo[0], hi[0] + 1):
            for b in range(lo[1], hi[1] + 1):
                for c in range(lo[2], hi[2] + 1):
                    e = ti.atomic_sub(w.cell_start[hash_cell(ti.Vector([a, b, c]), table_n(w))], 1) - 1
                    w.entries[e] = i


@ti.func
def scatter_all(w: ti.template(), center: ti.template()):
    """Place each counted rock in its slots. atomic_sub on the inclusive ends leaves cell_start[s] = start
    of slot s."""
    for k in range(scatter_items(w)):
        scatter_item(w, k, center)


@ti.func
def scatter_items(w: ti.template()):
    """The items of the scatter: the listed rocks (scope "tires") or the rock arrays."""
    n = 0
    if ti.static(w.masked):
        n = w.n_listed[None]
    else:
        n = w.ipar[IPar.N_ROCKS]
    return n


@ti.func
def scatter_item(w: ti.template(), k, center: ti.template()):
    """Item k of the scatter (:func:`scatter_items`; a loop of the caller's, which may hold other items)."""
    if ti.static(w.masked):
        scatter_rock(w, w.listed[k], center)
    elif ti.static(w.stored):  # active stepping counts only the rocks not flying (engine/active.py)
        if w.phase[k] != FLYING:
            scatter_rock(w, k, center)
    else:
        scatter_rock(w, k, center)


@world_kernel
def scatter(w: ti.template(), center: ti.template()):
    scatter_all(w, center)


# ---------------------------------------------------------------------------------------------------
# Ray cells: 3D DDA with a fixed step budget and tie-aware supercover.

@ti.func
def _emit(w: ti.template(), ray, c):
    k = w.ray_cell_count[ray]
    if k < w.ray_capacity:
        w.ray_cells[ray, k] = c
        w.ray_cell_count[ray] = k + 1


@ti.func
def segment_cells(w: ti.template(), ray, a, b):
    """Write every cell the segment a-b crosses into w.ray_cells[ray, :], in order from a to b."""
    cell = w.par[Par.CELL]
    eps = w.par[Par.TIE_EPS]
    c = cell_of(a, cell)
    c_end = cell_of(b, cell)
    d = b - a
    step = ti.Vector([0, 0, 0])
    left = ti.Vector([0, 0, 0])  # steps still to take per axis
    t_max = ti.Vector([0.0, 0.0, 0.0], dt=w.real)
    t_delta = ti.Vector([0.0, 0.0, 0.0], dt=w.real)
    big = ti.cast(3.0e38, w.real)
    for ax in ti.static(range(3)):
        left[ax] = ti.abs(c_end[ax] - c[ax])
        if c_end[ax] > c[ax]:
            step[ax] = 1
        elif c_end[ax] < c[ax]:
            step[ax] = -1
        if step[ax] != 0 and d[ax] != 0:
            boundary = ti.cast(c[ax] + (1 if step[ax] > 0 else 0), w.real) * cell
            t_max[ax] = (boundary - a[ax]) / d[ax]
            t_delta[ax] = cell / ti.abs(d[ax])
        else:
            t_max[ax] = big
            t_delta[ax] = big
    w.ray_cell_count[ray] = 0
    _emit(w, ray, c)
    budget = left[0] + left[1] + left[2]
    while budget > 0:
        t_min = big
        for ax in ti.static(range(3)):
            if left[ax] > 0 and t_max[ax] < t_min:
                t_min = t_max[ax]
        move = ti.Vector([0, 0, 0])
        for ax in ti.static(range(3)):
            if left[ax] > 0 and t_max[ax] <= t_min + eps:
                move[ax] = step[ax]
        n_move = ti.abs(move[0]) + ti.abs(move[1]) + ti.abs(move[2])
        if n_move > 1:  # the segment passes (nearly) through an edge or a corner: visit the side cells
            for ax in ti.static(range(3)):
                if move[ax] != 0:
                    side = c
                    side[ax] += move[ax]
                    _emit(w, ray, side)
            if n_move == 3:
                for ax in ti.static(range(3)):
                    side = c + move
                    side[ax] -= move[ax]
                    _emit(w, ray, side)
        c += move
        _emit(w, ray, c)
        for ax in ti.static(range(3)):
            if move[ax] != 0:
                t_max[ax] += t_delta[ax]
                left[ax] -= 1
        budget -= n_move


def ray_capacity(length: float, cell: float) -> int:
    """Upper bound of the cells segment_cells emits for a segment of this length."""
    per_axis = int(length / cell) + 2
    return 1 + 3 * per_axis * 3 + 8
