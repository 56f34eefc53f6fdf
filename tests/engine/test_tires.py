"""Tire rays: segment-sphere and swept tests, hash queries in both insert modes against brute force."""

import json
import os
import subprocess
import sys
from pathlib import Path

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


# ----------------------------------------------------------------------------------- the first tire wins
VEL_X, SPIN_COL = 12, 17  # engine/world.py: the wheel's velocity (x), its tread speed


def claimed_by(probe, rays, prev, dead, step):
    """Run the tire pass over ``rays`` (tire t's wheel moving at 100 (t + 1) m/s along x; the ``dead`` tires
    neither move nor spin, so what they find is too slow to launch) and return (the tire that launched each
    given rock, -1: none), read back from the launch velocity (uniform model, 30 degrees: v_x = 100 (t + 1) -
    10 cos 30), and the launch count the pass kept on the device."""
    from taichi_rocks.engine import rocks, tires
    from taichi_rocks.engine.world import LAUNCHED
    from harness import put_rocks

    w = probe.w
    probe.set_rays(prev, rays)
    data = w.ray.to_numpy().astype(np.float64)
    for t in range(len(rays)):
        data[t, VEL_X] = 0.0 if t in dead else 100.0 * (t + 1)
        data[t, SPIN_COL] = 0.0 if t in dead else 10.0
    w.ray.from_numpy(data.astype(w.np_real()))
    put_rocks(w, phase=np.zeros(w.pos.shape[0]), vel=np.zeros((w.pos.shape[0], 3)))
    tires.tire_pass(w, probe.switches, step)
    got = rocks.read_listed(w, w.pos.shape[0])
    tire = np.where(got["hit_step"][: probe.n] == step, np.rint(got["vel"][: probe.n, 0] / 100.0) - 1, -1)
    assert not w.claim.to_numpy().any()  # the claims are clear again for the next pass
    return tire.astype(int), int(w.tire_counts[LAUNCHED])


def first_tire_reference(pos, r, rays, prev, dead, swept):
    """NumPy: each rock's first tire in scene order that hits it and is not dead (float64 tests on the f32
    inputs); also the rocks within rounding of a tire's reach, whose verdict the reference cannot settle, and
    how many tires reach each rock."""
    from scipy.optimize import lsq_linear

    p32 = pos.astype(np.float32).astype(np.float64)
    r32 = r.astype(np.float32).astype(np.float64)
    tire = np.full(len(pos), -1)
    unsure = np.zeros(len(pos), bool)
    under = np.zeros(len(pos), int)  # how many tires reach each rock
    for t in range(len(rays)):
        a1, b1 = rays[t]
        if swept:
            a0, b0 = prev[t]
            basis = np.column_stack([a1 - a0, b0 - a0])
            near = np.flatnonzero(np.linalg.norm(p32[:, :2] - a0[:2], axis=1) < 1.0)
            dist = np.full(len(pos), np.inf)
            dist[near] = [np.sqrt(2.0 * lsq_linear(basis, c - a0, bounds=(0.0, 1.0), method="bvls").cost)
                          for c in p32[near]]
        else:
            d = b1 - a1
            u = np.clip((p32 - a1) @ d / (d @ d), 0.0, 1.0)
            dist = np.linalg.norm(p32 - (a1 + u[:, None] * d), axis=1)
        unsure |= np.abs(dist - r32) < 1e-5
        under += dist <= r32
        if t not in dead:
            tire = np.where((tire < 0) & (dist <= r32), t, tire)
    return tire, unsure, under


@pytest.mark.parametrize("insert,swept", [("center", False), ("aabb", False), ("center", True)])
def test_the_first_tire_in_scene_order_wins_a_rock(insert, swept):
    """Six tires over one patch of rocks, each rock under several of them: the tire pass launches every rock
    the first tire in scene order that can launch it (parallel claims, engine/tires.py launch_all) would, as
    a serial pass does; a tire that finds a rock but throws it too slowly (tires 0 and 3 stand still) leaves
    it to the next. Against NumPy, step after step (the claims must be clear each time), in both insert modes
    and with swept detection."""
    rng = np.random.default_rng(21)
    n = 2500
    r = rng.uniform(0.015, 0.03, n)
    pos = np.column_stack([rng.uniform(-0.12, 0.12, (n, 2)), r])
    xy = rng.uniform(-0.04, 0.04, (6, 2))  # six rays a few centimetres apart: their reaches overlap
    rays = np.array([[[x, y, 0.33], [x + 0.01, y, 0.0]] for x, y in xy])
    prev = rays - np.array([0.05, 0.02, 0.0]) if swept else rays
    dead = (0, 3)
    probe = Probe(pos, r, cell=0.05, insert=insert, rays=rays, swept=swept)
    ref, unsure, under = first_tire_reference(pos, r, rays, prev, dead, swept)
    sure = ~unsure
    won = [np.count_nonzero(ref == t) for t in range(6)]
    assert unsure.mean() < 0.01 and min(won[t] for t in (1, 2, 4, 5)) > 0 and won[0] == won[3] == 0
    assert np.count_nonzero(under >= 2) > 50 and np.count_nonzero(under >= 3) > 10  # contested rocks
    for step in (1, 2):
        got, launched = claimed_by(probe, rays, prev, dead, step)
        np.testing.assert_array_equal(got[sure], ref[sure])
        assert launched == np.count_nonzero(got >= 0)


def test_first_tire_wins_a_rock_many_tires_share():
    """Every rock under all 40 tires (one vertical ray repeated): the first live tire launches each one; with
    tires 0..k dead, tire k + 1 does. Many threads claim the same rocks at once."""
    rng = np.random.default_rng(22)
    n = 300
    r = np.full(n, 0.03)
    pos = np.column_stack([rng.uniform(-0.02, 0.02, (n, 2)), r])
    rays = np.tile(np.array([[[0.0, 0.0, 0.33], [0.0, 0.0, 0.0]]]), (40, 1, 1))
    probe = Probe(pos, r, cell=0.05, rays=rays)
    for step, first in enumerate((0, 1, 17, 39), start=1):
        got, launched = claimed_by(probe, rays, rays, tuple(range(first)), step)
        np.testing.assert_array_equal(got, np.full(n, first))
        assert launched == n


def shared_rocks_case(rng_seed=23):
    """Rocks under six rays a few centimetres apart (the reaches overlap), tires 0 and 3 dead (see above)."""
    rng = np.random.default_rng(rng_seed)
    n = 2500
    r = rng.uniform(0.015, 0.03, n)
    pos = np.column_stack([rng.uniform(-0.12, 0.12, (n, 2)), r])
    xy = rng.uniform(-0.04, 0.04, (6, 2))
    rays = np.array([[[x, y, 0.33], [x + 0.01, y, 0.0]] for x, y in xy])
    return pos, r, rays, (0, 3)


def test_the_first_tire_wins_on_vulkan():
    """The same claims on Vulkan (lavapipe; its tire pass takes one place of a slot per item, engine/tires.py
    places_one_per_item), in a process of its own started there: the NumPy reference's winners, with centre
    insertion ("aabb" insertion loses rocks in the hash's count on Vulkan, an atomic in a loop over each rock's
    cells: 336 of 340 hits here, with the serial tire pass too). No skip: a machine without a Vulkan driver fails
    here (the driver says so)."""
    here = Path(__file__).resolve()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(here.parents[2]), str(here.parents[1])]))  # harness
    run = subprocess.run([sys.executable, __file__, "vulkan"], capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(run.stdout.strip().splitlines()[-1])
    assert got["arch"] == "vulkan"
    pos, r, rays, dead = shared_rocks_case()
    ref, unsure, under = first_tire_reference(pos, r, rays, rays, dead, False)
    assert np.count_nonzero(under >= 2) > 50
    tire = np.array(got["tire"])
    np.testing.assert_array_equal(tire[~unsure], ref[~unsure])
    assert got["launched"] == np.count_nonzero(tire >= 0) > 100


def _claims_on(arch: str) -> int:
    """The Vulkan side of test_the_first_tire_wins_on_vulkan: one JSON line (arch, the winners, the launch
    count)."""
    from taichi_rocks.engine.runtime import init_taichi

    used = init_taichi(arch)
    out = {"arch": used}
    if used == arch:
        pos, r, rays, dead = shared_rocks_case()
        tire, launched = claimed_by(Probe(pos, r, cell=0.05, rays=rays), rays, rays, dead, 1)
        out.update(tire=tire.tolist(), launched=launched)
    print(json.dumps(out))
    return 0 if used == arch else 1


if __name__ == "__main__":
    sys.exit(_claims_on(sys.argv[1]))
