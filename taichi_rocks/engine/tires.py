"""Pass 2, the tires: rays from rear-tire centres to the ground find rocks, which are launched.

Detection. A tire's ray runs from its centre a to its bottom b. A rock (centre c, radius r) is hit when the
segment comes within r of c: t* = clamp((c - a).(b - a) / |b - a|^2, 0, 1), hit iff |c - (a + t*(b - a))|^2
<= r^2 (the closest-point form; unlike the quadratic of a ray-sphere intersection it has no cancellation and
handles a zero-length segment). "swept" detection tests the parallelogram the ray sweeps between the
previous and the current step instead, so a fast tire misses nothing it passed over; "substeps" evaluates
the ray at several positions interpolated within the step.

Launch. A rock run over is thrown with the velocity of the scene's launch model (engine/launch/, a module per
model), picked at compile time from the Plan's ``throw``. A rock is launched at most once per step, by the
first tire in scene order that would launch it (a tire that finds it but throws it slower than the rest speed
leaves it to the next); flying rocks are not re-launched. With the Plan's ``spin`` a launched rock also gets the
spin of a stone rolling off the tread at the model's release angle (engine/tumble.py).

In parallel (:func:`launch_all`), whatever the backend or thread count: a query is a tire (swept) or a ray of a
substep, and its box of hash cells holds every cell it can find a rock in (the ray's DDA cells, dilated with
centre insertion); the items (query, cell of the largest box) test their slot's rocks and claim a rock they
would launch with an atomic maximum of n_tires - t on its ``claim``: the smallest t holds it. A launch model's
velocity is a function of (tire, rock, step) and the rock's state, which no claim changes, so the winner is the
serial pass's; the winner then launches the rock with the same call (the same random numbers) and clears the
claim. No serial loop: one thread per query, per (query, cell), per rock.

"patch" detection (engine/patch.py) adds the tread's swept footprint to the swept test: a rock on the ground
anywhere under the tread is run over. The query box is then the union of the swept ray's box and the
footprint's XY box. Launch model and detection are compile-time switches of the Plan (``plan``: the kernel's
Switches, engine/kernels.py).
"""

import taichi as ti
from taichi.lang import impl

from . import hashgrid, patch, tirerow, tumble
from .geometry import closest_on_segment
from .hashgrid import cell_of, hash_cell, segment_cells, table_n
from .launch import MODELS
from .loops import top_loop
from .view import world_kernel
from .world import A0, A1, B0, B1, FLYING, LAUNCHED, MAX_OCC, SLIDING, SPAN_A, \
    SPAN_B, SPAN_C, IPar, Par


@ti.func
def segment_hits_sphere(a, b, c, r):
    q = closest_on_segment(a, b, c)
    return (c - q).norm_sqr() <= r * r


@ti.func
def parallelogram_dist2(o, e1, e2, c):
    """Squared distance from c to the parallelogram {o + u e1 + v e2 : u, v in [0, 1]}."""
    best = (c - closest_on_segment(o, o + e1, c)).norm_sqr()
    best = ti.min(best, (c - closest_on_segment(o + e2, o + e1 + e2, c)).norm_sqr())
    best = ti.min(best, (c - closest_on_segment(o, o + e2, c)).norm_sqr())
    best = ti.min(best, (c - closest_on_segment(o + e1, o + e1 + e2, c)).norm_sqr())
    # interior: solve the 2x2 normal equations for the projection of c onto the plane
    g11 = e1.dot(e1)
    g12 = e1.dot(e2)
    g22 = e2.dot(e2)
    det = g11 * g22 - g12 * g12
    if det > 1e-12 * g11 * g22:
        rc = c - o
        r1 = rc.dot(e1)
        r2 = rc.dot(e2)
        u = (g22 * r1 - g12 * r2) / det
        v = (g11 * r2 - g12 * r1) / det
        if 0.0 <= u <= 1.0 and 0.0 <= v <= 1.0:
            best = ti.min(best, (rc - u * e1 - v * e2).norm_sqr())
    return best


@world_kernel
def trace_rays(w: ti.template()):
    trace_all(w)


@ti.func
def substep_ray(w: ti.template(), t, s):
    """Tire t's ray (a, b) at substep s: interpolated between the previous and the current step."""
    f = ti.cast(s + 1, w.real) / w.substeps
    a = tirerow.point(w, t, A0) * (1.0 - f) + tirerow.point(w, t, A1) * f
    b = tirerow.point(w, t, B0) * (1.0 - f) + tirerow.point(w, t, B1) * f
    return a, b


@ti.func
def trace_all(w: ti.template()):
    """DDA cells of every ray of every substep (ray index = tire * substeps + s), one thread per ray (the tire
    pass queries each ray's box of cells, which holds these)."""
    for r in range(w.n_rays):
        a, b = substep_ray(w, r // w.substeps, r % w.substeps)
        segment_cells(w, r, a, b)


@ti.func
def slot_range(w: ti.template(), c):
    s = hash_cell(c, table_n(w))
    return w.cell_start[s], w.cell_start[s + 1]


@ti.func
def can_launch(w: ti.template(), plan: ti.template(), i, t, step):
    """Would tire t launch rock i? Not if it was launched this step or flies; else if the launch model's
    velocity beats the rest speed (the model's velocity depends on the tire, the rock and the step only)."""
    yes = False
    if w.hit_step[i] != step and w.phase[i] != FLYING:
        v, _, _ = MODELS[plan.throw].launch(w, plan, t, i, step)  # the model: a compile-time choice
        yes = v.norm() > w.par[Par.REST_SPEED]
    return yes


@ti.func
def launch_rock(w: ti.template(), plan: ti.template(), i, t, step):
    """Launch rock i by tire t (can_launch said yes): the same velocity, the same random numbers."""
    v, v_tread, alpha = MODELS[plan.throw].launch(w, plan, t, i, step)
    w.hit_step[i] = step
    w.vel[i] = v
    if ti.static(plan.impacts):  # who threw it: its own body is not hit (engine/impact_pass.py)
        w.thrower[i] = w.tire_vehicle[t]
    if ti.static(plan.spin):  # it rolls off the tread (engine/tumble.py)
        w.spin[i] = tumble.launch_spin(w, t, alpha, v_tread, w.radius[i], w.rock_id[i], step)
    if ti.static(plan.ground == "none"):
        w.phase[i] = FLYING
    else:
        w.phase[i] = FLYING if v[2] > 0.0 else SLIDING


@ti.func
def swept_query(w: ti.template(), plan: ti.template(), t):
    """Tire t's swept test (a0, e1, e2: the parallelogram; with ``plan.patch`` whether the tread's footprint
    counts and the highest a run-over rock's bottom may be) and its XY-and-Z query box (lo, hi)."""
    a0, b0 = tirerow.point(w, t, A0), tirerow.point(w, t, B0)
    a1 = tirerow.point(w, t, A1)
    e1 = a1 - a0  # the step's motion
    e2 = b0 - a0  # the ray
    lo = ti.min(ti.min(a0, b0), ti.min(a1, a1 + e2))
    hi = ti.max(ti.max(a0, b0), ti.max(a1, a1 + e2))
    tread = False  # patch: the footprint counts (an active tire with a footprint of some size)
    floor = b0[2]  # patch: the highest a run-over rock's bottom may be
    if ti.static(plan.patch):
        tread = tirerow.near_bed(w, t) and tirerow.has_tread(w, t)
        floor = ti.min(b0[2], tirerow.point(w, t, B1)[2]) + w.par[Par.PATCH_TOL]
        if tread:
            f_lo, f_hi = patch.footprint_box(w, t)
            lo = ti.Vector([ti.min(lo[0], f_lo[0]), ti.min(lo[1], f_lo[1]), lo[2]])
            hi = ti.Vector([ti.max(hi[0], f_hi[0]), ti.max(hi[1], f_hi[1]), hi[2]])
    return a0, e1, e2, tread, floor, lo, hi


@ti.func
def swept_hits(w: ti.template(), plan: ti.template(), t, i):
    """Does tire t's swept test (and with ``plan.patch`` its tread) run over rock i?"""
    a0, e1, e2, tread, floor, _, _ = swept_query(w, plan, t)
    r2 = w.radius[i] * w.radius[i]
    hit = parallelogram_dist2(a0, e1, e2, w.pos[i]) <= r2
    if ti.static(plan.patch):
        if tread and not hit and w.pos[i][2] - w.radius[i] <= floor:
            hit = patch.footprint_dist2(w, t, ti.Vector([w.pos[i][0], w.pos[i][1]])) <= r2
    return hit


def places_one_per_item() -> bool:
    """Compile-time: does each item of the claims and launches take one place of its cell's slot (Vulkan), or
    walk the slot's entries (CPU, CUDA)? On Vulkan (Taichi 1.7.4, lavapipe) an atomic inside an inner loop
    with a run-time trip count loses updates, even with a trip count the same for every thread; so there the
    places are items of the flat loop (up to the fullest slot's count, ``MAX_OCC``), elsewhere a short loop."""
    return impl.current_cfg().arch == ti.vulkan


@ti.func
def query_box(w: ti.template(), plan: ti.template(), q):
    """Query q's cells (first, last): swept, tire q's box (the parallelogram's and the footprint's XY box);
    else ray q's (tire q // substeps at substep q % substeps) box, which holds every cell the ray crosses;
    dilated by ``DILATE`` with centre insertion."""
    lo = ti.Vector([0.0, 0.0, 0.0], dt=w.real)
    hi = lo
    if ti.static(plan.swept):
        _, _, _, _, _, lo, hi = swept_query(w, plan, q)
    else:
        a, b = substep_ray(w, q // w.substeps, q % w.substeps)
        lo, hi = ti.min(a, b), ti.max(a, b)
    dil = w.ipar[IPar.DILATE] if ti.static(plan.center) else 0
    cell = w.par[Par.CELL]
    return cell_of(lo, cell) - dil, cell_of(hi, cell) + dil


@ti.func
def reset_counts(w: ti.template()):
    for k in ti.static((SPAN_A, SPAN_B, SPAN_C, LAUNCHED)):
        w.tire_counts[k] = 0


@ti.func
def n_queries(w: ti.template(), plan: ti.template()):
    return w.n_tires if ti.static(plan.swept) else w.n_rays


@ti.func
def box_query(w: ti.template(), plan: ti.template(), q):
    """Query q's cells into ``w.tire_cells``, the largest box's size in cells per axis into
    ``tire_counts[SPAN_A..SPAN_C]`` (atomic maxima)."""
    c_lo, c_hi = query_box(w, plan, q)
    w.tire_cells[q, 0] = c_lo
    w.tire_cells[q, 1] = c_hi
    for k in ti.static(range(3)):
        ti.atomic_max(w.tire_counts[SPAN_A + k], c_hi[k] - c_lo[k] + 1)


@ti.func
def in_cell(w: ti.template(), plan: ti.template(), i, c):
    """Is rock i in cell c? A cell's slot holds the rocks of every cell that hashes to it; with centre insertion
    a rock is in its centre's cell alone, and a query's box holds every cell a rock it can hit is in
    (:func:`query_box`), so a rock of another cell is either tested when its own cell is or out of reach: leaving
    it out here changes no claim, and spares a swept test per hash collision. (AABB insertion: every rock.)"""
    yes = True
    if ti.static(plan.center):
        d = cell_of(w.pos[i], w.par[Par.CELL]) - c
        yes = d[0] == 0 and d[1] == 0 and d[2] == 0
    return yes


@ti.func
def item_cell(w: ti.template(), plan: ti.template(), q):
    """Item q of the tire pass: (query, place in its cell's slot (0 unless one place per item), the slot's
    entries (start, end), or an empty range, and the cell)."""
    per = 1
    if ti.static(places_one_per_item()):
        per = w.tire_counts[MAX_OCC]
    j = q % per
    r = q // per
    sx, sy, sz = w.tire_counts[SPAN_A], w.tire_counts[SPAN_B], w.tire_counts[SPAN_C]
    query = r // (sx * sy * sz)
    u = r % (sx * sy * sz)
    c = w.tire_cells[query, 0] + ti.Vector([u // (sy * sz), (u // sz) % sy, u % sz])
    hi = w.tire_cells[query, 1]
    start, end = 0, 0
    if c[0] <= hi[0] and c[1] <= hi[1] and c[2] <= hi[2]:
        start, end = slot_range(w, c)
    return query, j, start, end, c


@ti.func
def query_hits(w: ti.template(), plan: ti.template(), query, i):
    """Does the query (swept: tire ``query``'s swept test; else ray ``query``) hit rock i?"""
    hit = False
    if ti.static(plan.swept):
        hit = swept_hits(w, plan, query, i)
    else:
        a, b = substep_ray(w, query // w.substeps, query % w.substeps)
        hit = segment_hits_sphere(a, b, w.pos[i], w.radius[i])
    return hit


@ti.func
def claim_rock(w: ti.template(), plan: ti.template(), query, i, step):
    """The query's tire claims rock i if it would launch it; the first claim of a rock counts it."""
    t = query if ti.static(plan.swept) else query // w.substeps
    if query_hits(w, plan, query, i):
        if can_launch(w, plan, i, t, step):
            if ti.atomic_max(w.claim[i], w.n_tires - t) == 0:
                ti.atomic_add(w.tire_counts[LAUNCHED], 1)


@ti.func
def launch_claimed(w: ti.template(), plan: ti.template(), query, i, step):
    """Item side of the launches: the query's tire launches rock i if it holds the claim (once)."""
    t = query if ti.static(plan.swept) else query // w.substeps
    if w.claim[i] == w.n_tires - t:
        if ti.atomic_min(w.claim[i], 0) == w.n_tires - t:  # one of the winner's items launches it
            launch_rock(w, plan, i, t, step)


@ti.func
def each_item_rock(w: ti.template(), plan: ti.template(), q, step, visit: ti.template()):
    """``visit(w, plan, query, rock, step)`` for the rocks item q of the claims or the launches covers: one place
    of its cell's slot, or the slot's every entry (:func:`places_one_per_item`)."""
    query, j, start, end, c = item_cell(w, plan, q)
    if ti.static(places_one_per_item()):
        if start + j < end:
            i = w.entries[start + j]
            if in_cell(w, plan, i, c):
                visit(w, plan, query, i, step)
    else:
        for e in range(start, end):
            i = w.entries[e]
            if in_cell(w, plan, i, c):
                visit(w, plan, query, i, step)


@ti.func
def each_query_rock(w: ti.template(), plan: ti.template(), step, visit: ti.template()):
    """The serial variant's walk (engine/loops.py) of what :func:`each_item_rock` visits: for each query, the
    rocks of every cell of its own box, cell after cell (nested loops, no flat index to decode; the parallel
    variant's items cover the largest box, whose cells outside a query's box are empty items). The same
    (query, rock) pairs, in another order: a claim is an atomic maximum and a launch depends only on the tire,
    the rock and the step, so the order changes nothing."""
    ti.loop_config(serialize=True)
    for query in range(n_queries(w, plan)):
        lo, hi = w.tire_cells[query, 0], w.tire_cells[query, 1]
        for a in range(lo[0], hi[0] + 1):
            for b in range(lo[1], hi[1] + 1):
                for c in range(lo[2], hi[2] + 1):
                    cell = ti.Vector([a, b, c])
                    start, end = slot_range(w, cell)
                    for e in range(start, end):
                        i = w.entries[e]
                        if in_cell(w, plan, i, cell):
                            visit(w, plan, query, i, step)


@ti.func
def launch_if_claimed(w: ti.template(), plan: ti.template(), i, step):
    """Rock side of the launches, in a loop over the rocks (active stepping's settle loop): rock i is launched
    by the tire holding its claim, if any, and its claim cleared."""
    code = w.claim[i]
    if code != 0:
        w.claim[i] = 0
        launch_rock(w, plan, i, w.n_tires - code, step)


@world_kernel
def tire_pass(w: ti.template(), plan: ti.template(), step: ti.i32):
    """The tire pass alone (``plan``: the switches of kernels.hash_and_tires), after the hash's scan (its
    ``MAX_OCC``) and scatter."""
    reset_counts(w)
    top_loop(plan)
    for q in range(n_queries(w, plan)):
        box_query(w, plan, q)
    launch_all(w, plan, step, True)


@ti.func
def scatter_and_launch(w: ti.template(), plan: ti.template(), step, launch: ti.template()):
    """The hash's scatter and the tire pass (:func:`launch_all`), its first loop (the queries' boxes) in the
    scatter's loop: one parallel task less."""
    reset_counts(w)
    n = hashgrid.scatter_items(w)
    top_loop(plan)
    for q in range(n + n_queries(w, plan)):
        if q < n:
            hashgrid.scatter_item(w, q, plan.center)
        else:
            box_query(w, plan, q - n)
    launch_all(w, plan, step, launch)


@ti.func
def launch_all(w: ti.template(), plan: ti.template(), step, launch: ti.template()):
    """Find and launch the rocks under every tire ray, the first tire in scene order winning a rock, whatever
    the thread count or the backend, in parallel loops, after the queries' boxes of cells (:func:`box_query`,
    one thread per tire with swept detection, else per ray of a substep; a box holds every cell the query can
    find a rock in, :func:`query_box`; a loop of the caller's, :func:`tire_pass`, :func:`scatter_and_launch`): the
    claims, over (query, cell of the largest box): each (tire, rock of the cell's slot) that would launch the
    rock (a hit, not launched, not flying, fast enough) writes n_tires - t into the rock's ``claim`` with an
    atomic maximum, so that the smallest t holds it; the launches, over the same items: the winning tire
    launches the rock with the same arguments as a serial pass in scene order would, once (an atomic exchange
    of the claim with 0, which leaves the claims clear for the next pass). Without ``launch`` the caller
    launches the claimed rocks in a loop of its own over the rocks (:func:`launch_if_claimed`; active stepping:
    its settle loop, no task of its own). The rocks claimed, which are the rocks launched, go to
    ``tire_counts[LAUNCHED]`` and ``w.launches`` after the claims: nothing is read back. Reads the switches ``center``,
    ``swept``, ``patch``, ``ground``, ``throw`` and ``fenders`` of ``plan``; the hash's scan left the fullest
    slot's count in ``tire_counts[MAX_OCC]``."""
    n_items = n_queries(w, plan) * w.tire_counts[SPAN_A] * w.tire_counts[SPAN_B] * w.tire_counts[SPAN_C]
    if ti.static(places_one_per_item()):
        n_items *= w.tire_counts[MAX_OCC]
    if ti.static(getattr(plan, "serial", False)):  # the serial variant walks each query's own box of cells
        each_query_rock(w, plan, step, claim_rock)
    else:
        for q in range(n_items):
            each_item_rock(w, plan, q, step, claim_rock)
    w.launches[None] += w.tire_counts[LAUNCHED]
    if ti.static(launch):
        if ti.static(getattr(plan, "serial", False)):
            each_query_rock(w, plan, step, launch_claimed)
        else:
            for q in range(n_items):
                each_item_rock(w, plan, q, step, launch_claimed)
