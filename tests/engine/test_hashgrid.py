"""Cell mapping, Teschner hash, hash build and DDA against NumPy references (incl. adversarial inputs)."""

import itertools

import numpy as np
import pytest
import taichi as ti

from harness import Probe, np_cell, np_hash
from taichi_rocks.engine import hashgrid

pytestmark = pytest.mark.usefixtures("taichi_cpu")


@pytest.fixture(scope="module")
def cell_kernels(taichi_cpu):
    n = 16384
    pts = ti.Vector.field(3, ti.f32, shape=n)
    cells = ti.Vector.field(3, ti.i32, shape=n)
    slots = ti.field(ti.i32, shape=n)

    @ti.kernel
    def run(l: ti.f32, table: ti.i32, m: ti.i32):
        for i in range(m):
            c = hashgrid.cell_of(pts[i], l)
            cells[i] = c
            slots[i] = hashgrid.hash_cell(c, table)

    def call(p, l, table):
        p = np.asarray(p, np.float32)
        buf = np.zeros((n, 3), np.float32)
        buf[: len(p)] = p
        pts.from_numpy(buf)
        run(l, table, len(p))
        return cells.to_numpy()[: len(p)].astype(np.int64), slots.to_numpy()[: len(p)].astype(np.int64)

    return call


def adversarial_points(l, rng):
    k = np.arange(-20, 21)
    on_boundaries = np.stack(np.meshgrid(k * l, k * l, [0.0, -l, l]), -1).reshape(-1, 3)
    near = on_boundaries[:200] + np.float32(1e-6)
    huge = rng.uniform(-1, 1, (300, 3)) * np.array([1e6, 1e7, 1e4])
    neg = -rng.uniform(0, 50, (300, 3))
    return np.concatenate([on_boundaries, near, huge, neg, rng.normal(0, 30, (500, 3))])


@pytest.mark.parametrize("l", [0.015, 0.1, 0.25, 1.0])
@pytest.mark.parametrize("table", [1, 7, 1_000_003, 2**31 - 1])
def test_cell_and_hash_match_numpy(cell_kernels, l, table):
    rng = np.random.default_rng(1)
    p = adversarial_points(l, rng).astype(np.float32)
    cells, slots = cell_kernels(p, l, table)
    np.testing.assert_array_equal(cells, np_cell(p, l))
    np.testing.assert_array_equal(slots, np_hash(np_cell(p, l), table))
    assert slots.min() >= 0 and slots.max() < table


def test_hash_wraps_in_32_bits():
    # cells whose products overflow 32 bits, and negative cells (two's complement)
    c = np.array([[2**20, -(2**20), 12345678], [-1, -1, -1], [0, 0, 0]])
    expected = [((x * 73856093) & 0xFFFFFFFF) ^ ((y * 19349663) & 0xFFFFFFFF) ^ ((z * 83492791) & 0xFFFFFFFF)
                for x, y, z in c.tolist()]
    np.testing.assert_array_equal(np_hash(c, 1_000_003), np.array(expected) % 1_000_003)


def rocks(rng, n, spread, r_range):
    pos = rng.uniform(-spread, spread, (n, 3))
    r = rng.uniform(*r_range, n)
    return pos, r


@pytest.mark.parametrize("insert", ["aabb", "center"])
@pytest.mark.parametrize("table", [None, 1, 13])
def test_build_lists_every_rock_in_every_cell(insert, table):
    rng = np.random.default_rng(2)
    l = 0.1
    pos, r = rocks(rng, 300, 1.0, (0.05, 0.1))
    pos[:20] = np.round(pos[:20] / l) * l  # centres exactly on cell corners
    probe = Probe(pos, r, cell=l, insert=insert, table=table)
    members = probe.slot_members()
    pos32 = pos.astype(np.float32)
    for i in range(len(pos)):
        if insert == "center":
            cells = [np_cell(pos32[i], l)]
        else:
            lo = np_cell(pos32[i] - np.float32(r[i]), l)
            hi = np_cell(pos32[i] + np.float32(r[i]), l)
            cells = list(itertools.product(*(range(a, b + 1) for a, b in zip(lo, hi))))
        for c in cells:
            assert i in members[int(np_hash(np.array(c), probe.table))]
    total = sum(len(v) for v in members.values())
    assert probe.total >= len(pos)
    if insert == "center":
        assert total == len(pos)


def brute_cells(a, b, l, tol):
    """Cells whose box, grown by tol (negative: shrunk), the segment a-b intersects (slab test, f64)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    lo = np.floor(np.minimum(a, b) / l).astype(int) - 1
    hi = np.floor(np.maximum(a, b) / l).astype(int) + 1
    out = set()
    d = b - a
    for c in itertools.product(*(range(x, y + 1) for x, y in zip(lo, hi))):
        bmin = np.array(c) * l - tol
        bmax = (np.array(c) + 1) * l + tol
        t0, t1 = 0.0, 1.0
        ok = True
        for ax in range(3):
            if abs(d[ax]) < 1e-300:
                if not (bmin[ax] <= a[ax] <= bmax[ax]):
                    ok = False
                    break
            else:
                u0, u1 = sorted(((bmin[ax] - a[ax]) / d[ax], (bmax[ax] - a[ax]) / d[ax]))
                t0, t1 = max(t0, u0), min(t1, u1)
        if ok and t0 <= t1:
            out.add(tuple(c))
    return out


def dda_cells(segments, l):
    rays = np.asarray(segments, np.float64)
    probe = Probe(np.zeros((1, 3)), [0.01], cell=l, rays=rays)
    probe.set_rays(rays, rays)
    from taichi_rocks.engine import tires
    tires.trace_rays(probe.w)
    counts = probe.w.ray_cell_count.to_numpy()
    cells = probe.w.ray_cells.to_numpy()
    return [[tuple(c) for c in cells[k, :counts[k]]] for k in range(len(rays))]


def segment_cases(rng, l):
    cases = [
        [[0.05, 0.05, 0.33], [0.05, 0.05, 0.0]],  # vertical tire ray
        [[0.1, 0.1, 0.3], [0.1, 0.1, 0.0]],  # along a cell edge
        [[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]],  # through corners
        [[-0.35, 0.02, -0.1], [0.45, 0.02, -0.1]],  # axis-parallel, negative start
        [[0.2, -0.3, 0.0], [0.2, -0.3, 0.0]],  # zero length
        [[-1.0, -1.0, 0.5], [-1.2, -0.7, 0.0]],
        [[0.3, 0.15, 0.1], [-0.2, 0.15, 0.1]],  # on a face plane, reversed
    ]
    for _ in range(40):
        a = rng.uniform(-1, 1, 3)
        b = a + rng.normal(0, 0.3, 3)
        cases.append([a, b])
    return np.array(cases)


@pytest.mark.parametrize("l", [0.1, 0.03])
def test_dda_matches_brute_force_cells(l):
    rng = np.random.default_rng(3)
    segs = segment_cases(rng, l)
    for (a, b), got in zip(segs, dda_cells(segs, l)):
        got = set(got)
        must = brute_cells(a, b, l, -1e-5 * l)  # cells the segment clearly crosses
        may = brute_cells(a, b, l, 1e-4 * l)  # cells it touches within rounding
        assert must <= got, (a, b, must - got)
        assert got <= may, (a, b, got - may)
        assert tuple(np_cell(a, l)) in got and tuple(np_cell(b, l)) in got


# the hash's prefix sum, serial (the CPU's) and over blocks (off the CPU), against NumPy: table sizes on and
# around the block edges of each level (32, 32^2, 32^3), counts with zeros, ones and one crowded slot
@pytest.mark.parametrize("parallel", [False, True])
def test_scan_matches_numpy_at_block_edges(parallel):
    from taichi_rocks.engine.world import MAX_OCC, World, scan_level_sizes

    rng = np.random.default_rng(5)
    for table in (1, 2, 31, 32, 33, 1023, 1024, 1025, 32769):
        w = World(4, ti.f32, hash_table=table, hash_entries=4, parallel_scan=parallel)
        assert w.scan_levels == (len(scan_level_sizes(table)) if parallel else 0)
        for counts in (rng.integers(0, 4, table), np.zeros(table, np.int64), np.eye(1, table, table // 2)[0] * 1000):
            before = np.concatenate([counts, [7]]).astype(np.int32)  # the slot past the table: overwritten
            w.cell_start.from_numpy(before)
            total = hashgrid.inclusive_scan(w)
            got = w.cell_start.to_numpy()
            want = np.cumsum(counts)
            np.testing.assert_array_equal(got[:table], want, err_msg=f"table {table}")
            assert got[table] == want[-1] == total
            assert w.tire_counts[MAX_OCC] == counts.max()
