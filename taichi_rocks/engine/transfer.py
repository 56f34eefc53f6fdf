"""Many fields to and from NumPy in one launch each way (engine/rocks.py's reads and writes of the rock fields).

Taichi compiles ``field.from_numpy`` and ``field.to_numpy`` once per field (the field is a template argument of
its copy kernel): a World's six to nine saved rock fields cost about 40 ms of compiling each way and field,
about 0.5 s a World on a 2-core CPU. Here a group of fields travels as two 2-D arrays, the real fields' components
side by side in columns of one array of the World's precision and the i32 fields in one int32 array, through one
kernel for both directions: one compile a World and group (about 60 ms), and one launch instead of one per field.

The values are copied, not converted (each array has its fields' dtype), so the bits are those of
``from_numpy`` / ``to_numpy``.
"""

import numpy as np
import taichi as ti

__all__ = ["Group", "put", "take"]


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
