"""The kernels a step launches, built from the pass modules (flight, bed, hashgrid, tires).

Every kernel takes the World ``w`` and, where it has compile-time switches, the Plan's switches it reads
(``plan``: a :class:`Switches`, one ``ti.template()`` argument) as ``ti.static(plan.flight)``: passes a plan
leaves out are not compiled. The Plan is the one switch mechanism: the World holds fields and their layout
only, so scenes that differ in a switch (an integrator, the launch model, the fenders, ...) have one World
layout and compile only the kernels that read it.
Points and displacements in the bed's local frame (world = origin + local) come as 2-vectors of float64, cast
to the World's precision: ``ti.types.vector(2, ti.f64)`` arguments, except in
``rock_pass``, launched every step, which takes its four as one array of 2-vectors (``frame``, rows CENTRE,
MOVE, LEAD, GRID): Taichi 1.7.4 builds a Matrix in Python for every vector argument of a launch (~10 us
each, ~4x two scalars), an array of them costs about what the scalars did. The kernels that move every rock
field (``reorder_rocks``) loop over the declaration (engine/rockfields.py, ``w.rocks``) at compile time.
"""


import taichi as ti

from . import hashgrid, stepdata, tires, tumble
from .bed import outside_bed, recycle_to_leading_edge
from .flight import fly
from .impact_pass import hit_bodies
from .loops import top_loop
from .world import FLYING, RAY_FIELDS, RESTING, IPar, Par, tmp_name
from .view import world_kernel

vec2 = ti.types.vector(2, ti.f64)


class Switches:
    """The switches of a Plan that one kernel reads, as that kernel's ``plan`` argument.

    Taichi 1.7.4 keys a ``ti.template()`` argument that is neither a field nor a container by its value
    (``hash`` and ``==``), so a kernel compiles once per World and distinct switches, and equal ones share the
    compiled kernel. Holding only the switches its kernel reads (``READS``), a Switches keeps scenes that
    differ elsewhere on one compiled kernel (a new integrator does not recompile the hash pass); reading a
    switch that is not held fails when the kernel compiles."""

    __slots__ = ("_items", "_hash")

    def __init__(self, plan, names, serial: bool = False):
        self._items = tuple((n, bool(serial) if n == "serial" else getattr(plan, n)) for n in names)
        self._hash = hash(self._items)

    def __getattr__(self, name):
        if not name.startswith("_"):
            for n, v in self._items:
                if n == name:
                    return v
        raise AttributeError(f"kernel switch {name!r} is not among {[n for n, _ in self._items]}")

    def __eq__(self, other):
        return isinstance(other, Switches) and self._items == other._items

    def __hash__(self):
        return self._hash

    def __repr__(self):
        return "Switches(" + ", ".join(f"{n}={v!r}" for n, v in self._items) + ")"


# The Plan's switches each kernel reads; "serial" is not the Plan's: the step's variant (engine/loops.py), which
# the stepper chooses (engine/variant.py).
READS = {
    "rock_pass": ("splash", "flight", "recycle", "center", "integrator", "gravity", "drag", "ground", "spin",
                  "impacts", "serial"),
    "coast_pass": ("flight", "recycle", "integrator", "gravity", "drag", "ground", "spin", "impacts"),
    "hash_and_tires": ("center", "swept", "patch", "ground", "throw", "fenders", "spin", "impacts",
                       "serial"),  # also tire_pass
    "health": ("recycle", "ground"),
    "active_step": ("splash", "flight", "recycle", "center", "swept", "patch", "integrator", "gravity", "drag",
                    "ground", "spin", "impacts", "serial"),
    "active_finish": ("splash", "center", "swept", "patch", "ground", "throw", "fenders", "spin", "impacts",
                      "serial"),
    "note_listed": ("serial",),
    "load_batch": ("serial",),
}


def switches(plan, serial: bool = False) -> dict:
    """Kernel name -> the :class:`Switches` of ``plan`` it reads, in the step's parallel or ``serial`` variant
    (engine/loops.py)."""
    return {k: Switches(plan, names, serial) for k, names in READS.items()}


# Rows of rock_pass's ``frame`` (2-vectors, float64, local frame): the bed centre, how far it moved this
# step, its leading direction (unit), and the corner of the tire mask's tiles; with impacts, from BODIES on the
# impacts pass's rows (engine/impact_pass.py: the step's start time, the poses of the vehicles hit).
CENTRE, MOVE, LEAD, GRID = 0, 1, 2, 3
BODIES = 4


@ti.func
def take_rays(w: ti.template(), plan: ti.template(), rays: ti.template()):
    """The step's tire rays (``rays``, layout of World.ray, float64) into ``w.ray``: passed as an argument of
    the step's first kernel, they cost no launch of their own."""
    if ti.static(plan.splash):
        for t, k in ti.ndrange(w.n_tires, RAY_FIELDS):
            w.ray[t, k] = ti.cast(rays[t, k], w.real)


@ti.func
def recycle(w: ti.template(), plan: ti.template(), i, c, m, d, step):
    """Recycling to the leading edge (engine/bed.py); a tumbling rock recycled in motion arrives at rest, so it
    stops spinning (its orientation stays)."""
    if ti.static(plan.spin):
        moving = w.phase[i] != RESTING
        recycle_to_leading_edge(w, i, c, m, d, step)
        if moving and w.phase[i] == RESTING:
            tumble.rest(w, i)
    else:
        recycle_to_leading_edge(w, i, c, m, d, step)


@ti.func
def rock_tail(w: ti.template(), plan: ti.template(), i, ph0, fr, step, hash_flying: ti.template()):
    """Pass 1 for rock i after its flight and impacts (``ph0``: its phase at the step's start; ``fr``: the
    step's frame, stepdata.frame_type): recycling to the leading edge, counting for the hash."""
    if ti.static(plan.recycle):
        recycle(w, plan, i, fr.centre, fr.move, fr.lead, step)
    if ti.static(plan.impacts):
        if ph0 != RESTING and w.phase[i] == RESTING:  # landed or recycled: a resting rock has no thrower
            w.thrower[i] = -1
    if ti.static(plan.splash):
        if ti.static(hash_flying):
            hashgrid.count_rock(w, i, plan.center, fr.grid)
        else:
            if w.phase[i] != FLYING:
                hashgrid.count_rock(w, i, plan.center, fr.grid)


@ti.func
def rock_step(w: ti.template(), plan: ti.template(), i, fr, step, hash_flying: ti.template()):
    """Pass 1 for rock i in the step's frame ``fr`` (stepdata.frame_type: time step, the bed's centre, move and
    leading direction, the tire mask's corner): flight, recycling to the leading edge, counting for the hash;
    ``hash_flying``: count flying rocks too (they are never launched, tires.try_launch; active stepping leaves them out). With
    ``plan.impacts`` a rock that flew is listed instead (its index and its state before the flight step,
    ``w.fly_*``) and its recycling and counting wait for the impacts loop (:func:`impacts_loop`), so that they
    see where a body sent it."""
    ph0 = RESTING
    x0 = ti.Vector([0.0, 0.0, 0.0], dt=w.real)
    v0 = ti.Vector([0.0, 0.0, 0.0], dt=w.real)
    if ti.static(plan.impacts):
        ph0 = w.phase[i]
        if ph0 == FLYING:  # only a stone flying at the step's start can meet a body (impact_pass docstring)
            x0 = w.pos[i]
            v0 = w.vel[i]
    if ti.static(plan.flight):
        fly(w, i, fr.h, plan.integrator, plan.gravity, plan.drag, plan.ground, plan.spin)
    listed = 0
    if ti.static(plan.impacts):
        # flying at the start (the same rocks at the end: nothing launches in this pass). Testing the phase after
        # flight too keeps Taichi 1.7.4 from merging this if with flight's own on the same phase, which breaks
        # its IR ("block->parent != current_container_stmt")
        if ph0 == FLYING or w.phase[i] == FLYING:
            k = ti.atomic_add(w.fly_count[None], 1)  # room for every rock: the list cannot overflow
            w.fly_index[k] = i
            w.fly_x0[k] = x0
            w.fly_v0[k] = v0
            listed = 1
    if listed == 0:
        rock_tail(w, plan, i, ph0, fr, step, hash_flying)


@ti.func
def impacts_loop(w: ti.template(), plan: ti.template(), fr, step, hash_flying: ti.template(), rows: ti.template(),
                 base: ti.template()):
    """The listed rocks of the rock loop (:func:`rock_step`), a top-level loop of its own after it (a task of the
    same kernel, no launch): stones against the bodies they hit (engine/impact_pass.py, the poses in ``rows``
    from row ``base`` on), then their recycling and counting. Kept out of the rock loop's body, the swept test
    compiles once, the rock loop stays as lean as without impacts, and only the few rocks in flight pay for
    it. Each listed rock flew at the step's start or is flying (``rock_tail``'s ``ph0`` is not RESTING)."""
    top_loop(plan)
    for k in range(w.fly_count[None]):
        i = w.fly_index[k]
        hit_bodies(w, plan, i, w.fly_x0[k], w.fly_v0[k], fr.h, rows, base, step)
        rock_tail(w, plan, i, FLYING, fr, step, hash_flying)


@world_kernel
def rock_pass(w: ti.template(), plan: ti.template(), rays: ti.types.ndarray(dtype=ti.f64, ndim=2),
              frame: ti.types.ndarray(dtype=vec2, ndim=1), dt: ti.f64, step: ti.i32):
    """Pass 1 fused: flight, recycling, counting for the hash (``plan.splash``), one read of each rock per step;
    with ``plan.impacts`` the impacts loop over the rocks that flew after it (:func:`impacts_loop`); ``frame``:
    the bed's centre, move and leading direction and the mask's corner (rows above), then the impacts' rows.
    With the hash it first takes the step's tire rays (take_rays)."""
    take_rays(w, plan, rays)
    h = ti.cast(dt, w.real)
    c = ti.cast(frame[CENTRE], w.real)
    m = ti.cast(frame[MOVE], w.real)
    d = ti.cast(frame[LEAD], w.real)
    g = ti.cast(frame[GRID], w.real)
    if ti.static(plan.splash and w.masked):
        hashgrid.mark_tire_tiles(w, g)
    if ti.static(plan.impacts):
        w.fly_count[None] = 0
    fr = stepdata.step_frame(w, h, c, m, d, g)
    top_loop(plan)
    for i in range(w.ipar[IPar.N_ROCKS]):
        rock_step(w, plan, i, fr, step, True)
    if ti.static(plan.impacts):
        impacts_loop(w, plan, fr, step, True, frame, BODIES)


@world_kernel
def coast_pass(w: ti.template(), plan: ti.template(), n: ti.i32, dt: ti.f64, centre: vec2, lead: vec2,
               step0: ti.i32):
    """``n`` steps of pass 1 in one launch, for when nothing outside a rock can change it: every vehicle that
    matters stands still for good, so the bed does not move and no tire can launch (a still tread throws
    nothing). Rocks are then independent: each thread takes its rock through the n steps doing exactly what
    ``rock_pass`` does (same functions, same step numbers for the random streams), and stops early once the
    rock rests inside the bed, where nothing can move it again. Bit-identical to n calls of ``step()``."""
    h = ti.cast(dt, w.real)
    c = ti.Vector([ti.cast(centre[0], w.real), ti.cast(centre[1], w.real)])
    m = ti.Vector([ti.cast(0.0, w.real), ti.cast(0.0, w.real)])
    d = ti.Vector([ti.cast(lead[0], w.real), ti.cast(lead[1], w.real)])
    for i in range(w.ipar[IPar.N_ROCKS]):
        for s in range(n):
            if ti.static(plan.flight):
                fly(w, i, h, plan.integrator, plan.gravity, plan.drag, plan.ground, plan.spin)
            if ti.static(plan.recycle):
                recycle(w, plan, i, c, m, d, step0 + s + 1)
            if w.phase[i] == RESTING:
                if ti.static(plan.impacts):  # coasting with impacts: no stone flies (Simulation._can_coast)
                    w.thrower[i] = -1
                settled = True
                if ti.static(plan.recycle):
                    settled = not outside_bed(w.pos[i], c, w.par[Par.BED_RADIUS], w.par[Par.GROUND_Z])
                if settled:
                    break


@world_kernel
def hash_and_tires(w: ti.template(), plan: ti.template(), step: ti.i32):
    """Passes after the rock pass, in one launch: scan, scatter, the tire pass (its ray cells, claims and
    launches; the rocks launched stay on the device, ``tire_counts[LAUNCHED]``), and clearing the counts for
    the next step's rock pass."""
    hashgrid.scan_counts(w, plan)
    tires.scatter_and_launch(w, plan, step, True)
    hashgrid.clear_all(w, plan)


@world_kernel
def reorder_rocks(w: ti.template()):
    """Re-sort the rocks in memory by hash slot after a scatter of every rock (centre insert: ``entries[k]`` is
    the rock at place k): every carried rock field (engine/rockfields.py) through its buffer, then ``entries``
    is the identity."""
    for f in ti.static(w.rocks):
        if ti.static(f.carried):
            src = ti.static(getattr(w, f.name))
            tmp = ti.static(getattr(w, tmp_name(f)))
            for k in range(w.ipar[IPar.N_ROCKS]):
                tmp[k] = src[w.entries[k]]
            for k in range(w.ipar[IPar.N_ROCKS]):
                src[k] = tmp[k]
    for k in range(w.ipar[IPar.N_ROCKS]):
        w.entries[k] = k


@world_kernel
def count_flying(w: ti.template()) -> ti.i32:
    """Rocks of the rock arrays (the active list with active stepping: rocks in the tiles rest) in flight."""
    n = 0
    for i in range(w.ipar[IPar.N_ROCKS]):
        if w.phase[i] == FLYING:
            n += 1
    return n


@world_kernel
def health(w: ti.template(), plan: ti.template(), centre: vec2, slack: ti.f64):
    """Count bad rocks into ``w.health_out``: non-finite state [0], outside the bed [1] (checked with
    recycling), below the ground [2] (checked with ground contact); the smallest index of a bad rock of each
    kind goes to [3..5] (as an index into the fields). ``slack`` widens the bed and lowers the ground."""
    out = ti.static(w.health_out)
    for k in ti.static(range(6)):
        out[k] = 0 if k < 3 else 2147483647
    radius = w.par[Par.BED_RADIUS] + ti.cast(slack, w.real)
    ground = w.par[Par.GROUND_Z] - ti.cast(slack, w.real)
    for i in range(w.ipar[IPar.N_ROCKS]):
        p, v = w.pos[i], w.vel[i]
        finite = True
        for a in ti.static(range(3)):
            if not (ti.abs(p[a]) < 1e30 and ti.abs(v[a]) < 1e30):  # false for NaN too
                finite = False
        if not finite:
            out[0] += 1
            ti.atomic_min(out[3], i)
        elif ti.static(plan.recycle):
            d2 = (p[0] - centre[0]) ** 2 + (p[1] - centre[1]) ** 2
            if d2 > radius * radius:
                out[1] += 1
                ti.atomic_min(out[4], i)
        if ti.static(plan.ground != "none"):
            if finite and p[2] - w.radius[i] < ground:
                out[2] += 1
                ti.atomic_min(out[5], i)
