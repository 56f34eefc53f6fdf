"""Whole Taichi fields from NumPy in one launch (the renderer's fields: render/vehicles.py).

Taichi compiles ``field.from_numpy`` once per field (the field is a template argument of its copy kernel):
:func:`put_whole` writes whole fields of any shapes and element kinds (scalars, vectors, matrices) from their
arrays in one launch, one compile per tuple of fields instead of one per field. (A World's data are ndarrays,
read and written through engine/worlddata.py ``HostField``.)

The values are copied, not converted (each array has its fields' dtype), so the bits are those of
``from_numpy``.
"""

import math

import numpy as np
import taichi as ti
from taichi.lang.util import to_numpy_type

__all__ = ["put_whole", "entries", "most_entries", "entry_index"]


def _element(f) -> tuple:
    """The shape of one entry of field ``f``: () a scalar, (n,) a vector, (n, m) a matrix."""
    if not hasattr(f, "n"):
        return ()
    return (f.n,) if getattr(f, "ndim", 2) == 1 else (f.n, f.m)


def put_whole(fields: list, arrays: list, real_np) -> None:
    """Each array into the whole of its field, as ``field.from_numpy(array)`` would: the array's shape is the
    field's shape followed by its entries' (a vector's n, a matrix's n x m); a field holds ``real_np`` values
    or int32 ones. One launch, one compile per tuple of fields."""
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
