"""Known-answer values of the counter-based hash (engine/randomness.py), computed independently.

The mixer is C. Wellons' "lowbias32" (hash-prospector): x ^= x >> 16; x *= 0x7feb352d; x ^= x >> 15;
x *= 0x846ca68b; x ^= x >> 16, modulo 2^32. The values below were computed with plain Python integers from
those published constants (the function ``lowbias32`` here, not the module's), and the first steps for x = 1
by hand: 1 -> 1 (1 >> 16 = 0) -> 0x7feb352d -> 0x7feb352d ^ (0x7feb352d >> 15 = 0xffd6) = 0x7febcafb. A change
of constant, shift or chaining in the engine, in its NumPy twin or in both, fails here.
``uniform01(seed, a, b, stream)`` = (h >> 8) / 2^24 with h = mix(mix(mix(mix(seed ^ 0x9e3779b9) ^ a) ^ b)
^ stream), every argument taken modulo 2^32.
"""

import numpy as np
import pytest
import taichi as ti

from taichi_rocks.engine import randomness  # the module under test

M32 = 0xFFFFFFFF

MIX = {0x0: 0x0, 0x1: 0x688990C0, 0x2: 0xD1132181, 0x9E3779B9: 0x01FCE552, 0x12345678: 0xF5E71C96,
       0x80000000: 0xCC4B4124, 0xFFFFFFFF: 0x6768824A}
# (seed, a, b, stream) -> the 24-bit integer h >> 8 (uniform01 = that / 2^24)
UNIFORM = {(0, 0, 0, 0): 4322206, (1, 2, 3, 4): 9374628, (3, 17, 250, 201): 13171733,
           (-1, -1, -1, -1): 7500532, (2 ** 31 - 1, 0, 7, 202): 7216894}


def lowbias32(x: int) -> int:
    x &= M32
    x ^= x >> 16
    x = (x * 0x7FEB352D) & M32
    x ^= x >> 15
    x = (x * 0x846CA68B) & M32
    x ^= x >> 16
    return x


def test_the_table_is_the_published_mixer():
    assert {x: lowbias32(x) for x in MIX} == MIX
    x = 1
    x ^= x >> 16
    x = (x * 0x7FEB352D) & M32
    assert x == 0x7FEB352D and x ^ (x >> 15) == 0x7FEBCAFB  # the hand-computed steps


def test_numpy_twins_give_the_known_answers():
    xs = np.array(list(MIX), np.uint64)
    np.testing.assert_array_equal(randomness.mix32_np(xs), np.array(list(MIX.values()), np.uint32))
    for args, h in UNIFORM.items():
        u = randomness.uniform01_np(*args)
        assert u.dtype == np.float32 and float(u) == h / 2 ** 24, args


def test_kernels_give_the_known_answers(taichi_cpu):
    xs = np.array(list(MIX), np.uint32)
    args = np.array(list(UNIFORM), np.int64).astype(np.int32)
    mixed = ti.ndarray(ti.u32, len(xs))
    unif = ti.ndarray(ti.f32, len(args))

    @ti.kernel
    def run(x: ti.types.ndarray(dtype=ti.u32, ndim=1), a: ti.types.ndarray(dtype=ti.i32, ndim=2),
            m: ti.types.ndarray(dtype=ti.u32, ndim=1), u: ti.types.ndarray(dtype=ti.f32, ndim=1)):
        for i in range(x.shape[0]):
            m[i] = randomness.mix32(x[i])
        for i in range(a.shape[0]):
            u[i] = randomness.uniform01(a[i, 0], a[i, 1], a[i, 2], a[i, 3])

    run(xs, args, mixed, unif)
    np.testing.assert_array_equal(mixed.to_numpy(), np.array(list(MIX.values()), np.uint32))
    np.testing.assert_array_equal(unif.to_numpy(), np.array(list(UNIFORM.values())) / np.float32(2 ** 24))


@pytest.mark.parametrize("stream", [2, 101, 201, 202])
def test_uniform01_is_uniform_and_streams_are_independent(stream):
    """The streams the engine draws from (crescent, launch angle and spread): uniform on [0, 1) by a KS test,
    and uncorrelated between neighbouring streams and rock ids."""
    from scipy.stats import kstest

    ids = np.arange(20000)
    u = randomness.uniform01_np(5, ids, 123, stream).astype(np.float64)
    assert kstest(u, "uniform").pvalue > 1e-3
    v = randomness.uniform01_np(5, ids, 123, stream + 1).astype(np.float64)
    w = randomness.uniform01_np(5, ids + 1, 123, stream).astype(np.float64)
    assert abs(np.corrcoef(u, v)[0, 1]) < 0.03 and abs(np.corrcoef(u, w)[0, 1]) < 0.03
