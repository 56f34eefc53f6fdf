"""Tire rays: segment-sphere and swept tests, hash queries in both insert modes against brute force."""

import numpy as np
import pytest
import taichi as ti

from harness import Probe, np_segment_sphere, segment_sphere_kernel
from taichi_rocks.config.keys import choices

pytestmark = pytest.mark.usefixtures("taichi_cpu")


@pytest.fixture(scope="module")
def seg_kernel(taichi_cpu):
    return segment_sphere_kernel(ti.f64)


def test_segment_sphere_cases(seg_kernel):
    a = np.array([0.0, 0.0, 1.0])
    b = np.array([0.0, 0.0, 0.0])
    r = 0.25
    c = np.array([
        [0.25, 0.0, 0.5],  # exactly tangent to the side
        [0.0, 0.0, 1.25],  # tangent beyond the top end
        [0.0, 0.0, -0.25],  # tangent below the bottom end
        [0.0, 0.0, 0.5],  # centre on the segment (segment inside the sphere)
        [0.0, 0.0, 1.3],  # behind the start
        [0.0, 0.0, -0.3],  # past the end
        [0.2500001, 0.0, 0.5],  # just outside
        [5.0, 5.0, 5.0],  # far
        [0.1, 0.1, 0.9],  # inside
    ])
    got = seg_kernel(a, b, c, np.full(len(c), r))
    ref = np_segment_sphere(a, b, c, np.full(len(c), r))
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(got, [1, 1, 1, 1, 0, 0, 0, 0, 1])
    # zero-length segment = point test
    got0 = seg_kernel(b, b, c, np.full(len(c), r))
    np.testing.assert_array_equal(got0, np_segment_sphere(b, b, c, np.full(len(c), r)))


def test_segment_sphere_random(seg_kernel):
    rng = np.random.default_rng(5)
    m = 4000
    a = rng.normal(0, 1, 3)
    b = a + rng.normal(0, 1, 3)
    c = rng.normal(0, 1.2, (m, 3))
    r = rng.uniform(0.05, 0.6, m)
    got = seg_kernel(a, b, c, r)
    ref = np_segment_sphere(a, b, c, r)
    # disagreements only within rounding of the tangent distance
    bad = np.flatnonzero(got != ref)
    d = b - a
    t = np.clip((c[bad] - a) @ d / (d @ d), 0, 1)
    dist = np.linalg.norm(c[bad] - (a + t[:, None] * d), axis=1)
    assert np.all(np.abs(dist - r[bad]) < 1e-12)
    assert got.sum() > 30 and (~got).sum() > 1000


def bed_rocks(rng, n, radius_range, half=1.0):
    r = rng.uniform(*radius_range, n)
    xy = rng.uniform(-half, half, (n, 2))
    return np.column_stack([xy, r]), r


def brute_hits(pos, r, rays):
    hit = np.zeros(len(pos), bool)
    for a, b in rays:
        hit |= np_segment_sphere(a, b, pos, r)
    return np.flatnonzero(hit)


@pytest.mark.parametrize("cell", ["min_radius", "max_diameter", 0.037])
def test_aabb_and_center_find_the_same_hits_as_brute_force(cell):
    rng = np.random.default_rng(7)
    pos, r = bed_rocks(rng, 6000, (0.015, 0.05), half=0.6)
    # vertical tire rays, one exactly on a cell boundary, one tangent to a rock, one negative
    rays = [[[x, y, 0.33], [x, y, 0.0]] for x, y in rng.uniform(-0.5, 0.5, (12, 2))]
    rays += [[[0.1, 0.2, 0.33], [0.1, 0.2, 0.0]], [[-0.3, -0.45, 0.33], [-0.3, -0.45, 0.0]]]
    rays += [[[-0.2, 0.1, 0.4], [0.3, -0.2, 0.0]]]  # a slanted one
    pos[0] = [0.1 + 0.03, 0.2, 0.03]  # tangent to the ray at (0.1, 0.2): distance = r
    r[0] = 0.03
    pos[1] = [0.1, 0.2 - 0.025, 0.025]
    r[1] = 0.025
    rays = np.array(rays)
    l = {"min_radius": 0.015, "max_diameter": 0.1}.get(cell, cell)
    ref = brute_hits(pos.astype(np.float32).astype(np.float64), r.astype(np.float32).astype(np.float64), rays)
    assert len(ref) > 20
    got_aabb = Probe(pos, r, cell=l, insert="aabb", rays=rays).hits()
    got_center = Probe(pos, r, cell=l, insert="center", rays=rays).hits()
    np.testing.assert_array_equal(got_aabb, got_center)
    np.testing.assert_array_equal(got_aabb, ref)


@pytest.mark.parametrize("table", [1, 2, 10_000_019])
def test_hash_stress_same_hits(table):
    rng = np.random.default_rng(8)
    pos, r = bed_rocks(rng, 2000, (0.02, 0.05), half=0.3)
    rays = np.array([[[x, y, 0.33], [x, y, 0.0]] for x, y in rng.uniform(-0.3, 0.3, (8, 2))])
    ref = brute_hits(pos.astype(np.float32).astype(np.float64), r.astype(np.float32).astype(np.float64), rays)
    for insert in choices("sim.hash.insert"):
        np.testing.assert_array_equal(Probe(pos, r, cell=0.1, insert=insert, table=table, rays=rays).hits(), ref)


def test_all_rocks_in_one_cell():
    """500 rocks in one 0.1 m cell: the ray finds exactly those within r of it, in both insert modes."""
    rng = np.random.default_rng(9)
    pos = np.column_stack([rng.uniform(0.01, 0.09, (500, 2)), np.full(500, 0.02)])
    r = np.full(500, 0.005)
    pos[:3, :2] = [[0.05, 0.05], [0.054, 0.05], [0.05, 0.0465]]  # on the ray, inside r, just inside r
    pos[3, :2] = [0.0556, 0.05]  # just outside r
    assert np.all(np.floor(pos / 0.1) == 0)  # one cell
    rays = np.array([[[0.05, 0.05, 0.33], [0.05, 0.05, 0.0]]])
    # the ray is vertical and spans the rocks' height: a rock is hit iff its centre is within r of it in XY
    p32 = pos.astype(np.float32).astype(np.float64)
    expected = np.flatnonzero(np.hypot(p32[:, 0] - 0.05, p32[:, 1] - 0.05) <= np.float32(0.005))
    assert {0, 1, 2} <= set(expected) and 3 not in expected and len(expected) >= 5
    np.testing.assert_array_equal(brute_hits(p32, r.astype(np.float32).astype(np.float64), rays), expected)
    for insert in choices("sim.hash.insert"):
        np.testing.assert_array_equal(Probe(pos, r, cell=0.1, insert=insert, rays=rays).hits(), expected)


def test_swept_catches_what_the_ray_skips():
    """A fast tire: ray detection at two positions misses rocks in between; swept finds them all."""
    rng = np.random.default_rng(11)
    n = 3000
    pos = np.column_stack([rng.uniform(-0.2, 1.4, n), rng.uniform(-0.1, 0.1, n), np.zeros(n)])
    r = rng.uniform(0.015, 0.03, n)
    pos[:, 2] = r
    prev = np.array([[[0.0, 0.0, 0.33], [0.0, 0.0, 0.0]]])
    cur = np.array([[[1.2, 0.0, 0.33], [1.2, 0.0, 0.0]]])  # 60 m/s at dt = 0.02
    swept = Probe(pos, r, cell=0.1, insert="center", rays=cur, swept=True).hits(prev=prev)
    ray = Probe(pos, r, cell=0.1, insert="center", rays=cur).hits(prev=prev)
    # exact reference: within r of the vertical plane strip x in [0, 1.2], z in [0, 0.33]
    p32 = pos.astype(np.float32).astype(np.float64)
    r32 = r.astype(np.float32).astype(np.float64)
    dx = np.maximum(np.maximum(0.0 - p32[:, 0], p32[:, 0] - 1.2), 0.0)
    dz = np.maximum(np.maximum(0.0 - p32[:, 2], p32[:, 2] - 0.33), 0.0)
    ref = np.flatnonzero(dx ** 2 + p32[:, 1] ** 2 + dz ** 2 <= r32 ** 2)
    assert len(ref) > 30
    np.testing.assert_array_equal(swept, ref)
    assert set(ray) <= set(ref) and len(ray) < len(ref) / 5


def test_swept_oblique_matches_the_exact_distance_to_the_parallelogram():
    """A tire turning (diagonal motion) with a slanted ray: swept detection hits exactly the rocks within r of
    the parallelogram the ray sweeps, whose distance comes from a box-constrained least-squares problem
    (SciPy's lsq_linear: min |u e1 + v e2 - (c - o)| over u, v in [0, 1]), independent of the kernel's
    edge-and-interior construction."""
    from scipy.optimize import lsq_linear

    rng = np.random.default_rng(12)
    n = 2500
    a0, b0 = np.array([0.0, 0.0, 0.33]), np.array([0.05, -0.04, 0.0])  # a ray leaning back and sideways
    move = np.array([0.8, 0.6, 0.0])  # 1 m in one step, 37 degrees off the x axis
    t = rng.uniform(-0.1, 1.1, n)
    pos = np.column_stack([move[0] * t + rng.uniform(-0.15, 0.15, n), move[1] * t + rng.uniform(-0.15, 0.15, n),
                           np.zeros(n)])
    r = rng.uniform(0.015, 0.03, n)
    pos[:, 2] = r
    prev = np.array([[a0, b0]])
    cur = prev + move
    got = Probe(pos, r, cell=0.1, insert="center", rays=cur, swept=True).hits(prev=prev)
    p32 = pos.astype(np.float32).astype(np.float64)
    r32 = r.astype(np.float32).astype(np.float64)
    basis = np.column_stack([move, b0 - a0])
    dist = np.array([np.sqrt(2.0 * lsq_linear(basis, c - a0, bounds=(0.0, 1.0), method="bvls").cost) for c in p32])
    clear = np.abs(dist - r32) > 1e-5  # leave out rocks within f32 rounding of tangent
    expected = np.flatnonzero(dist <= r32)
    assert len(expected) > 100 and n - len(expected) > 500 and clear.mean() > 0.99
    np.testing.assert_array_equal(np.intersect1d(got, np.flatnonzero(clear)), np.intersect1d(expected,
                                                                                               np.flatnonzero(clear)))
