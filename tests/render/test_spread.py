"""render/kernels.py spread_stride: the order the parallel loops visit rows and tiles in is a permutation."""

import math

import pytest

from taichi_rocks.render.kernels import spread_stride


@pytest.mark.parametrize("n", [1, 2, 3, 8, 180, 240, 360, 720, 1080, 1081, 2160, 7919])
def test_every_index_once_and_runs_spread(n):
    k = spread_stride(n)
    order = [(q * k) % n for q in range(n)]
    assert sorted(order) == list(range(n))
    assert math.gcd(k, n) == 1
    if n >= 64:  # a run of a tenth of the range reaches across most of it
        run = order[: n // 10]
        assert max(run) - min(run) > 0.8 * n
        assert abs(k / n - 0.618) < 0.02
