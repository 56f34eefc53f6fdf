"""How a kernel sees the World's data: a few ndarrays, read as the fields they hold (``w.pos[i]``).

The World (engine/world.py) keeps every field of its layout in one of a few ``ti.ndarray`` groups, by element
type and width (:data:`GROUPS`: the reals of its precision as scalars, 3-vectors and 4-vectors; int32, float64
and int64 scalars), each field at an offset of its group, its dimensions at run time. A kernel takes the
groups as arguments and builds, as it compiles, a :class:`View` of them: an object with one attribute per
field, so that the physics reads ``w.pos[i]``, ``w.ts_key[sl]``, ``w.fly_count[None]`` as it did when these
were fields, and the kernels do not fork. A field of a scalar group with several components per entry (a
6-vector box, an int32 key pair, a float64 2-vector row) reads as a vector and is written whole
(:class:`Row`).

Where a field sits (its group, its place in the group's table of offsets and dimensions) is the World's
:class:`Layout`, hashable and the same for every World of the same fields whatever its sizes: the offsets,
the dimensions and the sizes (rocks, hash table, tile store, event buffer, ...) are read from the head of the
int32 group at run time (:data:`HEAD`). So a kernel compiles once per (layout, switches, arch), not per World.

:func:`world_kernel` turns a kernel written with a World parameter (``w: ti.template()``) into one that takes
the layout and the groups in its place (what Taichi's ahead-of-time modules and its C API can launch: ndarrays
and 32-bit scalars), and builds the View as its first statement; called with a World, it passes the World's
layout and groups. The kernel's source is rewritten line for line (the same line numbers in Taichi's
messages, under a file name of ``<file> (world kernel)``).
"""

from __future__ import annotations

import ast
import inspect
import linecache
import textwrap

import taichi as ti
from taichi.lang import impl
from taichi.lang._ndrange import _Ndrange
from taichi.lang.expr import Expr
from taichi.lang.matrix import make_matrix

__all__ = ["GROUPS", "HEAD", "SIZES", "View", "world_kernel", "WorldKernel"]

#: the ndarray groups: name -> (dtype name ("real": the World's precision), components of an element)
GROUPS = {"r1": ("real", 1), "r3": ("real", 3), "r4": ("real", 4), "i1": ("i32", 1), "d1": ("f64", 1),
          "l1": ("i64", 1)}
GROUP_NAMES = tuple(GROUPS)
#: run-time sizes at the head of the int32 group, after the fields' table; reals at the head of r1
SIZES = ("n", "table_size", "entry_capacity", "ray_capacity", "store_grid", "store_capacity", "tiles_x", "tiles_y",
         "event_capacity")
REAL_SIZES = ("store_tile", "tile_size")
HEAD = 4  # ints per field in the table: its offset (in entries of its group's elements) and three dimensions


class _Static(_Ndrange):
    """The base of the objects a kernel holds at compile time (a View, a field's accessor): Taichi 1.7.4's
    ``ti.static`` takes only a few kinds of values and its local assignment converts the rest (a tuple or a
    list element by element); an ``_Ndrange`` it passes through unchanged in both. Never iterated."""

    def __init__(self, *args, **kwargs):  # (no range of its own)
        pass


class Acc(_Static):
    """A field as a kernel sees it: ``g`` its group (the kernel's ndarray argument), ``off`` its offset,
    ``dim(j)`` its j-th dimension (an Expr, read where it is used: few fields have more than one), ``ndim``
    their number, ``row`` its components when several scalars of its group make one entry (0: one element
    of the group per entry), ``dtype`` its scalar type."""

    def __init__(self, g, off, dim, ndim, row, dtype):
        self.g, self.off, self.dim, self.ndim, self.row, self.dtype = g, off, dim, ndim, row, dtype

    @property
    def shape(self) -> tuple:
        return tuple(self.dim(j) for j in range(self.ndim))

    def _flat(self, idx):
        if idx is None:
            idx = ()
        if not isinstance(idx, tuple):
            idx = (idx,)
        flat = 0
        for k, i in enumerate(idx):
            flat = flat + i
            if k + 1 < len(idx):
                flat = flat * self.dim(k + 1)
        return flat

    def __getitem__(self, idx):
        flat = self._flat(idx)
        if self.row:
            base = (self.off + flat) * self.row
            return Row(self.g, base, self.row)
        return impl.subscript(None, self.g, self.off + flat)


class Row(Expr):
    """An entry of ``width`` consecutive scalars of group ``g`` from ``base``: reads as a vector (an Expr),
    assigns (``=``, ``+=``, ...) component by component."""

    def __init__(self, g, base, width):
        self._g, self._base, self._width = g, base, width
        super().__init__(make_matrix([impl.subscript(None, g, base + j) for j in range(width)]))

    def _element(self, j):
        return impl.subscript(None, self._g, self._base + j)

    @staticmethod
    def _part(value, j):
        if isinstance(value, (list, tuple)):
            return value[j]
        return impl.subscript(None, value, j) if isinstance(value, Expr) else value[j]

    def _assign(self, other):
        for j in range(self._width):
            self._element(j)._assign(self._part(other, j))
        return self

    def _augassign(self, other, op):
        for j in range(self._width):
            self._element(j)._augassign(self._part(other, j), op)


class View(_Static):
    """The World's fields inside a kernel (module docstring): one :class:`Acc` per field of ``layout``, its
    compile-time attributes (``layout.statics``) and its run-time sizes (``w.store_grid``: Exprs). ``cache``:
    the offsets and dimensions read once at the kernel's start into local variables (the serial variant of a
    step, engine/loops.py, where they stay in registers), else at every use (one more load, which parallel
    tasks would make anyway: a kernel's locals reach them through memory)."""

    def __init__(self, layout, groups: tuple, cache: bool):
        g = dict(zip(GROUP_NAMES, groups))

        def read(group, k):
            e = impl.subscript(None, g[group], k)
            return impl.expr_init(e) if cache else e

        n_fields = len(layout.fields)
        for k, name in enumerate(SIZES):
            setattr(self, name, read("i1", HEAD * n_fields + k))
        for k, name in enumerate(REAL_SIZES):
            setattr(self, name, read("r1", k))
        head = g["i1"]
        statics = dict(layout.statics)
        scalar = {"real": statics["real"], "i32": ti.i32, "f64": ti.f64, "i64": ti.i64}
        for k, (name, group, row, ndim, tail) in enumerate(layout.fields):
            if tail is None:  # dimensions that depend on the World's sizes: from the head
                dim = (lambda j, k=k: impl.subscript(None, head, HEAD * k + 1 + j))
            else:  # the layout's (the first one, seldom asked for, from the head)
                dim = (lambda j, k=k, tail=tail: tail[j - 1] if j > 0 else impl.subscript(None, head, HEAD * k + 1))
            setattr(self, name, Acc(g[group], read("i1", HEAD * k), dim, ndim, row, scalar[GROUPS[group][0]]))
        for name, value in layout.statics:
            setattr(self, name, value)
        self.tiles = (self.tiles_x, self.tiles_y)
        if statics.get("impacts"):  # the event buffer (engine/events.py append) on its fields
            self.events = EventsView(self.ev_ints, self.ev_reals, self.ev_count, self.event_capacity,
                                     statics["event_record"], statics["real"])
        self.layout = layout


class EventsView(_Static):
    """The World's event buffer inside a kernel: what engine/events.py ``append`` reads of an EventBuffer."""

    def __init__(self, ints, reals, count, capacity, record, real):
        self.ints, self.reals, self.count, self.capacity, self.record, self.real = \
            ints, reals, count, capacity, record, real


class WorldKernel:
    """A kernel made by :func:`world_kernel`: ``kernel`` the Taichi kernel, ``at`` the place of the World among
    the arguments of a call (which :meth:`expand` replaces with its layout and groups)."""

    def __init__(self, kernel, at: int, name: str):
        self.kernel, self.at, self.__name__ = kernel, at, name
        self._primal = kernel._primal

    def expand(self, args: tuple) -> tuple:
        w = args[self.at]
        return args[:self.at] + (w.layout,) + w.groups + args[self.at + 1:]

    def __call__(self, *args):
        return self.kernel(*self.expand(args))


def _view(layout, groups, plan=None):
    """The View a world kernel builds as it compiles (its first statement)."""
    return View(layout, groups, bool(getattr(plan, "serial", False)))


_REWRITTEN: dict = {}  # file name -> the lines of its world kernels as rewritten


def world_kernel(fn=None, *, param: str = "w"):
    """``@world_kernel`` (in place of ``@ti.kernel``): the kernel ``fn``, whose parameter ``param`` is a World
    (``w: ti.template()``), as a Taichi kernel taking the World's layout and groups in its place (module
    docstring). Called with a World (:class:`WorldKernel`)."""
    if fn is None:
        return lambda f: world_kernel(f, param=param)
    lines, first = inspect.getsourcelines(fn)
    src = textwrap.dedent("".join(lines))
    tree = ast.parse(src)
    fdef = tree.body[0]
    names = [a.arg for a in fdef.args.args]
    at = names.index(param)
    arg = fdef.args.args[at]
    text = src.splitlines(True)
    plan = "plan" if "plan" in names else "None"
    groups = ", ".join(f"{param}__{g}" for g in GROUP_NAMES)
    params = f"{param}__layout: ti.template(), " + ", ".join(
        f"{param}__{g}: ti.types.ndarray(ndim=1)" for g in GROUP_NAMES)
    line = text[arg.lineno - 1]
    end = arg.annotation.end_col_offset if arg.annotation is not None else arg.end_col_offset
    text[arg.lineno - 1] = line[:arg.col_offset] + params + line[end:]
    body = fdef.body[0]
    if hasattr(body, "body") or isinstance(body, ast.Match):  # the View's statement goes before it, on its line
        raise SyntaxError(f"{fn.__name__}: a world kernel begins with a simple statement (its docstring), not a "
                          f"{type(body).__name__.lower()} block")
    line = text[body.lineno - 1]
    text[body.lineno - 1] = (line[:body.col_offset] + f"{param} = ti.static(_world_view({param}__layout, "
                             f"({groups},), {plan})); " + line[body.col_offset:])
    for d in fdef.decorator_list:  # the decorators go (the kernel is made below), their lines stay
        for k in range(d.lineno - 1, d.end_lineno):
            text[k] = "\n"
    filename = f"{inspect.getsourcefile(fn)} (world kernel)"
    padded = ["\n"] * (first - 1) + text
    # one text per source file holding every world kernel of it at its lines (Taichi reads a kernel's source
    # from the file its code names, by line)
    merged = _REWRITTEN.setdefault(filename, [])
    merged.extend(["\n"] * (len(padded) - len(merged)))
    merged[first - 1:first - 1 + len(text)] = text
    linecache.cache[filename] = (sum(map(len, merged)), None, merged, filename)
    ns = fn.__globals__
    if fn.__closure__:  # a kernel defined in a function: its free variables join a copy of the module's names
        ns = {**ns, **{name: cell.cell_contents for name, cell in zip(fn.__code__.co_freevars, fn.__closure__)}}
    ns.setdefault("_world_view", _view)
    ns.setdefault("ti", ti)
    scope: dict = {}
    exec(compile("".join(padded), filename, "exec", dont_inherit=True), ns, scope)  # (no __future__: Taichi
    # reads the annotations as objects)
    made = scope[fn.__name__]
    made.__qualname__ = fn.__qualname__
    made.__doc__ = fn.__doc__
    return WorldKernel(ti.kernel(made), at, fn.__name__)
