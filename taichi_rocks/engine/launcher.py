"""Launching a kernel many times at the cost of the launch alone: Taichi's launch with its Python side done once.

A call of a Taichi 1.7.4 kernel from Python checks and converts every argument before the launch: it finds the
compiled instance from the template arguments (hashing them), builds a launch context and sets each argument
on it, about 10 us for an empty kernel and 10 us more for each array argument or returned value on these CPUs
(``launch_probe`` in the benchmark). A game's frame makes a few such calls, each over about a millisecond of
budget. :class:`Launcher` keeps, per set of template arguments, the compiled kernel and a launch context, and
on a call sets only the scalar and array arguments on that context and launches: about 1-2 us.

It does what Taichi's own launch does, in the same order, and nothing else: the same compiled kernel (from the
same cache), the same argument values (scalars converted as Taichi converts them, NumPy arrays by pointer and
shape), the same return value; so the results are the same bits. What it leaves out is what the engine's hot
kernels do not use: autodiff, argument packs, textures, matrix-typed scalar arguments and non-contiguous arrays
(a kernel or a call with any of them takes Taichi's own path), and Taichi's type errors (a call that would
need a new compiled instance, an array of another dtype or rank, takes Taichi's own path too, which compiles
or raises as it always did). Only on the CPU backend, where a launch runs on the calling thread and an array
argument is the NumPy buffer itself; elsewhere every call is Taichi's own.

The compiled kernel can go away: Taichi drops every compiled kernel when an SNode tree is destroyed
(engine/trees.py) or the runtime restarts; a launcher notices (its instance is no longer Taichi's) and builds
its context again.
"""

from __future__ import annotations

import numpy as np
from taichi._lib import core as _ti_core
from taichi.lang import impl
from taichi.lang._ndarray import Ndarray
from taichi.types import ndarray_type, primitive_types
from taichi.types.annotations import template

from .runtime import on_cpu

__all__ = ["Launcher"]

_INT, _FLOAT, _ARRAY, _OTHER = 0, 1, 2, -1


def _kind(annotation):
    """How the launcher sets an argument of this annotation (None: a template; _OTHER: Taichi's own path)."""
    if isinstance(annotation, template) or annotation is template:
        return None
    if id(annotation) in primitive_types.integer_type_ids:  # signed ones: Taichi sets unsigned ones otherwise
        return _INT if any(annotation is t for t in (primitive_types.i8, primitive_types.i16, primitive_types.i32,
                                                     primitive_types.i64)) else _OTHER
    if id(annotation) in primitive_types.real_type_ids:
        return _FLOAT
    if isinstance(annotation, ndarray_type.NdarrayType):
        return _ARRAY
    return _OTHER


def _array_key(v):
    """A cheap key of what an array argument's compiled instance depends on: a NumPy array's dtype and rank, a
    device array's features (:func:`_features`, kept on the array once made)."""
    if type(v) is np.ndarray:
        return (v.dtype.num, v.ndim)
    key = getattr(v, "_launch_key", None)
    if key is None:
        key = _features(v) if isinstance(v, Ndarray) else id(type(v))
        try:
            v._launch_key = key
        except AttributeError:
            pass
    return key


def _features(v) -> tuple:
    """What a compiled kernel is specialised on of a device array argument (Taichi's own key: its element type,
    dimensions and element shape): another array of the same features runs the same compiled kernel."""
    return (str(v.dtype), len(v.shape), tuple(v.element_shape), v.layout)


def _getter(ret):
    """The launch context's reader of a kernel's one returned scalar, as Taichi reads it (None: no value;
    _OTHER: another kind of return, Taichi's own path)."""
    if ret is None:
        return None
    if len(ret) != 1:
        return _OTHER
    t = ret[0]
    if any(t is x for x in (primitive_types.i8, primitive_types.i16, primitive_types.i32, primitive_types.i64)):
        return lambda ctx, index: ctx.get_struct_ret_int(index)
    if t in primitive_types.real_types:
        return lambda ctx, index: ctx.get_struct_ret_float(index)
    return _OTHER


class _Bound:
    """The compiled instance of one set of template arguments, its launch context and what the arrays it was
    built with were (dtype, rank): a call with others takes Taichi's own path."""

    __slots__ = ("t_kernel", "config", "caps", "ctx", "prog", "arrays", "key", "templates", "last")


class Launcher:
    """``kernel`` (a ``@ti.kernel``) called as it is, ``launcher(*args)``, at the cost of the launch alone on the
    CPU (module docstring); the same arguments, the same result. Hold one per user of the kernel (a stepper):
    it keeps its template arguments alive while it lives."""

    def __init__(self, kernel):
        self.kernel = kernel
        # a world kernel (engine/view.py) takes the World as its layout and groups: expanded before the launch
        self._expand = getattr(kernel, "expand", None)
        self._primal = getattr(kernel, "_primal", None)  # None: not a Taichi kernel (a wrapper): called as it is
        self._plan = None  # per argument: its kind (None: template), built at the first call
        self._bound: dict = {}

    def __call__(self, *args):
        if self._primal is None or not on_cpu():
            return self.kernel(*args)
        if self._expand is not None:
            args = self._expand(args)
        if self._plan is None:
            self._plan = tuple(_kind(a.annotation) for a in self._primal.arguments)
            self._templates = tuple(i for i, k in enumerate(self._plan) if k is None)
            self._arrays = tuple(i for i, k in enumerate(self._plan) if k == _ARRAY)
            self._ret = _getter(self._primal.return_type)
            self._supported = (_OTHER not in self._plan and len(self._plan) == len(args)
                               and self._primal.autodiff_mode == _ti_core.AutodiffMode.NONE
                               and self._ret is not _OTHER)
        if not self._supported or len(args) != len(self._plan):
            return self._primal_call(args)
        # one compiled instance per template arguments and arrays' features (Taichi's key): one bound context each
        tkey = tuple(id(args[i]) for i in self._templates) + tuple(_array_key(args[i]) for i in self._arrays)
        b = self._bound.get(tkey)
        if b is None or self._primal.compiled_kernels.get(b.key) is not b.t_kernel \
                or impl.get_runtime().prog is not b.prog:
            b = self._bind(args, tkey)
            if b is None:
                return self._primal_call(args)
        ctx = b.ctx
        slot = 0
        arrays = b.arrays
        for i, kind in enumerate(self._plan):
            if kind is None:
                continue
            v = args[i]
            if kind == _INT:
                ctx.set_arg_int((slot,), int(v))
            elif kind == _FLOAT:
                ctx.set_arg_float((slot,), float(v))
            else:
                want = arrays[slot]
                if want[0] == "ndarray":  # a device array (a World's group): one of the features compiled for
                    if v is not b.last.get(slot) and (not isinstance(v, Ndarray) or _features(v) != want[1]):
                        return self._primal_call(args)
                    # set at every launch: Taichi's launch turns the array's handle in the context into its
                    # address in place, so a context launched once no longer holds the handle
                    ctx.set_arg_ndarray((slot,), v.arr)
                    b.last[slot] = v
                else:
                    if type(v) is not np.ndarray or v.dtype != want[0] or v.ndim != want[1] \
                            or not v.flags.c_contiguous:
                        return self._primal_call(args)
                    shape = v.shape if want[2] == 0 else v.shape[:-want[2]]
                    ctx.set_arg_external_array_with_shape((slot,), int(v.ctypes.data), v.nbytes, shape, 0)
            slot += 1
        # the compiled code asked for at every launch, as Taichi's call does (a cache lookup): Taichi hands a
        # reference into its cache, which another kernel's compile may move, so it is never kept
        b.prog.launch_kernel(b.prog.compile_kernel(b.config, b.caps, b.t_kernel), ctx)
        if self._ret is None:
            return None
        b.prog.synchronize()
        return self._ret(ctx, (0,))

    def _primal_call(self, args):
        """Taichi's own call (``args`` already expanded for a world kernel)."""
        return (self.kernel.kernel if self._expand is not None else self.kernel)(*args)

    def _bind(self, args, tkey):
        """Compile (or find) the instance of these template arguments, as Taichi's call does, and make its
        launch context; None when an argument is not one the launcher sets (Taichi's own path then)."""
        prim = self._primal
        key = prim.ensure_compiled(*args)
        b = _Bound()
        b.key = key
        b.t_kernel = prim.compiled_kernels[key]
        b.prog = impl.get_runtime().prog
        b.config, b.caps = b.prog.config(), b.prog.get_device_caps()
        b.ctx = b.t_kernel.make_launch_context()
        b.last = {}  # slot -> the device array set there last (kept alive: the context points into it)
        arrays = {}
        slot = 0
        for i, kind in enumerate(self._plan):
            if kind is None:
                continue
            if kind == _ARRAY:
                v = args[i]
                if isinstance(v, Ndarray):
                    arrays[slot] = ("ndarray", _features(v))
                elif type(v) is not np.ndarray:
                    return None
                else:
                    needed = prim.arguments[i].annotation
                    element = 0
                    if needed.dtype is not None and id(needed.dtype) not in primitive_types.type_ids:
                        element = needed.dtype.ndim
                    arrays[slot] = (v.dtype, v.ndim, element)
            slot += 1
        b.arrays = arrays
        # alive while bound: their ids stay theirs (and a World's groups, checked by identity)
        b.templates = tuple(args[i] for i in self._templates)
        self._bound[tkey] = b
        return b
