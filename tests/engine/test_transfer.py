"""engine/transfer.py: whole fields from NumPy in one launch give the bits of Taichi's own per-field
``from_numpy``, in both precisions, for every kind of field. (A World's fields: tests/engine/test_worlddata.py.)"""

import numpy as np
import pytest
import taichi as ti

from taichi_rocks.engine import transfer

pytestmark = pytest.mark.usefixtures("taichi_cpu")


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
