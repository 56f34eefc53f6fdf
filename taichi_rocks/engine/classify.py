"""Step 1 of active stepping (engine/active.py's docstring): which occupied tiles give rocks to the active list
this step. Rim tiles: those the bed's trailing crescent crosses, walked as a band of tile lines along the circle
|q - c| = R widened by the move (``rim_plan``, ``band_width``, ``band_slot``), or every slot after a jump or a
load; gone tiles, wholly outside the new disk; tire tiles, under a tire's query box this step (``take_tire``,
``classify_tire_tile``). A tile takes the highest class that applies (NONE < RIM < TIRE < MOVE_ALL) and its
first mark lists it for the gather (``mark``); ``under_a_tire`` is the gather's test of a rock in a tire tile."""

import taichi as ti

from . import tirerow
from .loops import top_loop
from .patch import footprint_box
from .tiles import rounding_margin, same_key, slot_of, tile_key
from .world import A0, A1, B0, RAY_FIELDS, Par

__all__ = ["NONE", "RIM", "TIRE", "MOVE_ALL", "SURVIVORS", "HOLES", "MOVERS", "MARKED", "classify", "mark",
           "under_a_tire"]

NONE, RIM, TIRE, MOVE_ALL = 0, 1, 2, 3  # tile classes of a step (a tile takes the highest that applies)

# World.a_counts: the active rocks still listed after settling, the holes below their count and the listed
# rocks above it (compaction), the slots marked this step (mark()), the band's widest row and column and the
# largest tire box in tiles (rim_plan, tire_boxes)
SURVIVORS, HOLES, MOVERS, MARKED, WIDTH_ROWS, WIDTH_COLS, SPAN_X, SPAN_Y = range(8)


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
