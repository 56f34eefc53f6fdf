"""What changed since the last read: the rows ``Simulation.changes()`` returns, at a cost that follows them.

A game draws the bed from a mirror of it and wants, each frame, only the rocks whose drawn state (position,
phase and, when the scene tumbles, orientation) changed: a few thousand of 200,000. The World keeps, per rock
id, the drawn state as of the end of the last step (``drawn_pos``, ``drawn_phase``, ``drawn_orient``), a flag per
id and a list of the ids flagged since the last read (``drawn_flag``, ``drawn_list``, ``drawn_count``):

* :func:`note` - at the end of every step, for each rock a step can have changed (the active list after the
  tire pass, inside the settling loop of active stepping; every rock with full stepping), compare its state with
  the mirror bit for bit; where it differs, copy it and list the id once (an atomic flag, then an atomic slot);
* :func:`shift_drawn_rows` - the floating origin moved by d (engine/origin.py ``move_origin``): the mirror moves
  as the rocks do, p' = fl(p - d), and a rock is listed where its world position changes by rounding, float64(p') + origin' != float64(p) + origin
  (the f32 move rounds near a zero coordinate; the origin, anchor + whole multiples of 64 m, rounds in float64
  when the anchor has a fraction): a few to all rocks, once per shift (every 3-6 s at 20 m/s);
* :func:`sync_drawn` - rocks were loaded (a new Simulation, restore, set_rocks): the mirror from the rock arrays,
  every id listed (the next read gives every rock);
* :func:`gather_packed` (CPU) - the read in one launch: the k listed ids' mirror rows into a float64 NumPy array
  the host keeps (Taichi writes into it in place; every int32 id and f32 value is exact in float64), the flags
  and the count cleared, k returned; a buffer too small for k is grown and the launch repeated
  (:func:`gather_counted`: the same, k written into a one-element array, for a host without Python: native/);
* :func:`gather` (GPU backends) - k read first (one scalar), then the rows into NumPy arrays of k rows (Taichi
  copies k rows back, not the bed).

Between two steps the mirror equals every rock's drawn state, so a read applied to a mirror of the bed
reproduces ``Simulation.state()`` exactly (tests/engine/test_changes.py, every frame, both stepping modes, with
tumbling and with origin shifts). The cost of a step grows by one comparison per rock the step visits; a read
costs O(k). On a GPU the mirror and the gathered rows are device fields: a renderer using Taichi on the same
device can take them as they are (docs: "Reading what changed").
"""


import taichi as ti

from .loops import top_loop
from .params import IPar
from .view import world_kernel

__all__ = ["note", "note_listed", "shift_drawn_rows", "sync_drawn", "listed_count", "gather", "gather_packed",
           "gather_counted", "DRAWN"]

#: the rock fields the mirror holds, as (rock field, mirror field); "orient" only where the World has it
DRAWN = (("pos", "drawn_pos"), ("phase", "drawn_phase"), ("orient", "drawn_orient"))


def mirrored(w) -> tuple:
    """The (rock field, mirror field, components) of World ``w``'s mirror (none without one)."""
    if not getattr(w, "drawn", False):
        return ()
    n = {f.name: f.n for f in w.rocks}
    return tuple((r, m, n[r]) for r, m in DRAWN if r in n)


@ti.func
def _differs(a, b, n: ti.template()):
    """Bit-level difference of two values of ``n`` components (NaN differs from itself: such a rock is
    listed)."""
    out = False
    if ti.static(n > 1):
        for j in ti.static(range(n)):
            if a[j] != b[j]:
                out = True
    else:
        out = a != b
    return out


@ti.func
def _list(w: ti.template(), rid):
    if ti.atomic_max(w.drawn_flag[rid], 1) == 0:
        w.drawn_list[ti.atomic_add(w.drawn_count[None], 1)] = rid


@ti.func
def note(w: ti.template(), i):
    """Rock i of the rock arrays (the active list): if its drawn state differs from the mirror's, copy it there
    and list its id. A no-op in a World without a mirror."""
    if ti.static(len(mirrored(w)) > 0):
        rid = w.rock_id[i]
        if rid >= 0:
            changed = False
            for r, m, n in ti.static(mirrored(w)):
                if _differs(ti.static(getattr(w, r))[i], ti.static(getattr(w, m))[rid], n):
                    changed = True
            if changed:
                for r, m, _ in ti.static(mirrored(w)):
                    ti.static(getattr(w, m))[rid] = ti.static(getattr(w, r))[i]
                _list(w, rid)


@world_kernel
def note_listed(w: ti.template(), plan: ti.template()):
    """:func:`note` for every rock of the rock arrays (full stepping, after a step or a coast), in the step's
    variant (``plan``: Switches of ``serial``, engine/loops.py)."""
    top_loop(plan)
    for i in range(w.ipar[IPar.N_ROCKS]):
        note(w, i)


@ti.func
def shift_drawn_rows(w: ti.template(), dv, before, after, exact: ti.template()):
    """The floating origin moved by ``dv`` (the move as a 3-vector in the World's precision, z = 0) from
    ``before`` to ``after`` (float64 XY, world; engine/origin.py ``move_origin``): every mirror position moves as
    its rock does (p - d in the World's precision), and a rock whose world position float64(p) + origin differs
    after the move (the f32 move rounds, or the float64 sum does) is listed. ``exact``: the backend computes in
    float64 (CPU, CUDA); without it every rock is listed."""
    for rid in range(w.n):
        p = w.drawn_pos[rid]
        q = p - dv
        moved = True
        if ti.static(exact):
            moved = False
            for c in ti.static(range(2)):
                if ti.cast(p[c], ti.f64) + before[c] != ti.cast(q[c], ti.f64) + after[c]:
                    moved = True
        if moved:
            _list(w, rid)
        w.drawn_pos[rid] = q


@world_kernel
def sync_drawn(w: ti.template()):
    """Every rock is in the rock arrays (just loaded): the mirror from them, every id listed."""
    for i in range(w.ipar[IPar.N_ROCKS]):
        rid = w.rock_id[i]
        for r, m, _ in ti.static(mirrored(w)):
            ti.static(getattr(w, m))[rid] = ti.static(getattr(w, r))[i]
        _list(w, rid)


@world_kernel
def listed_count(w: ti.template()) -> ti.i32:
    return w.drawn_count[None]


@ti.func
def _packed_row(w: ti.template(), out: ti.template(), j, rid):
    out[j, 0] = ti.cast(rid, ti.f64)
    out[j, 1] = ti.cast(w.drawn_phase[rid], ti.f64)
    p = w.drawn_pos[rid]
    for c in ti.static(range(3)):
        out[j, 2 + c] = ti.cast(p[c], ti.f64)
    if ti.static(len(mirrored(w)) == 3):
        q = w.drawn_orient[rid]
        for c in ti.static(range(4)):
            out[j, 5 + c] = ti.cast(q[c], ti.f64)


@ti.func
def _take_packed(w: ti.template(), out: ti.template()):
    """The rows of every listed id into ``out`` (as :func:`gather_packed` says), the flags and the count cleared
    if they fit; returns the count."""
    k = w.drawn_count[None]
    fits = k <= out.shape[0]
    ti.loop_config(serialize=True)
    for j in range(k):
        if fits:
            rid = w.drawn_list[j]
            _packed_row(w, out, j, rid)
            w.drawn_flag[rid] = 0
    if fits:
        w.drawn_count[None] = 0
    return k


@world_kernel
def gather_packed(w: ti.template(), out: ti.types.ndarray(dtype=ti.f64, ndim=2)) -> ti.i32:
    """Rows (id, phase, position in the local frame, orientation x, y, z, w with tumbling) of every listed id
    into ``out`` (float64), the flags and the count cleared; returns the count. If ``out`` has fewer rows than
    the count, nothing is written or cleared (the caller grows it and calls again). One serial task: a game's
    read is a few thousand rows, less work than a parallel task's start-up on the CPU (engine/loops.py)."""
    return _take_packed(w, out)


@world_kernel
def gather_counted(w: ti.template(), out: ti.types.ndarray(dtype=ti.f64, ndim=2),
                   count: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """:func:`gather_packed` with the count written to ``count[0]`` instead of returned: what a host launching
    through Taichi's C API reads (a kernel returns no value there; native/)."""
    count[0] = _take_packed(w, out)


@world_kernel
def gather(w: ti.template(), k: ti.i32, ints: ti.types.ndarray(ndim=2), reals: ti.types.ndarray(ndim=2)):
    """The first ``k`` listed ids' rows: ``ints[j]`` = (id, phase), ``reals[j]`` = (position in the local frame,
    then the orientation x, y, z, w with tumbling); their flags and the count cleared."""
    for j in range(k):
        rid = w.drawn_list[j]
        ints[j, 0] = rid
        ints[j, 1] = w.drawn_phase[rid]
        p = w.drawn_pos[rid]
        for c in ti.static(range(3)):
            reals[j, c] = p[c]
        if ti.static(len(mirrored(w)) == 3):
            q = w.drawn_orient[rid]
            for c in ti.static(range(4)):
                reals[j, 3 + c] = q[c]
        w.drawn_flag[rid] = 0
    w.drawn_count[None] = 0
