"""engine/transfer.py: a group of fields to and from NumPy in one launch each way gives the bits of Taichi's own
per-field ``from_numpy`` / ``to_numpy``, in both precisions, for vector and scalar fields, any order of dtypes,
part of the rows, and values that a conversion would change (f32 subnormals, NaN payloads, extreme ints)."""

import numpy as np
import pytest
import taichi as ti

from taichi_rocks.engine import transfer

pytestmark = pytest.mark.usefixtures("taichi_cpu")

ROWS = 37


def _fields(real):
    # real and int fields interleaved, as a World's declaration orders them
    return [ti.Vector.field(3, real, ROWS), ti.field(ti.i32, ROWS), ti.field(real, ROWS),
            ti.Vector.field(4, real, ROWS), ti.field(ti.i32, ROWS)]


def _arrays(np_real, rng):
    pos = rng.normal(0, 1e6, (ROWS, 3)).astype(np_real)
    pos[0] = [np.finfo(np_real).tiny / 4, -0.0, np.finfo(np_real).max]  # a subnormal, a signed zero, the max
    ids = rng.integers(-2 ** 31, 2 ** 31 - 1, ROWS, dtype=np.int64).astype(np.int32)
    ids[:2] = [-2 ** 31, 2 ** 31 - 1]
    rad = rng.uniform(0.01, 0.1, ROWS).astype(np_real)
    quat = rng.normal(size=(ROWS, 4)).astype(np_real)
    phase = rng.integers(0, 3, ROWS).astype(np.int32)
    return [pos, ids, rad, quat, phase]


@pytest.mark.parametrize("real, np_real", [(ti.f32, np.float32), (ti.f64, np.float64)], ids=["f32", "f64"])
def test_put_and_take_are_from_numpy_and_to_numpy(real, np_real):
    rng = np.random.default_rng(7)
    mine, theirs = _fields(real), _fields(real)
    is_real = [True, False, True, True, False]
    g = transfer.Group(mine, is_real, np_real)
    arrays = _arrays(np_real, rng)
    transfer.put(g, arrays, ROWS)
    for f, a in zip(theirs, arrays):
        f.from_numpy(a)
    for f, t, a in zip(mine, theirs, arrays):
        got = f.to_numpy()
        assert got.dtype == a.dtype and got.tobytes() == t.to_numpy().tobytes() == a.tobytes()
    # taken back: every row, then part of them (the first m entries, as read_listed asks)
    for m in (ROWS, 5, 0):
        back = transfer.take(g, m)
        assert len(back) == len(arrays)
        for b, a in zip(back, arrays):
            assert b.shape == a[:m].shape and b.dtype == a.dtype and b.tobytes() == a[:m].tobytes()
    # a put of the first rows leaves the others as they were
    fresh = _arrays(np_real, np.random.default_rng(8))
    transfer.put(g, [a[:4] for a in fresh], 4)
    for f, a, b in zip(mine, arrays, fresh):
        got = f.to_numpy()
        assert got[:4].tobytes() == b[:4].tobytes() and got[4:].tobytes() == a[4:].tobytes()


def test_group_columns():
    g = transfer.Group(_fields(ti.f32), [True, False, True, True, False], np.float32)
    assert g.real_cols == ((0, 3), (3, 0), (4, 4)) and g.n_real == 8 and g.n_int == 2
    assert g.order == [(True, 0), (False, 0), (True, 1), (True, 2), (False, 1)]


@pytest.mark.parametrize("real, np_real", [(ti.f32, np.float32), (ti.f64, np.float64)], ids=["f32", "f64"])
def test_put_whole_is_from_numpy_on_every_kind_of_field(real, np_real):
    """Scalars, vectors and matrices of one, two and three dimensions, real and int32, in one launch: the bits
    of from_numpy, every entry in its place (values unique per entry: a misplaced one shows)."""
    rng = np.random.default_rng(11)
    make = [lambda: ti.field(ti.i32, 5), lambda: ti.Vector.field(2, ti.i32, 4), lambda: ti.Vector.field(6, real, 3),
            lambda: ti.field(real, (3, 6, 4)), lambda: ti.field(ti.i32, (2, 6, 2)), lambda: ti.field(real, 7),
            lambda: ti.Matrix.field(2, 3, real, (2, 3))]
    mine, theirs = [m() for m in make], [m() for m in make]
    arrays = []
    for f in mine:
        shape = tuple(f.shape) + transfer._element(f)
        if f.dtype == ti.i32:
            arrays.append(rng.permutation(np.arange(-10_000, 10_000))[:int(np.prod(shape))].reshape(shape).astype(np.int32))
        else:
            a = rng.normal(0, 1e3, shape).astype(np_real)
            a.flat[0] = -0.0
            arrays.append(a)
    transfer.put_whole(mine, arrays, np_real)
    for f, t, a in zip(mine, theirs, arrays):
        t.from_numpy(a)
        got = f.to_numpy()
        assert got.shape == a.shape and got.dtype == a.dtype and got.tobytes() == a.tobytes() == t.to_numpy().tobytes()
    with pytest.raises(ValueError, match="shape"):
        transfer.put_whole(mine[:1], [np.zeros(4, np.int32)], np_real)
    other = np.float64 if np_real == np.float32 else np.float32  # a real field of the other precision
    with pytest.raises(ValueError, match="values"):
        transfer.put_whole(mine[5:6], [arrays[5]], other)
