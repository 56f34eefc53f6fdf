"""Many fields to and from NumPy in one launch each way (engine/rocks.py's reads and writes of the rock fields).

Taichi compiles ``field.from_numpy`` and ``field.to_numpy`` once per field (the field is a template argument of
its copy kernel): a World's six to nine saved rock fields cost about 40 ms of compiling each way and field,
about 0.5 s a World on a 2-core CPU. Here a group of fields travels as two 2-D arrays, the real fields' components
side by side in columns of one array of the World's precision and the i32 fields in one int32 array, through one
kernel for both directions: one compile a World and group (about 60 ms), and one launch instead of one per field.

:func:`put_whole` writes whole fields of any shapes and element kinds (scalars, vectors, matrices; a World's
bodies, engine/impact_pass.py) from their arrays in one launch: one compile a World instead of one per field.

The values are copied, not converted (each array has its fields' dtype), so the bits are those of
``from_numpy`` / ``to_numpy``.
"""

import math

import numpy as np
import taichi as ti
from taichi.lang.util import to_numpy_type

__all__ = ["Group", "put", "take", "put_whole", "entries", "most_entries", "entry_index"]


class Group:
    """Fields of one length (a World's rock arrays, or its tile store) split by dtype: ``reals`` (scalar or
    vector fields of the World's precision) and ``ints`` (scalar i32 fields), each field's first column and
    width (0: a scalar field) in its array."""

    def __init__(self, fields: list, is_real: list, real_np):
        self.reals = tuple(f for f, r in zip(fields, is_real) if r)
        self.ints = tuple(f for f, r in zip(fields, is_real) if not r)
        self.real_np = real_np
        self.order = [(True, self.reals.index(f)) if r else (False, self.ints.index(f))
                      for f, r in zip(fields, is_real)]
        cols, c = [], 0
        for f in self.reals:
            w = f.n if hasattr(f, "n") else 0  # a Vector field has n components, a scalar field none
            cols.append((c, w))
            c += max(w, 1)
        self.real_cols, self.n_real = tuple(cols), max(c, 1)
        self.n_int = max(len(self.ints), 1)

    def arrays(self, rows: int) -> tuple:
        return np.zeros((rows, self.n_real), self.real_np), np.zeros((rows, self.n_int), np.int32)


@ti.kernel
def _copy(reals: ti.template(), cols: ti.template(), ints: ti.template(), r: ti.types.ndarray(ndim=2),
          k: ti.types.ndarray(ndim=2), n: ti.i32, into_fields: ti.i32):
    """The first ``n`` rows: the arrays into the fields if ``into_fields``, else the fields into the arrays. The
    direction is an argument, not a template: one compile serves both."""
    for i in range(n):
        for f in ti.static(range(len(reals))):
            c, w = ti.static(cols[f][0], cols[f][1])
            for j in ti.static(range(max(w, 1))):
                if into_fields:
                    if ti.static(w > 0):
                        reals[f][i][j] = r[i, c + j]
                    else:
                        reals[f][i] = r[i, c]
                else:
                    if ti.static(w > 0):
                        r[i, c + j] = reals[f][i][j]
                    else:
                        r[i, c] = reals[f][i]
        for f in ti.static(range(len(ints))):
            if into_fields:
                ints[f][i] = k[i, f]
            else:
                k[i, f] = ints[f][i]


def put(g: Group, arrays: list, rows: int) -> None:
    """``arrays`` (one per field of ``g``, in the order the group was given, each of ``rows`` rows and its
    field's dtype) into the first ``rows`` entries of the fields."""
    r, k = g.arrays(rows)
    for (real, j), a in zip(g.order, arrays):
        if real:
            c, w = g.real_cols[j]
            r[:, c:c + max(w, 1)] = np.asarray(a).reshape(rows, max(w, 1))
        else:
            k[:, j] = a
    _copy(g.reals, g.real_cols, g.ints, r, k, rows, 1)


def take(g: Group, rows: int) -> list:
    """The first ``rows`` entries of every field of ``g``, one array per field in the order the group was
    given (vector fields ``(rows, n)``, scalar ones ``(rows,)``)."""
    r, k = g.arrays(rows)
    if rows:
        _copy(g.reals, g.real_cols, g.ints, r, k, rows, 0)
    out = []
    for real, j in g.order:
        if real:
            c, w = g.real_cols[j]
            out.append(r[:, c:c + w].copy() if w else r[:, c].copy())
        else:
            out.append(k[:, j].copy())
    return out


def _element(f) -> tuple:
    """The shape of one entry of field ``f``: () a scalar, (n,) a vector, (n, m) a matrix."""
    if not hasattr(f, "n"):
        return ()
    return (f.n,) if getattr(f, "ndim", 2) == 1 else (f.n, f.m)


def put_whole(fields: list, arrays: list, real_np) -> None:
    """Each array into the whole of its field, as ``field.from_numpy(array)`` would: the array's shape is the
    field's shape followed by its entries' (a vector's n, a matrix's n x m); a field holds ``real_np`` values
    (the World's precision) or int32 ones. One launch, one compile per tuple of fields."""
    reals, ints, layout, r_at, k_at = [], [], [], 0, 0
    for f, a in zip(fields, arrays):
        elem = _element(f)
        shape = tuple(f.shape) + elem
        is_int = f.dtype == ti.i32
        if not is_int and np.dtype(to_numpy_type(f.dtype)) != np.dtype(real_np):
            raise ValueError(f"a field of {f.dtype} among fields of {np.dtype(real_np)} values")
        flat = np.ascontiguousarray(a, np.int32 if is_int else real_np)
        if flat.shape != shape:
            raise ValueError(f"an array of shape {flat.shape} for a field of shape {shape}")
        (ints if is_int else reals).append(flat.reshape(-1))
        layout.append((not is_int, k_at if is_int else r_at, elem, int(np.prod(elem, dtype=int))))
        if is_int:
            k_at += flat.size
        else:
            r_at += flat.size
    r = np.concatenate(reals) if reals else np.zeros(1, real_np)
    k = np.concatenate(ints) if ints else np.zeros(1, np.int32)
    _put_whole(tuple(fields), tuple(layout), r, k)


def entries(f) -> int:
    """Entries of field ``f`` (1 for a 0-D field)."""
    return math.prod(f.shape)


def most_entries(fields) -> int:
    """The entries of the largest of ``fields``: the range of a loop that visits every entry of each."""
    return max(entries(f) for f in fields)


@ti.kernel
def _put_whole(fields: ti.template(), layout: ti.template(), r: ti.types.ndarray(ndim=1),
               k: ti.types.ndarray(ndim=1)):
    """Field f's entries, in row-major order, from ``r`` (real) or ``k`` (int32) at its offset (``layout[f]``:
    (real?, offset, entry shape, values per entry)). One parallel loop over the largest field's entries, each
    field taking the entry of that index if it has one: one task to compile, where a loop per field would be a
    task per field, each compiled on its own."""
    for lin in range(ti.static(most_entries(fields))):
        for f in ti.static(range(len(fields))):
            real, at, elem, size = ti.static(layout[f])
            if lin < ti.static(entries(fields[f])):
                I = entry_index(lin, ti.static(tuple(fields[f].shape)))
                base = at + lin * size
                for j in ti.static(range(size)):
                    if ti.static(real):
                        _set(fields[f], I, elem, j, r[base + j])
                    else:
                        _set(fields[f], I, elem, j, k[base + j])


@ti.func
def entry_index(lin, shape: ti.template()):
    """The index of entry ``lin`` (row-major) of a field of ``shape`` (one to three dimensions)."""
    ti.static_assert(1 <= len(shape) <= 3, "entry_index: a field of one to three dimensions")
    if ti.static(len(shape) == 1):
        return ti.Vector([lin])
    elif ti.static(len(shape) == 2):
        return ti.Vector([lin // shape[1], lin % shape[1]])
    else:
        return ti.Vector([lin // (shape[1] * shape[2]), lin // shape[2] % shape[1], lin % shape[2]])


@ti.func
def _set(field: ti.template(), I, elem: ti.template(), j: ti.template(), value):
    """Value j (row-major) of entry I of ``field``, whose entries have shape ``elem``."""
    if ti.static(len(elem) == 0):
        field[I] = value
    elif ti.static(len(elem) == 1):
        field[I][j] = value
    else:
        field[I][j // elem[1], j % elem[1]] = value
