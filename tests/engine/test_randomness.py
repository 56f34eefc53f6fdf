"""The counter-based hash (engine/randomness.py): its NumPy twins equal the Taichi functions bit for bit."""

import numpy as np


def test_numpy_twins_equal_the_kernels(taichi_cpu):
    import taichi as ti

    from taichi_rocks.engine.randomness import mix32, mix32_np, uniform01, uniform01_np

    rng = np.random.default_rng(7)
    n = 4096
    xs = np.concatenate([[0, 1, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF],
                         rng.integers(0, 2 ** 32, n - 5, dtype=np.uint64)]).astype(np.uint32)
    args = rng.integers(-2 ** 31, 2 ** 31, (n, 4), dtype=np.int64).astype(np.int32)
    args[:8] = [[0, 0, 0, 0], [-1, -1, -1, -1], [1, 2, 3, 4], [2 ** 31 - 1, 0, 7, 201], [5, -7, 11, 101],
                [0, 1, 0, 1], [99, 2 ** 31 - 1, -2 ** 31, 3], [12, 34, 56, 78]]
    mixed = ti.ndarray(ti.u32, n)
    unif = ti.ndarray(ti.f32, n)

    @ti.kernel
    def run(x: ti.types.ndarray(dtype=ti.u32, ndim=1), a: ti.types.ndarray(dtype=ti.i32, ndim=2),
            m: ti.types.ndarray(dtype=ti.u32, ndim=1), u: ti.types.ndarray(dtype=ti.f32, ndim=1)):
        for i in range(x.shape[0]):
            m[i] = mix32(x[i])
            u[i] = uniform01(a[i, 0], a[i, 1], a[i, 2], a[i, 3])

    run(xs, args, mixed, unif)
    want_mix = mixed.to_numpy()
    assert len(np.unique(want_mix)) > n - 4  # a hash, not a constant: the comparison below means something
    np.testing.assert_array_equal(mix32_np(xs), want_mix)
    np.testing.assert_array_equal(mix32_np(xs.astype(np.int64)), want_mix)  # any integer type, modulo 2^32
    assert int(mix32_np(int(xs[7]))) == int(want_mix[7])  # scalars too
    want_u = unif.to_numpy()
    assert 0.0 <= want_u.min() and want_u.max() < 1.0 and want_u.std() > 0.2
    got_u = uniform01_np(args[:, 0], args[:, 1], args[:, 2], args[:, 3])
    assert got_u.dtype == np.float32
    np.testing.assert_array_equal(got_u, want_u)
