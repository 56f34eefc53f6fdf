"""Pass 2, the tires: rays from rear-tire centres to the ground find rocks, which are launched.

Detection. A tire's ray runs from its centre a to its bottom b. A rock (centre c, radius r) is hit when the
segment comes within r of c: t* = clamp((c - a).(b - a) / |b - a|^2, 0, 1), hit iff |c - (a + t*(b - a))|^2
<= r^2 (the closest-point form; unlike the quadratic of a ray-sphere intersection it has no cancellation and
handles a zero-length segment). "swept" detection tests the parallelogram the ray sweeps between the
previous and the current step instead, so a fast tire misses nothing it passed over; "substeps" evaluates
the ray at several positions interpolated within the step.

Launch. A rock run over is thrown with the velocity of the scene's launch model (engine/launch/, a module per
model), picked at compile time from the Plan's ``throw``. A rock is launched at most once per step, by the
first ray (in tire order) that finds it; flying rocks are not re-launched. With the Plan's ``spin`` a launched
rock also gets the spin of a stone rolling off the tread at the model's release angle (engine/tumble.py).

"patch" detection (engine/patch.py) adds the tread's swept footprint to the swept test: a rock on the ground
anywhere under the tread is run over. The query box is then the union of the swept ray's box and the
footprint's XY box. Launch model and detection are compile-time switches of the Plan (``plan``: the kernel's
Switches, engine/kernels.py).
"""

import taichi as ti

from . import patch, tumble
from .geometry import closest_on_segment
from .hashgrid import cell_of, hash_cell, segment_cells, table_n
from .launch import MODELS
from .world import A0, A1, ACTIVE, B0, B1, FLYING, HALF_L, HALF_W, SLIDING, IPar, Par


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


@ti.func
def ray_vec(w: ti.template(), t, k):
    return ti.Vector([w.ray[t, k], w.ray[t, k + 1], w.ray[t, k + 2]])


@ti.kernel
def trace_rays(w: ti.template()):
    trace_all(w)


@ti.func
def trace_all(w: ti.template()):
    """DDA cells of every ray of every substep (ray index = tire * substeps + s): serial, a handful of rays
    (a parallel task's start-up would cost more than they do)."""
    ti.loop_config(serialize=True)
    for t, s in ti.ndrange(w.n_tires, w.substeps):
        f = ti.cast(s + 1, w.real) / w.substeps
        a = ray_vec(w, t, A0) * (1.0 - f) + ray_vec(w, t, A1) * f
        b = ray_vec(w, t, B0) * (1.0 - f) + ray_vec(w, t, B1) * f
        segment_cells(w, t * w.substeps + s, a, b)


@ti.func
def try_launch(w: ti.template(), plan: ti.template(), i, t, step):
    """Launch rock i by tire t unless already launched this step or flying; returns 1 if launched."""
    launched = 0
    if w.hit_step[i] != step and w.phase[i] != FLYING:
        v, v_tread, alpha = MODELS[plan.throw].launch(w, plan, t, i, step)  # the model: a compile-time choice
        if v.norm() > w.par[Par.REST_SPEED]:
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
            launched = 1
    return launched


@ti.func
def slot_range(w: ti.template(), c):
    s = hash_cell(c, table_n(w))
    return w.cell_start[s], w.cell_start[s + 1]


@ti.kernel
def tire_pass(w: ti.template(), plan: ti.template(), step: ti.i32) -> ti.i32:
    """The tire pass alone (``plan``: the switches of kernels.hash_and_tires)."""
    return launch_all(w, plan, step)


@ti.func
def launch_all(w: ti.template(), plan: ti.template(), step):
    """Find and launch the rocks under every tire ray. Serial over tires: the first tire wins a rock,
    whatever the thread count (a handful of rays; the cost is in the cells, not the loop). Reads the switches
    ``center``, ``swept``, ``patch``, ``ground``, ``throw`` and ``fenders`` of ``plan``."""
    launched = 0
    ti.loop_config(serialize=True)
    for t in range(w.n_tires):
        dil = w.ipar[IPar.DILATE] if ti.static(plan.center) else 0
        if ti.static(plan.swept):
            a0, b0 = ray_vec(w, t, A0), ray_vec(w, t, B0)
            a1 = ray_vec(w, t, A1)
            e1 = a1 - a0  # the step's motion
            e2 = b0 - a0  # the ray
            lo = ti.min(ti.min(a0, b0), ti.min(a1, a1 + e2))
            hi = ti.max(ti.max(a0, b0), ti.max(a1, a1 + e2))
            tread = False  # patch: the footprint counts (an active tire with a footprint of some size)
            floor = b0[2]  # patch: the highest a run-over rock's bottom may be
            if ti.static(plan.patch):
                tread = w.ray[t, ACTIVE] != 0.0 and (w.ray[t, HALF_W] > 0.0 or w.ray[t, HALF_L] > 0.0)
                floor = ti.min(b0[2], w.ray[t, B1 + 2]) + w.par[Par.PATCH_TOL]
                if tread:
                    f_lo, f_hi = patch.footprint_box(w, t)
                    lo = ti.Vector([ti.min(lo[0], f_lo[0]), ti.min(lo[1], f_lo[1]), lo[2]])
                    hi = ti.Vector([ti.max(hi[0], f_hi[0]), ti.max(hi[1], f_hi[1]), hi[2]])
            cell = w.par[Par.CELL]
            c_lo = cell_of(lo, cell) - dil
            c_hi = cell_of(hi, cell) + dil
            for cx, cy, cz in ti.ndrange((c_lo[0], c_hi[0] + 1), (c_lo[1], c_hi[1] + 1), (c_lo[2], c_hi[2] + 1)):
                start, end = slot_range(w, ti.Vector([cx, cy, cz]))
                for e in range(start, end):
                    i = w.entries[e]
                    r2 = w.radius[i] * w.radius[i]
                    hit = parallelogram_dist2(a0, e1, e2, w.pos[i]) <= r2
                    if ti.static(plan.patch):
                        if tread and not hit and w.pos[i][2] - w.radius[i] <= floor:
                            hit = patch.footprint_dist2(w, t, ti.Vector([w.pos[i][0], w.pos[i][1]])) <= r2
                    if hit:
                        launched += try_launch(w, plan, i, t, step)
        else:
            for s in range(w.substeps):
                f = ti.cast(s + 1, w.real) / w.substeps
                a = ray_vec(w, t, A0) * (1.0 - f) + ray_vec(w, t, A1) * f
                b = ray_vec(w, t, B0) * (1.0 - f) + ray_vec(w, t, B1) * f
                ray = t * w.substeps + s
                for k in range(w.ray_cell_count[ray]):
                    c = w.ray_cells[ray, k]
                    for dx, dy, dz in ti.ndrange((-dil, dil + 1), (-dil, dil + 1), (-dil, dil + 1)):
                        start, end = slot_range(w, c + ti.Vector([dx, dy, dz]))
                        for e in range(start, end):
                            i = w.entries[e]
                            if segment_hits_sphere(a, b, w.pos[i], w.radius[i]):
                                launched += try_launch(w, plan, i, t, step)
    w.launches[None] += launched
    return launched
