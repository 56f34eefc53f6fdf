"""SNode trees for the Taichi fields the package allocates (the renderer's buffers, the effects' pools, event
buffers of their own; a World holds its data in ndarrays, engine/worlddata.py), each tree owned by a
:class:`FieldTrees` that gives it back when its owner is done.

Two limits of Taichi 1.7.4 shape this module:

- **Alignment.** Taichi's SPIR-V backends (Vulkan) pack the fields of a tree end to end with no alignment
  padding; a tree per element size keeps every offset a multiple of that size (see :class:`FieldTrees`).
- **A process holds at most 512 SNode trees** on the LLVM backends (``kMaxNumSnodeTreesLlvm``), counting every
  tree ever finalized that was not destroyed: ``ti.field(..., shape=...)`` declared between kernel launches
  makes a tree of its own at the next launch. Past the limit the next kernel launch writes outside the
  runtime's table of roots and the process dies of a segfault, with no error (measured here: the 501st
  ``ti.field`` + ``from_numpy`` pair crashed). Long-lived processes build many Renderers and effects: a sweep
  worker (runner/tasks.py), the viewer's rebuilds, a notebook, the test suite.
- **Destroying a tree throws away every compiled kernel of the process** (``SNodeTree.destroy`` calls
  ``clear_compiled_functions``: fields hold pointers into their tree), so each kernel used afterwards compiles
  again: the rock and tire passes alone take 3-4 s each. Destroying a renderer's buffer as it grew cost the
  default scene's render five recompiles of everything in 90 frames (3.4 frames/s instead of 5.7).

So every tree is owned, and trees are destroyed rarely and together:

- a :class:`FieldTrees` records the trees it finalized; :meth:`FieldTrees.release` retires them (their owner
  is done with them) and :meth:`FieldTrees.destroy` frees them at once (Taichi then reuses the tree ids);
- given an ``owner``, its trees are retired when the owner is garbage-collected;
- retired trees are destroyed only when the package's live trees pass :data:`SOFT_LIMIT` at an allocation (a
  safe point: never from inside a garbage collection that may run during a kernel launch), all in one go and
  with the registered evictors (a :class:`Pool` destroys the objects no owner holds); a render, a simulation
  or the viewer never get there, a long sweep worker seldom. Past :data:`HARD_LIMIT` an
  allocation fails with a clear error instead of a crash.
"""

from __future__ import annotations

import gc
import weakref

import numpy as np
import taichi as ti
from taichi.lang.util import to_numpy_type

__all__ = ["FieldTrees", "Pool", "live_trees", "retired_trees", "on_pressure", "SOFT_LIMIT", "HARD_LIMIT"]

TAICHI_LIMIT = 512  # SNode trees per process on the LLVM backends (Taichi 1.7.4, kMaxNumSnodeTreesLlvm)
SOFT_LIMIT = 384  # live trees of the package past which an allocation first destroys the retired ones and evicts
# (late: every kernel compiles again after that; 64 below HARD_LIMIT, the room the allocations after it need)
HARD_LIMIT = 448  # live trees of the package past which an allocation fails (room left for Taichi's own roots)
BATCH_TREES = 4  # the most trees one batch builds (element sizes 1, 2, 4, 8 bytes)

_state: dict = {"prog": None, "live": 0, "retired": [], "evictors": []}


def _runtime_state() -> dict:
    """The bookkeeping of the running Taichi runtime (a new ``ti.init`` drops every tree: start over)."""
    prog = id(ti.lang.impl.get_runtime().prog)
    if _state["prog"] != prog:
        _state.update(prog=prog, live=0, retired=[])
    return _state


def live_trees() -> int:
    """SNode trees the package holds now in this runtime (retired ones included until destroyed)."""
    return _runtime_state()["live"]


def retired_trees() -> int:
    """Of :func:`live_trees`, those whose owners are done with them (destroyed at the next pressure)."""
    return sum(t.count for t in _runtime_state()["retired"])


def on_pressure(evict) -> None:
    """Register ``evict()``: called before an allocation when the live trees pass :data:`SOFT_LIMIT`; it
    destroys what it can spare (once per function)."""
    if evict not in _state["evictors"]:
        _state["evictors"].append(evict)


def _drain(st: dict) -> None:
    while st["retired"]:
        st["retired"].pop().destroy()


def _before_allocation(new: int) -> None:
    st = _runtime_state()
    if st["live"] + new > SOFT_LIMIT:  # rare: every kernel compiles again after this (module docstring)
        gc.collect()  # owners (Renderers, Simulations) held only by reference cycles go now: their trees retire
        _drain(st)
        for evict in st["evictors"]:
            evict()
    if st["live"] + new > HARD_LIMIT:
        raise RuntimeError(f"taichi-rocks holds {st['live']} Taichi SNode trees and this allocation needs {new} "
                           f"more, past its limit of {HARD_LIMIT} (Taichi allows {TAICHI_LIMIT} per process): "
                           "close Renderers and drop Simulations that are done")


def _settle() -> None:
    """Run Taichi's field checks now, as a kernel launch would: the runtime lists the vector fields made since
    its last check and checks them all at the next one, so a tree destroyed while its fields were still listed
    would fail that check (a destroyed member has no shape) at some later, unrelated launch."""
    ti.lang.impl.get_runtime().materialize()


def _retire(trees: "FieldTrees") -> None:
    if _state["prog"] == trees._prog and trees._trees and trees not in _state["retired"]:
        _state["retired"].append(trees)


class FieldTrees:
    """Allocates fields in SNode trees and owns the trees (:meth:`destroy` frees them all).

    Two ways to allocate:

    - **batched** (dust's fields): :meth:`place` / :meth:`field` put each field in a tree of its element
      size, and :meth:`finalize` builds those trees at once;
    - **at once** (a renderer's buffers, made when first needed): :meth:`scalar`, :meth:`vector`,
      :meth:`matrix` and :meth:`image` build a tree per call, ready to use.

    Why a tree per element size: Taichi's SPIR-V backends (Vulkan) pack the fields of a tree end to end,
    sorted by size, with no alignment padding, and index a 64-bit element at byte offset o as element o >> 3. A
    64-bit field landing at 4 mod 8 (after fields of an odd number of 32-bit words) is thus read and
    written 4 bytes too low, over its neighbour, silently (Taichi 1.7.4; the LLVM backends, CPU and CUDA,
    align their layouts). The i64 launch counter did: in minimal.toml's layout it shared 8 bytes with the
    last ``ray_cell_count`` entry, so on Vulkan launches_total read that ray's cell count plus the step's
    launches, and each launch bumped the count. In a tree whose fields all have one element size every
    offset is a multiple of that size.

    ``owner``: when it is garbage-collected, the trees are retired (module docstring).
    """

    def __init__(self, owner=None):
        self._builders: dict[int, ti.FieldsBuilder] = {}
        self._trees: list = []
        self._prog = _runtime_state()["prog"]
        self._owner = None if owner is None else weakref.ref(owner)
        if owner is not None:
            weakref.finalize(owner, _retire, self)

    @classmethod
    def given(cls, trees: "FieldTrees | None", owner) -> "FieldTrees":
        """``trees`` if given (the fields then belong to its owner), or new trees owned by ``owner``."""
        return trees if trees is not None else cls(owner=owner)

    # ---------------------------------------------------------------------------------------------- batched
    def _place(self, make, dtype, shape):
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        size = np.dtype(to_numpy_type(dtype)).itemsize
        if not self._builders:  # checked before anything is made: a refusal leaves no half-built tree behind
            _before_allocation(BATCH_TREES)
        if size not in self._builders:
            self._builders[size] = ti.FieldsBuilder()
        f = make()
        self._builders[size].dense(ti.axes(*range(len(shape))), shape).place(f)
        return f

    def field(self, dtype, shape):
        """A scalar field of a Taichi ``dtype`` over ``shape`` (an event buffer of its own, test buffers)."""
        return self._place(lambda: ti.field(dtype), dtype, shape)

    def place(self, spec, real):
        """The field of a :class:`FieldSpec` (``real``: the simulation's Taichi precision)."""
        dtype = real if spec.dtype == "real" else {"i32": ti.i32, "i64": ti.i64, "f64": ti.f64}[spec.dtype]
        make = (lambda: ti.field(dtype)) if spec.n == 1 else (lambda: ti.Vector.field(spec.n, dtype))
        return self._place(make, dtype, spec.shape)

    def finalize(self) -> None:
        """Build the trees of the fields placed so far."""
        for fb in self._builders.values():
            self._keep(fb.finalize(raise_warning=False))
        self._builders = {}
        _settle()

    # ---------------------------------------------------------------------------------------------- at once
    def _now(self, makers: list, shape, axes=None):
        shape = (int(shape),) if np.isscalar(shape) else tuple(int(s) for s in shape)
        _before_allocation(1)  # before the fields exist: a refusal leaves none unplaced
        fields = [make() for make in makers]
        fb = ti.FieldsBuilder()
        if not shape:
            fb.place(*fields)
        elif axes is None:
            fb.dense(ti.axes(*range(len(shape))), shape).place(*fields)
        else:  # nested: the first axis outermost (image rows contiguous)
            node = fb
            for ax, n in zip(axes, shape):
                node = node.dense(ax, n)
            node.place(*fields)
        self._keep(fb.finalize(raise_warning=False))
        _settle()
        return fields[0] if len(fields) == 1 else tuple(fields)

    def scalar(self, dtype, shape=()):
        """A scalar field over ``shape`` (() for a 0-D one) in a tree of its own."""
        return self._now([lambda: ti.field(dtype)], shape)

    def vector(self, n: int, dtype, shape=()):
        return self._now([lambda: ti.Vector.field(n, dtype)], shape)

    def matrix(self, n: int, m: int, dtype, shape=()):
        return self._now([lambda: ti.Matrix.field(n, m, dtype)], shape)

    def image(self, width: int, height: int, *members):
        """Fields over width x height pixels, indexed [x, y] and laid out rows contiguous, in one tree;
        ``members``: (n, dtype) each, n = 1 for a scalar field (all of one element size: Vulkan packs a tree
        without alignment). One field, or a tuple of them."""
        makers = [(lambda d=d: ti.field(d)) if n == 1 else (lambda n=n, d=d: ti.Vector.field(n, d))
                  for n, d in members]
        return self._now(makers, (height, width), axes=(ti.j, ti.i))

    # ---------------------------------------------------------------------------------------------- owning
    def _keep(self, tree) -> None:
        self._trees.append(tree)
        _runtime_state()["live"] += 1

    @property
    def count(self) -> int:
        """The trees this owns now."""
        return len(self._trees)

    def release(self) -> "FieldTrees":
        """Retire the trees this owns (their fields must not be used again): destroyed with the others the next
        time the live trees run high. Returns a new, empty FieldTrees for the owner's next fields."""
        _retire(self)
        owner = self._owner() if self._owner is not None else None
        return FieldTrees(owner=owner)

    def destroy(self) -> None:
        """Free every tree this owns (their fields must not be used again). Idempotent; a tree of an earlier
        Taichi runtime is dropped, not destroyed."""
        st = _runtime_state()
        same = st["prog"] == self._prog
        if self in st["retired"]:
            st["retired"].remove(self)
        for tree in self._trees:
            if same:
                tree.destroy()
                st["live"] -= 1
        self._trees = []


class Pool:
    """Objects that hold fields, leased by owners in turn and kept by layout: a renderer's buffers
    (render/buffers.py, render/hits.py), dust's fields (engine/effects/dust.py).

    Every kernel compiles again for a new object of fields (its fields are template arguments: seconds), so an
    owner done with its object leaves it here, and the next owner of the same layout gets it back, reset, with
    its kernels compiled. Each object has ``trees`` (its :class:`FieldTrees`) and ``owner`` (a weak reference
    to its owner, or None); it is free once its owner called :meth:`give_back` or was garbage-collected.
    Two live owners never share one. Free objects stay until the process runs short of SNode trees: then
    :meth:`evict` (registered with :func:`on_pressure`) destroys them. A new Taichi runtime forgets them all
    (their fields died with the old one)."""

    def __init__(self):
        self._by_key: dict = {}
        self._prog = None
        on_pressure(self.evict)

    def lease(self, owner, key, make, reset=None):
        """A free object of layout ``key`` for ``owner``, after ``reset(obj)``; or else ``make()``, kept.

        When every object of the layout is leased, a garbage collection runs first: an owner that a finished
        test or notebook cell dropped but a reference cycle still holds is not freed before the collector runs,
        and the next owner would compile a new object. A collection takes milliseconds (about 50 ms in a
        process holding a test suite's worth of objects); a new object's compiles take seconds."""
        prog = _runtime_state()["prog"]
        if self._prog != prog:
            self._by_key, self._prog = {}, prog
        obj = self._free(key)
        if obj is None and self._by_key.get(key):
            gc.collect()
            obj = self._free(key)
        if obj is not None:
            if reset is not None:
                reset(obj)
            obj.owner = weakref.ref(owner)
            return obj
        obj = make()
        obj.owner = weakref.ref(owner)
        self._by_key.setdefault(key, []).append(obj)
        return obj

    def _free(self, key):
        return next((obj for obj in self._by_key.get(key, ()) if self.is_free(obj)), None)

    @staticmethod
    def is_free(obj) -> bool:
        return obj.owner is None or obj.owner() is None

    @staticmethod
    def give_back(obj, owner) -> None:
        """``owner`` is done with ``obj`` (it must not use it again); nothing if ``obj`` is no longer its (a
        second close after another owner leased it)."""
        if obj.owner is not None and obj.owner() is owner:
            obj.owner = None

    def evict(self) -> None:
        """Destroy every free object's trees."""
        for key in list(self._by_key):
            keep = []
            for obj in self._by_key[key]:
                if self.is_free(obj):
                    obj.trees.destroy()
                else:
                    keep.append(obj)
            if keep:
                self._by_key[key] = keep
            else:
                del self._by_key[key]
