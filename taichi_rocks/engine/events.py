"""Impact events: one declaration of the record (:data:`EVENT_FIELDS`, the NumPy dtype :data:`EVENT_DTYPE`), a
device buffer appended atomically from kernels (:class:`EventBuffer`), and its drain to a structured array.

The device layout derives from the declaration: integer fields are columns of one int32 matrix, float fields
(vectors: one column per component) columns of one matrix in the simulation's precision: in a World, fields of
its ndarray groups (engine/view.py); a buffer of its own places them in trees of one element size each
(engine/trees.py, FieldTrees: Vulkan packs a tree without alignment). A kernel builds an
:meth:`EventBuffer.record` struct by field name and appends it with :func:`append`: a slot from an atomic
counter; past the capacity the counter still counts, so an overflow is counted and reported by the drain
(``dropped``), never lost silently. Which events an overflow drops depends on thread timing.

:meth:`EventBuffer.drain` returns the events since the previous drain (sorted by step, rock and vehicle, so
that a run gives the same array whatever the order threads appended in) and empties the buffer. Times: on the
device relative to the buffer's reference time ``t_ref`` (float64 on the host: the simulation time at the last
drain that took events, or at an empty one once it lagged more than ``REF_SPAN``), so float32 keeps them to
~1e-7 of the time between drains.
"""

import numpy as np
import taichi as ti

from ..config.impacts import DAMAGE_CLASSES
from ..motion.bodies import LABELS
from .launcher import Launcher
from .view import world_kernel
from .runtime import on_cpu
from .trees import FieldTrees

__all__ = ["EVENT_FIELDS", "EVENT_DTYPE", "EventBuffer", "append", "LABELS", "DAMAGE_CLASSES"]

# name, host dtype, shape, meaning. Indices: ``part`` into motion.bodies.LABELS, ``damage`` into
# config.impacts.DAMAGE_CLASSES. Vectors are in the frame of the vehicle hit (x forward, y left, z up).
EVENT_FIELDS = (
    ("time", np.float64, (), "s, when the stone touched the body"),
    ("step", np.int64, (), "the simulation step it touched in (step count after that step)"),
    ("vehicle", np.int32, (), "the vehicle hit (index in the scene's [[vehicle]] list)"),
    ("part", np.int8, (), "what was hit: index into LABELS"),
    ("damage", np.int8, (), "damage class: index into DAMAGE_CLASSES (mark, chip, crack)"),
    ("point", np.float64, (3,), "m, contact point on the body, vehicle frame"),
    ("normal", np.float64, (3,), "outward unit normal of the body at the contact, vehicle frame"),
    ("speed", np.float64, (), "m/s, speed of the stone relative to the body's contact point"),
    ("normal_speed", np.float64, (), "m/s, its component into the body (>= 0)"),
    ("normal_momentum", np.float64, (), "N s, m times the normal speed"),
    ("energy", np.float64, (), "J, kinetic energy of the relative motion, 1/2 m speed^2"),
    ("radius", np.float64, (), "m, the stone's radius"),
    ("rock", np.int32, (), "the stone's id"),
    ("thrower", np.int32, (), "the vehicle whose tire threw it (-1: unknown)"),
)
EVENT_DTYPE = np.dtype([(name, dt, shape) for name, dt, shape, _ in EVENT_FIELDS])


def _columns():
    """(name, is_int, first column, components) per field, and the int and real column counts."""
    out, n_int, n_real = [], 0, 0
    for name, dt, shape, _ in EVENT_FIELDS:
        width = int(np.prod(shape)) if shape else 1
        is_int = np.issubdtype(dt, np.integer)
        out.append((name, is_int, n_int if is_int else n_real, width, len(shape) > 0))
        if is_int:
            n_int += width
        else:
            n_real += width
    return tuple(out), n_int, n_real


COLUMNS, N_INT, N_REAL = _columns()
REF_SPAN = 1.0  # s: the reference time moves at an empty drain only when it lags more than this (float32: 1e-7 s)


_RECORDS: dict = {}


def record_type(real):
    """The event as a Taichi struct in precision ``real``, one object per precision: build one in a kernel by
    keyword and append() it."""
    key = str(real)
    if key not in _RECORDS:
        vec3 = ti.types.vector(3, real)
        _RECORDS[key] = ti.types.struct(**{name: (vec3 if vector else (ti.i32 if is_int else real))
                                           for name, is_int, _, _, vector in COLUMNS})
    return _RECORDS[key]


@ti.data_oriented
class EventBuffer:
    """``capacity`` events on the device, in precision ``real``; ``trees``: the FieldTrees to place the fields in
    (finalized by their owner), or None for trees of its own; or ``world``: the World whose ``ev_ints``,
    ``ev_reals``, ``ev_count`` hold them (engine/world.py field_specs; kernels then see them as ``w.events``)."""

    def __init__(self, capacity: int, real, trees=None, world=None):
        if int(capacity) < 1:
            raise ValueError(f"an event buffer holds at least one event, got capacity {capacity}")
        self.capacity = int(capacity)
        self.real = real
        self.world = world
        if world is not None:
            self.ints, self.reals, self.count = world.ev_ints, world.ev_reals, world.ev_count
        else:
            own = trees is None
            trees = FieldTrees() if own else trees
            self.ints = trees.field(ti.i32, (self.capacity, N_INT))
            self.reals = trees.field(real, (self.capacity, N_REAL))
            self.count = trees.field(ti.i32, ())  # events appended since the last drain, kept or not
            if own:
                trees.finalize()
        self.np_real = np.float64 if real == ti.f64 else np.float32
        self.record = record_type(real)  # build one in a kernel by keyword and append() it
        self.dropped = 0  # events lost to overflow, over all drains
        self.t_ref = 0.0  # s: device times are relative to this

    def drain(self, t_now: float | None = None) -> np.ndarray:
        """The events since the last drain as a structured array of :data:`EVENT_DTYPE`; empties the buffer and,
        given ``t_now`` (the simulation time), makes it the reference of the times appended from now on. On the
        CPU one launch writes them into host arrays kept for it (Taichi writes NumPy arrays in place there); on a
        device the count is read first and exactly that many rows come back."""
        if on_cpu():
            host = self.__dict__.get("_host")  # (a data-oriented object: each attribute read costs a microsecond)
            if host is None:
                host = self._host = (Launcher(_take_all if self.world is None else _take_all_world),
                                     self if self.world is None else self.world,
                                     np.empty((self.capacity, N_INT), np.int32),
                                     np.empty((self.capacity, N_REAL), self.np_real))
            appended = int(host[0](host[1], host[2], host[3]))
            if appended == 0:  # most drains of a game's frames: nothing to convert or sort, the reference stays
                if t_now is not None and abs(float(t_now) - self.t_ref) > REF_SPAN:
                    self.t_ref = float(t_now)
                return np.empty(0, EVENT_DTYPE)
            n = min(appended, self.capacity)
            ints, reals = host[2][:n], host[3][:n]
        else:
            appended = int(self.count[None])
            n = min(appended, self.capacity)
            ints = np.empty((n, N_INT), np.int32)
            reals = np.empty((n, N_REAL), self.np_real)
            if appended:
                if self.world is None:
                    _gather(self, n, ints, reals)
                else:
                    _gather_world(self.world, n, ints, reals)
        self.dropped += appended - n
        if n == 0:  # most drains of a game's frames: nothing to convert or sort, and the reference time stays
            self._move_ref(t_now, False)
            return np.empty(0, EVENT_DTYPE)
        out = np.empty(n, EVENT_DTYPE)
        for name, is_int, col, width, vector in COLUMNS:
            src = ints if is_int else reals
            out[name] = src[:, col:col + width] if vector else src[:, col]
        out["time"] += self.t_ref
        self._move_ref(t_now, True)
        return out[np.lexsort((out["vehicle"], out["rock"], out["step"]))]

    def _move_ref(self, t_now: float | None, drained: bool) -> None:
        """The reference time moves to ``t_now`` at a drain that took events, or once it lags ``REF_SPAN``
        behind: an empty drain (most of a game's frames) leaves it, so the step kernels need not be told of a
        new one every frame, and the device's times stay within REF_SPAN + the time between drains of it."""
        if t_now is not None and (drained or abs(float(t_now) - self.t_ref) > REF_SPAN):
            self.t_ref = float(t_now)

    def reset(self, t_now: float = 0.0) -> None:
        """Forget every event and the overflow count (a restart, a restore)."""
        if self.world is None:
            _clear(self)
        else:
            self.count[None] = 0
        self.dropped, self.t_ref = 0, float(t_now)


@ti.func
def _rows(buf: ti.template(), n, ints: ti.template(), reals: ti.template()):
    """Events 0 .. n - 1 of ``buf`` into the host's arrays, the count cleared."""
    for k in range(n):
        for c in ti.static(range(N_INT)):
            ints[k, c] = buf.ints[k, c]
        for c in ti.static(range(N_REAL)):
            reals[k, c] = buf.reals[k, c]
    buf.count[None] = 0


@ti.func
def _all_rows(buf: ti.template(), ints: ti.template(), reals: ti.template()):
    """Every event kept (at most the capacity) into ``ints`` and ``reals`` (capacity rows each), the count
    cleared; returns the count appended since the last drain (kept or not). One serial task: a frame's few
    events are less work than a parallel task's start-up."""
    appended = buf.count[None]
    ti.loop_config(serialize=True)
    for k in range(ti.min(appended, buf.capacity)):
        for c in ti.static(range(N_INT)):
            ints[k, c] = buf.ints[k, c]
        for c in ti.static(range(N_REAL)):
            reals[k, c] = buf.reals[k, c]
    buf.count[None] = 0
    return appended


@ti.kernel
def _gather(buf: ti.template(), n: ti.i32, ints: ti.types.ndarray(), reals: ti.types.ndarray()):
    _rows(buf, n, ints, reals)


@world_kernel
def _gather_world(w: ti.template(), n: ti.i32, ints: ti.types.ndarray(), reals: ti.types.ndarray()):
    """A World's events (``w.events``), as :func:`_gather`."""
    _rows(w.events, n, ints, reals)


@ti.kernel
def _take_all(buf: ti.template(), ints: ti.types.ndarray(), reals: ti.types.ndarray()) -> ti.i32:
    return _all_rows(buf, ints, reals)


@world_kernel
def _take_all_world(w: ti.template(), ints: ti.types.ndarray(), reals: ti.types.ndarray()) -> ti.i32:
    """A World's events (``w.events``), as :func:`_take_all`."""
    return _all_rows(w.events, ints, reals)


@world_kernel
def take_counted(w: ti.template(), ints: ti.types.ndarray(), reals: ti.types.ndarray(),
                 count: ti.types.ndarray(dtype=ti.i32, ndim=1)):
    """A World's events as :func:`_take_all_world`, the count appended since the last drain written to
    ``count[0]`` instead of returned: what a host launching through Taichi's C API reads (native/)."""
    count[0] = _all_rows(w.events, ints, reals)


@ti.kernel
def _clear(buf: ti.template()):
    buf.count[None] = 0


@ti.func
def append(buf: ti.template(), ev):
    """Append event ``ev`` (a ``buf.record``; ``time`` relative to ``buf.t_ref``); past the capacity only the
    count grows."""
    slot = ti.atomic_add(buf.count[None], 1)
    if slot < buf.capacity:
        for name, is_int, col, width, vector in ti.static(COLUMNS):
            if ti.static(vector):
                for j in ti.static(range(width)):
                    buf.reals[slot, col + j] = ev[name][j]
            elif ti.static(is_int):
                buf.ints[slot, col] = ev[name]
            else:
                buf.reals[slot, col] = ev[name]
