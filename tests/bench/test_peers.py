"""The benchmark's peers (bench/peers.py) find what a plain segment-sphere test finds: NVIDIA Warp's HashGrid
query (warp-lang is in the test extra: without it this fails) and SciPy's cKDTree, against a float64
brute force written here, on random rocks and on rocks placed tangent to a ray, just inside and just outside."""

import numpy as np
import pytest

from taichi_rocks.bench import peers  # the one import of the module under test


def _reference(pos, rad, rays) -> np.ndarray:
    """Rocks within r of any segment a -> b, in float64 from the float32 inputs (closest point on the segment)."""
    pos, rad, rays = (np.asarray(x, np.float64) for x in (pos, rad, rays))
    hit = np.zeros(len(pos), bool)
    for a, b in rays:
        d = b - a
        t = np.clip((pos - a) @ d / (d @ d), 0.0, 1.0)
        hit |= np.linalg.norm(pos - (a + t[:, None] * d), axis=1) <= rad
    return np.flatnonzero(hit)


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(21)
    n = 30_000
    rad = rng.uniform(0.015, 0.05, n)
    pos = np.column_stack([rng.uniform(-3.0, 3.0, (n, 2)), rad])
    rays = [[[x, y, 0.33], [x + dx, y, 0.0]] for (x, y), dx in zip(rng.uniform(-2.5, 2.5, (10, 2)),
                                                                   rng.uniform(-0.05, 0.05, 10))]
    rays = np.array(rays)
    # adversarial rocks at the first ray's foot: tangent-ish just inside, and just outside (1 mm)
    a, b = rays[0]
    side = np.array([1.0, 0.0, 0.0])
    foot = a + 0.9 * (b - a)
    pos[:2] = [foot + 0.0299 * side, foot + 0.0311 * side]
    rad[:2] = 0.03
    pos, rad, rays = (np.ascontiguousarray(x, np.float32) for x in (pos, rad, rays))
    ref = _reference(pos, rad, rays)
    assert 0 in ref and 1 not in ref and len(ref) > 30
    return pos, rad, rays, ref


def test_numpy_brute_force_and_kdtree_match_the_reference(case):
    pos, rad, rays, ref = case
    np.testing.assert_array_equal(np.flatnonzero(peers.numpy_brute(pos, rad, rays)), ref)
    np.testing.assert_array_equal(np.sort(peers.kdtree_query(pos, rad, rays, float(rad.max()))), ref)


def test_warp_hashgrid_query_matches_the_reference(case):
    pos, rad, rays, ref = case
    warp, info = peers.start_warp(True)
    assert warp is not None and info["available"] and info["device"] == "cpu", info
    warp.prepare(pos, rad, rays, float(rad.max()))
    warp.run()
    np.testing.assert_array_equal(warp.hit_ids(), ref)
    moved = rays + np.float32([0.5, 0.5, 0.0])  # a second launch: only its hits count (the stamp)
    warp.prepare(pos, rad, moved, float(rad.max()))
    warp.run()
    again = _reference(pos, rad, moved)
    assert len(again) > 30 and not np.array_equal(again, ref)
    np.testing.assert_array_equal(warp.hit_ids(), again)


def test_ray_samples_cover_every_touching_sphere():
    """The query radius around the samples reaches every sphere of radius <= r_max touching the segment."""
    rays = np.array([[[0.0, 0.0, 0.33], [0.07, 0.0, 0.0]]])
    pts, m, q = peers.ray_samples(rays, 0.05)
    seg = np.linalg.norm(rays[0, 1] - rays[0, 0])
    assert m == int(np.ceil(seg / 0.05)) and len(pts) == m
    # the farthest a point of the segment is from a sample is half the spacing: a touching sphere's centre
    # is within r_max of the segment, so within r_max + spacing / 2 = q of a sample
    assert q == pytest.approx(0.05 + 0.5 * seg / m)
    t = np.linspace(0.0, 1.0, 2001)
    line = rays[0, 0] + t[:, None] * (rays[0, 1] - rays[0, 0])
    gap = np.min(np.linalg.norm(line[:, None, :] - pts[None].astype(np.float64), axis=2), axis=1).max()
    assert gap <= 0.5 * seg / m + 1e-6
