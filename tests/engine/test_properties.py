"""Property tests (hypothesis) of the geometry kernels, with NumPy as the oracle.

cell_of / hash_cell against np_cell / np_hash (points on and next to cell boundaries, negative and huge
values, any table size), the DDA's cell list against a brute-force slab test of every cell, the
segment-sphere test against np_segment_sphere (f64 and f32), and the hits of a hash built in both insert
modes against brute force. Each Taichi kernel is compiled once per module (module fixtures; probes are
reloaded with new rocks, rays and cell sizes); examples are derandomized so CI runs are reproducible.
"""

import numpy as np
import pytest
import taichi as ti
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness import Probe, np_cell, np_hash, np_segment_sphere, segment_sphere_kernel
from scenes_util import reload_probe
from taichi_rocks.config.keys import choices
from taichi_rocks.engine import hashgrid, tires
from test_hashgrid import brute_cells, cell_kernels  # noqa: F401  (cell_kernels: module fixture)
from test_tires import seg_kernel  # noqa: F401  (module fixture: f64 segment-sphere kernel)

pytestmark = pytest.mark.usefixtures("taichi_cpu")

SETTINGS = dict(deadline=None, derandomize=True, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
F32_EPS = float(np.finfo(np.float32).eps)
CELLS = [0.015, 0.03, 0.0625, 0.1, 0.25, 1.0]


def f32(x):
    return np.asarray(x, np.float32).astype(np.float64)


# ------------------------------------------------------------------------------------------ strategies
@st.composite
def coordinate(draw, l):
    """A float32 coordinate: anywhere (incl. huge and negative), on a cell boundary k * l, or one float32
    step beside one."""
    kind = draw(st.sampled_from(["any", "huge", "boundary", "beside"]))
    if kind == "any":
        return float(draw(st.floats(-1e3, 1e3, width=32)))
    if kind == "huge":
        return float(draw(st.floats(-2e6, 2e6, width=32)))  # |x / l| < 2^31 for l >= 0.001
    k = draw(st.integers(-10**6, 10**6))
    x = np.float32(k) * np.float32(l)
    if kind == "beside":
        x = np.nextafter(x, np.float32(draw(st.sampled_from([-np.inf, np.inf]))))
    return float(x)


@st.composite
def points_and_cell(draw, max_size=64):
    l = draw(st.sampled_from(CELLS) | st.floats(0.001, 4.0))
    pts = draw(st.lists(st.tuples(coordinate(l), coordinate(l), coordinate(l)), min_size=1, max_size=max_size))
    return np.array(pts, np.float32), float(np.float32(l))


TABLES = st.sampled_from([1, 2, 7, 97, 1_000_003, 2**31 - 1]) | st.integers(1, 2**31 - 1)
INT32 = st.integers(-(2**31), 2**31 - 1)


@st.composite
def segment(draw, l, max_len=1.0):
    """A segment near the origin: endpoints anywhere or snapped to cell boundaries, directions along an
    axis, along a face, through corners (equal steps per axis) or any; sometimes of zero length."""
    a = np.array([draw(st.floats(-2.0, 2.0, width=32)) for _ in range(3)])
    snap = draw(st.lists(st.booleans(), min_size=3, max_size=3))
    a = np.where(snap, np.round(a / l) * l, a)
    kind = draw(st.sampled_from(["any", "axis", "face", "diagonal", "zero"]))
    size = draw(st.floats(0.0, max_len / 2.0))
    signs = np.array(draw(st.lists(st.sampled_from([-1.0, 1.0]), min_size=3, max_size=3)))
    if kind == "any":
        d = np.array([draw(st.floats(-1.0, 1.0)) for _ in range(3)])
        d *= size / max(np.linalg.norm(d), 1e-12)
    elif kind == "axis":
        d = np.zeros(3)
        d[draw(st.integers(0, 2))] = size
    elif kind == "face":
        d = np.array([draw(st.floats(-1.0, 1.0)) for _ in range(3)])
        d[draw(st.integers(0, 2))] = 0.0
        d *= size / max(np.linalg.norm(d), 1e-12)
    elif kind == "diagonal":
        d = signs * (np.round(size / l) * l)
    else:
        d = np.zeros(3)
    return f32(a), f32(a + d)


# ------------------------------------------------------------------------------------------ cells and hash
@pytest.fixture(scope="module")
def hash_kernel(taichi_cpu):
    n = 256
    cells = ti.Vector.field(3, ti.i32, shape=n)
    slots = ti.field(ti.i32, shape=n)

    @ti.kernel
    def run(table: ti.i32, m: ti.i32):
        for i in range(m):
            slots[i] = hashgrid.hash_cell(cells[i], table)

    def call(c, table):
        buf = np.zeros((n, 3), np.int32)
        buf[: len(c)] = c
        cells.from_numpy(buf)
        run(table, len(c))
        return slots.to_numpy()[: len(c)].astype(np.int64)

    return call


@settings(max_examples=100, **SETTINGS)
@given(data=points_and_cell(), table=TABLES)
def test_cell_and_hash_of_points_match_numpy(cell_kernels, data, table):
    pts, l = data
    cells, slots = cell_kernels(pts, l, table)
    ref = np_cell(pts, l)
    np.testing.assert_array_equal(cells, ref)
    np.testing.assert_array_equal(slots, np_hash(ref, table))
    assert np.all((0 <= slots) & (slots < table))


@settings(max_examples=100, **SETTINGS)
@given(cells=st.lists(st.tuples(INT32, INT32, INT32), min_size=1, max_size=256), table=TABLES)
def test_hash_of_any_int32_cell_matches_numpy(hash_kernel, cells, table):
    c = np.array(cells, np.int64)
    slots = hash_kernel(c.astype(np.int32), table)
    np.testing.assert_array_equal(slots, np_hash(c, table))
    assert np.all((0 <= slots) & (slots < table))


# ------------------------------------------------------------------------------------------ DDA
MAX_RAYS = 8


@pytest.fixture(scope="module")
def dda_probe(taichi_cpu):
    rays = np.zeros((MAX_RAYS, 2, 3))
    rays[:, 0, 2] = 1.05  # sizes the ray-cell buffers for segments up to 1.05 m at cells >= 0.03
    return Probe(np.zeros((1, 3)), [0.01], cell=0.03, rays=rays)


def traced_cells(probe, segs, l):
    reload_probe(probe, np.zeros((1, 3)), [0.01], segs, cell=l)
    probe.set_rays(probe.rays, probe.rays)
    tires.trace_rays(probe.w)
    counts = probe.w.ray_cell_count.to_numpy()
    cells = probe.w.ray_cells.to_numpy()
    return [[tuple(c) for c in cells[k, :counts[k]]] for k in range(len(segs))]


@st.composite
def segments_and_cell(draw):
    l = draw(st.sampled_from([0.03, 0.0625, 0.1, 0.25]))
    segs = draw(st.lists(segment(l), min_size=1, max_size=MAX_RAYS))
    return np.array(segs), l


@settings(max_examples=80, **SETTINGS)
@given(data=segments_and_cell())
def test_dda_cells_match_brute_force(dda_probe, data):
    """Every cell the segment clearly crosses is listed, and nothing farther than the documented near-tie
    tolerance (TIE_EPS = 1e-5 of the segment's parameter, plus float32 rounding) from it; both end cells
    are listed, no cell twice in a row, and the list fits the engine's ray_capacity bound."""
    segs, l = data
    for (a, b), got in zip(segs, traced_cells(dda_probe, segs, l)):
        length = float(np.linalg.norm(b - a))
        assert len(got) <= hashgrid.ray_capacity(length, l), (a, b, len(got))
        cells = set(got)
        must = brute_cells(a, b, l, -1e-5 * l)
        may = brute_cells(a, b, l, 1e-4 * l + 2e-5 * length)
        assert must <= cells, (a, b, l, must - cells)
        assert cells <= may, (a, b, l, cells - may)
        assert tuple(np_cell(a, l)) in cells and tuple(np_cell(b, l)) in cells
        assert all(p != q for p, q in zip(got, got[1:]))


# ------------------------------------------------------------------------------------------ segment-sphere
@pytest.fixture(scope="module")
def seg_kernel32(taichi_cpu):
    return segment_sphere_kernel(ti.f32, n=512)


def segment_distance(a, b, c):
    d = b - a
    dd = d @ d
    t = np.zeros(len(c)) if dd == 0 else np.clip((c - a) @ d / dd, 0.0, 1.0)
    return np.linalg.norm(c - (a + t[:, None] * d), axis=1)


@st.composite
def spheres_near_a_segment(draw, n_max=128):
    """A segment (sometimes of zero length) and spheres around it; some exactly tangent (the centre one
    radius away from a point of the segment, or beyond an end, along an axis) or centred on it."""
    a = np.array([draw(st.floats(-1.0, 1.0)) for _ in range(3)])
    zero = draw(st.booleans())
    b = a if zero else a + np.array([draw(st.floats(-0.5, 0.5)) for _ in range(3)])
    seed = draw(st.integers(0, 2**32 - 1))
    n = draw(st.integers(1, n_max))
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.01, 0.5, n)
    t = rng.choice([0.0, 1.0, 0.5, rng.uniform()], n) if not zero else np.zeros(n)
    on = a + t[:, None] * (b - a)
    kind = rng.integers(0, 4, n)
    axis = np.eye(3)[rng.integers(0, 3, n)] * rng.choice([-1.0, 1.0], (n, 1))
    c = np.where((kind == 0)[:, None], on + axis * r[:, None], 0.0)  # tangent (up to rounding)
    c = np.where((kind == 1)[:, None], on, c)  # centred on the segment
    c = np.where((kind >= 2)[:, None], on + rng.normal(0, 0.4, (n, 3)), c)  # anywhere near
    return a, b, c, r


@settings(max_examples=100, **SETTINGS)
@given(data=spheres_near_a_segment())
def test_segment_sphere_f64_matches_numpy(seg_kernel, data):
    a, b, c, r = data
    got = seg_kernel(a, b, c, r)
    ref = np_segment_sphere(a, b, c, r)
    bad = got != ref
    dist = segment_distance(a, b, c)
    assert np.all(np.abs(dist[bad] - r[bad]) <= 1e-6 * r[bad]), (dist[bad], r[bad])


@settings(max_examples=100, **SETTINGS)
@given(data=spheres_near_a_segment())
def test_segment_sphere_f32_matches_numpy(seg_kernel32, data):
    """In float32 (the default precision) the kernel sees the rounded inputs; the oracle evaluates those
    in float64. Its rounding error scales with the coordinates (|a|, |c - a|, |b - a| <= ~2 m here) more
    than with r, yet it stays within 1e-6 r of tangency for these metre-scale inputs (measured over 300
    examples: 6e-8 r)."""
    a, b, c, r = (f32(x) for x in data)
    got = seg_kernel32(a, b, c, r)
    ref = np_segment_sphere(a, b, c, r)
    bad = got != ref
    dist = segment_distance(a, b, c)
    assert np.all(np.abs(dist[bad] - r[bad]) <= 1e-6 * r[bad]), (dist[bad] - r[bad], r[bad])


# ------------------------------------------------------------------------------------------ probe hits
N_ROCKS, N_RAYS = 400, 6


@pytest.fixture(scope="module")
def hit_probes(taichi_cpu):
    """Compiled once per insert mode, with capacities for cells down to r_min and radii up to 2 r_min
    (aabb entries), rays up to 0.5 m at cells >= 0.01 m."""
    pos = np.zeros((N_ROCKS, 3))
    pos[:, 0] = np.arange(N_ROCKS)
    rays = np.zeros((N_RAYS, 2, 3))
    rays[:, 0, 2] = 0.5
    r = np.full(N_ROCKS, 0.05)
    return {ins: Probe(pos, r, cell=0.01, insert=ins, rays=rays) for ins in choices("sim.hash.insert")}


@st.composite
def bed_and_rays(draw):
    """A patch of rocks (radius min = max sometimes), tire-like vertical rays or any rays over it, cell edge
    r_min, 2 r_max or in between, the whole thing translated (negative cells, f32 rounding); some rocks on
    cell corners, tangent to a ray, or centred on one."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    r_min = draw(st.floats(0.01, 0.05))
    r_max = r_min if draw(st.booleans()) else draw(st.floats(r_min, 2.0 * r_min))
    l = draw(st.sampled_from(["min", "diam", "between"]))
    l = {"min": r_min, "diam": 2.0 * r_max, "between": rng.uniform(r_min, 3.0 * r_max)}[l]
    shift = np.array([draw(st.floats(-50.0, 50.0)) for _ in range(2)] + [0.0])
    n = draw(st.integers(1, N_ROCKS))
    m = draw(st.integers(1, N_RAYS))
    vertical = draw(st.booleans())
    a = np.column_stack([rng.uniform(-0.4, 0.4, (m, 2)), np.full(m, 0.33)])
    b = a.copy()
    b[:, 2] = 0.0
    if not vertical:
        d = rng.normal(0.0, 0.2, (m, 3))
        b = a + d * np.minimum(1.0, 0.45 / np.linalg.norm(d, axis=1))[:, None]
    rays = np.stack([a, b], axis=1)
    r = rng.uniform(r_min, r_max, n) if r_max > r_min else np.full(n, r_min)
    pos = np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), rng.uniform(-0.1, 0.4, n)])
    kind = rng.integers(0, 5, n)
    ray = rng.integers(0, m, n)
    t = rng.uniform(0, 1, n)
    on = rays[ray, 0] + t[:, None] * (rays[ray, 1] - rays[ray, 0])
    axis = np.eye(3)[rng.integers(0, 2, n)] * rng.choice([-1.0, 1.0], (n, 1))
    pos = np.where((kind == 0)[:, None], np.round(pos / l) * l, pos)  # on a cell corner
    pos = np.where((kind == 1)[:, None], on + axis * r[:, None], pos)  # tangent (up to rounding)
    pos = np.where((kind == 2)[:, None], on, pos)  # centred on the ray
    return f32(pos + shift), f32(r), f32(rays + shift), float(np.float32(l))


@settings(max_examples=60, **SETTINGS)
@given(data=bed_and_rays())
def test_probe_hits_in_both_insert_modes_match_brute_force(hit_probes, data):
    """Both insert modes list the same hits (exactly), which are brute force's up to float32 rounding of the
    tangent distance. Translated up to 50 m, that rounding is absolute (~eps |x|): measured up to 7e-5 r,
    0.32 eps * scale, so the bound here is 8 eps * (r + |c| + ray length), not a fraction of r."""
    pos, r, rays, l = data
    got = {ins: reload_probe(p, pos, r, rays, cell=l).hits(step=3) for ins, p in hit_probes.items()}
    np.testing.assert_array_equal(got["center"], got["aabb"])  # the same candidates get the same f32 test
    dist = np.min([segment_distance(a, b, pos) for a, b in rays], axis=0)
    ref = dist <= r
    hit = np.zeros(len(pos), bool)
    hit[got["center"]] = True
    bad = hit != ref
    scale = r + np.linalg.norm(pos, axis=1) + np.max(np.linalg.norm(rays[:, 1] - rays[:, 0], axis=1))
    assert np.all(np.abs(dist[bad] - r[bad]) <= 8 * F32_EPS * scale[bad]), (dist[bad] - r[bad])
