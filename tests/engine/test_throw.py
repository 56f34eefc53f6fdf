"""The tread launch model (engine/launch/tread.py) and the tread's footprint (engine/patch.py), each against
NumPy references."""

import itertools
import math

import numpy as np
import pytest
import taichi as ti
from scipy.optimize import brentq

from harness import Probe
from taichi_rocks.engine import patch
from taichi_rocks.engine.launch import tread
from taichi_rocks.engine.view import world_kernel
from taichi_rocks.engine.world import (FENDER, FLAP, FWD, HALF_L, HALF_W, RAY_FIELDS, SPIN, TIRE_R, VEL, IPar,
                                       Par, World)
from taichi_rocks.motion.vehicles import RearTires

pytestmark = pytest.mark.usefixtures("taichi_cpu")

# the scene's defaults ([launch], [bed] density, [world] gravity)
DEFAULTS = dict(grip=2.0e5, relax=math.radians(12.0), spread=0.3, adhesion=3.0e4, groove=0.012, density=2600.0,
                g=9.81, transfer=1.0, restitution=0.35)


def set_tread_params(w, wetness=0.0, spin_spread=0.0, **kw):
    p = {**DEFAULTS, **kw}
    par = w.par.to_numpy().astype(np.float64)
    par[Par.GRIP], par[Par.GRIP_RELAX], par[Par.GRIP_SPREAD] = p["grip"], p["relax"], p["spread"]
    par[Par.ADHESION], par[Par.GROOVE], par[Par.DENSITY] = p["adhesion"], p["groove"], p["density"]
    par[Par.GRAVITY], par[Par.TRANSFER], par[Par.RESTITUTION] = p["g"], p["transfer"], p["restitution"]
    par[Par.WETNESS], par[Par.SPREAD] = wetness, spin_spread
    w.set_params(par)


# ------------------------------------------------------------------------------------------ NumPy references
def np_hold_minus_pull(a, ap, r, mu, xi, centripetal, wet, p=DEFAULTS):
    hold = mu * p["grip"] * xi * np.exp(-(a - ap) / p["relax"]) + wet * p["adhesion"]
    return hold - 4.0 / 3.0 * p["density"] * r * (centripetal + p["g"] * np.cos(a))


def np_release(ap, r, mu, xi, centripetal, wet, n=20001):
    """First root of H - P in [ap, pi] by a dense scan and brentq; also the width of the first region where
    H <= P (a region narrower than the kernel's march step may be stepped over)."""
    f = lambda a: np_hold_minus_pull(a, ap, r, mu, xi, centripetal, wet)
    if f(ap) <= 0:
        return ap, np.inf
    grid = np.linspace(ap, np.pi, n)
    neg = np.flatnonzero(f(grid) <= 0)
    if not len(neg):
        return np.pi, np.inf
    j = neg[0]
    root = brentq(f, grid[j - 1], grid[j], xtol=1e-14)
    back = np.flatnonzero(f(grid[j:]) > 0)
    width = np.inf if not len(back) else grid[j + back[0]] - root
    return root, width


@pytest.fixture(scope="module")
def angle_kernel(taichi_cpu):
    """tread.release_angle over batches, float64."""
    m = 4096
    w = World(1, ti.f64)
    inp = ti.field(ti.f64, shape=(m, 5))
    out = ti.field(ti.f64, shape=m)

    @world_kernel
    def run(w: ti.template(), k: ti.i32):
        """tread.release_angle over a batch."""
        for i in range(k):
            out[i] = tread.release_angle(w, inp[i, 0], inp[i, 1], inp[i, 2], inp[i, 3], inp[i, 4])

    def call(ap, r, mu, xi, centripetal, wet):
        set_tread_params(w, wetness=wet)
        k = max(np.size(x) for x in (ap, r, mu, xi, centripetal))
        buf = np.zeros((m, 5))
        buf[:k] = np.column_stack([np.broadcast_to(x, k) for x in (ap, r, mu, xi, centripetal)])
        inp.from_numpy(buf)
        run(w, k)
        return out.to_numpy()[:k]

    return call


def random_rocks(rng, n):
    V = rng.uniform(0.5, 40.0, n)
    slip = rng.uniform(0.0, 0.3, n)
    R = rng.uniform(0.25, 0.6, n)
    L = rng.uniform(0.05, 0.3, n)
    ap = np.arcsin(np.minimum(1.0, L / (2 * R)))
    return dict(ap=ap, r=rng.uniform(0.003, 0.06, n), mu=rng.uniform(0.2, 1.2, n),
                xi=np.exp(0.3 * rng.uniform(-1, 1, n)), centripetal=(V * (1 + slip)) ** 2 / R)


@pytest.mark.parametrize("wet", [0.0, 0.37, 1.0])
def test_release_angle_matches_the_force_balance(angle_kernel, wet):
    rng = np.random.default_rng(int(wet * 100) + 1)
    n = 1500
    x = random_rocks(rng, n)
    # edge cases: released at the patch (heavy, fast), never released (tiny, slow, sticky), at rest
    x["r"][:5], x["centripetal"][:5] = 0.06, 40.0 ** 2 / 0.25
    x["r"][5:10], x["centripetal"][5:10], x["mu"][5:10] = 0.003, 0.5 ** 2 / 0.6, 1.2
    x["centripetal"][10] = 0.0
    got = angle_kernel(x["ap"], x["r"], x["mu"], x["xi"], x["centripetal"], wet)
    ref = np.empty(n)
    width = np.empty(n)
    for i in range(n):
        ref[i], width[i] = np_release(x["ap"][i], x["r"][i], x["mu"][i], x["xi"][i], x["centripetal"][i], wet)
    np.testing.assert_allclose(got[:5], x["ap"][:5])
    np.testing.assert_allclose(ref[:5], x["ap"][:5])
    assert np.all(np.abs(got[5:10] - np.pi) < 1e-12) and np.all(ref[5:10] == np.pi)
    off = np.abs(got - ref) > 1e-6
    # the march steps (pi - ap) / 32: a first region of release narrower than that can be stepped over
    step = (np.pi - x["ap"]) / tread.MARCH
    assert np.all(width[off] < step[off]), (got[off], ref[off], width[off])
    assert off.mean() < 0.01
    at_patch, never = np.isclose(ref, x["ap"]), ref == np.pi
    assert at_patch.sum() > 10 and never.sum() > 10 and (~at_patch & ~never).sum() > 200  # all three kinds


def test_release_angle_trends(angle_kernel):
    ap = math.asin(0.12 / 0.66)
    cen = lambda V: (V * 1.15) ** 2 / 0.33
    radii = np.linspace(0.004, 0.03, 40)
    by_size = angle_kernel(ap, radii, 0.6, 1.0, cen(20.0), 0.0)
    assert np.all(np.diff(by_size) <= 0) and by_size[0] > by_size[-1], "heavier stones leave earlier"
    speeds = np.linspace(3.0, 40.0, 40)
    by_speed = angle_kernel(ap, 0.008, 0.6, 1.0, cen(speeds), 0.0)
    assert np.all(np.diff(by_speed) <= 0) and by_speed[0] > by_speed[-1], "faster wheels throw earlier"
    wet = [angle_kernel(ap, radii, 0.6, 1.0, cen(20.0), w) for w in (0.0, 0.5, 1.0)]
    assert np.all(wet[1] >= wet[0]) and np.all(wet[2] >= wet[1]) and np.any(wet[2] > wet[0] + 0.05), \
        "wetter ground, later release"
    mus = np.linspace(0.2, 1.0, 20)
    by_mu = angle_kernel(ap, 0.01, mus, 1.0, cen(20.0), 0.0)
    assert np.all(np.diff(by_mu) >= 0) and by_mu[-1] > by_mu[0], "more grip, later release"


# ------------------------------------------------------------------------------------------ launch velocity
@pytest.fixture(scope="module")
def throw_world(taichi_cpu):
    """A World whose ray rows are per-case tires: throw_velocity, throw_angle and guarded over batches."""
    m = 512
    w = World(1, ti.f64, n_tires=m, ray_capacity=1)
    rock = ti.field(ti.f64, shape=(m, 2))
    v_open = ti.Vector.field(3, ti.f64, shape=m)
    v_guard = ti.Vector.field(3, ti.f64, shape=m)
    alpha = ti.field(ti.f64, shape=m)

    @world_kernel
    def run(w: ti.template(), k: ti.i32, step: ti.i32):
        """throw_angle and throw_velocity (open and guarded) over a batch."""
        for i in range(k):
            seed = w.ipar[IPar.SEED]
            alpha[i] = tread.throw_angle(w, rock[i, 0], rock[i, 1], w.ray[i, SPIN], w.ray[i, TIRE_R],
                                         w.ray[i, HALF_L], seed, i, step)
            v_open[i] = tread.throw_velocity(w, i, rock[i, 0], rock[i, 1], i, step, False)
            v_guard[i] = tread.throw_velocity(w, i, rock[i, 0], rock[i, 1], i, step, True)

    def call(rows, r, mu, step=7, **params):
        set_tread_params(w, **params)
        k = len(r)
        data = np.zeros((m, RAY_FIELDS))
        data[:k] = rows
        data[k:, TIRE_R] = 1.0
        w.ray.from_numpy(data)
        buf = np.zeros((m, 2))
        buf[:k, 0], buf[:k, 1] = r, mu
        rock.from_numpy(buf)
        run(w, k, step)
        return (alpha.to_numpy()[:k], v_open.to_numpy()[:k], v_guard.to_numpy()[:k])

    return call


def tire_rows(rng, k, slip=None, reverse=False, lateral=0.0, fender=50.0, flap=-1.0):
    heading = rng.uniform(-np.pi, np.pi, k)
    f = np.column_stack([np.cos(heading), np.sin(heading)])
    V = rng.uniform(2.0, 35.0, k) * (-1 if reverse else 1)
    s = rng.uniform(0.0, 0.3, k) if slip is None else np.full(k, slip)
    lat = rng.uniform(-lateral, lateral, k)
    rows = np.zeros((k, RAY_FIELDS))
    rows[:, VEL] = V * f[:, 0] - lat * f[:, 1]
    rows[:, VEL + 1] = V * f[:, 1] + lat * f[:, 0]
    rows[:, FWD:FWD + 2] = f
    rows[:, SPIN] = V * (1 + s)
    rows[:, TIRE_R] = rng.uniform(0.25, 0.6, k)
    rows[:, HALF_L] = rng.uniform(0.03, 0.1, k)
    rows[:, HALF_W] = 0.1
    rows[:, FENDER] = np.radians(fender)
    rows[:, FLAP] = flap
    return rows


def np_tread_velocity(rows, alpha, mu, transfer=1.0):
    """Spread 0: k (v_wheel_xy - spin cos(alpha) f, |spin| sin(alpha))."""
    k = np.minimum(1.0, transfer * mu)
    spin = rows[:, SPIN]
    xy = rows[:, VEL:VEL + 2] - (spin * np.cos(alpha))[:, None] * rows[:, FWD:FWD + 2]
    return k[:, None] * np.column_stack([xy, np.abs(spin) * np.sin(alpha)])


def test_launch_velocity_is_the_tread_point_velocity(throw_world):
    rng = np.random.default_rng(3)
    k = 500
    rows = tire_rows(rng, k, lateral=1.5)
    r, mu = rng.uniform(0.002, 0.05, k), rng.uniform(0.3, 1.4, k)
    for transfer in (1.0, 0.8):
        alpha, v, _ = throw_world(rows, r, mu, transfer=transfer)
        np.testing.assert_allclose(v, np_tread_velocity(rows, alpha, mu, transfer), rtol=1e-9, atol=1e-9)
    ap = np.arcsin(rows[:, HALF_L] / rows[:, TIRE_R])
    pinched = alpha <= ap + 1e-12
    assert pinched.sum() > 50 and (~pinched).sum() > 20  # both capture outcomes occur
    # capture: about p_carry = min(1, mu) / (1 + (r / groove)^4) of the stones are carried
    p = np.minimum(1, mu) / (1 + (r / 0.012) ** 4)
    assert abs((~pinched).sum() - p.sum()) < 4 * np.sqrt(p.sum()) + 3
    # counter-based: the same numbers again, other numbers at another step
    again, v2, _ = throw_world(rows, r, mu)
    np.testing.assert_array_equal(again, alpha)
    other, _, _ = throw_world(rows, r, mu, step=8)
    assert np.mean(other != alpha) > 0.5


@pytest.mark.parametrize("reverse", [False, True])
def test_launches_respect_the_kinematic_bound(throw_world, reverse):
    rng = np.random.default_rng(4 + reverse)
    k = 500
    rows = tire_rows(rng, k, slip=0.0, reverse=reverse)
    r, mu = rng.uniform(0.002, 0.05, k), rng.uniform(0.3, 1.4, k)
    alpha, v, _ = throw_world(rows, r, mu)
    V = np.abs(rows[:, SPIN])
    speed = np.linalg.norm(v, axis=1)
    assert np.all(speed <= 2 * V * np.sin(alpha / 2) * (1 + 1e-9) + 1e-12)
    # with slip and lateral slide, spread: no faster than the tread point itself
    rows = tire_rows(rng, k, lateral=2.0, reverse=reverse)
    alpha, v, _ = throw_world(rows, r, mu, spin_spread=math.radians(8.0))
    spin = rows[:, SPIN]
    point = np.column_stack([rows[:, VEL:VEL + 2] - (spin * np.cos(alpha))[:, None] * rows[:, FWD:FWD + 2],
                             np.abs(spin) * np.sin(alpha)])
    rel = v - np.minimum(1, mu)[:, None] * np.column_stack([rows[:, VEL:VEL + 2], 0 * spin])
    # spread turns the tread's part only: its size is that of the tread point's velocity in the wheel frame
    np.testing.assert_allclose(np.linalg.norm(rel, axis=1), np.minimum(1, mu) * np.abs(spin), rtol=1e-9)
    assert np.all(np.linalg.norm(v, axis=1) <= np.linalg.norm(point, axis=1)
                  + np.abs(spin) * 2 * np.sin(math.radians(8.0) / 2) + 1e-9)
    # backwards relative to the wheel below 90 degrees, also reversing
    f = rows[:, FWD:FWD + 2]
    back = -np.sign(spin) * np.einsum("ij,ij->i", rel[:, :2], f)
    low = alpha < np.radians(85)
    assert low.sum() > 100 and np.all(back[low] > 0)


def test_fenders_and_mud_flaps_stop_what_reaches_them(throw_world):
    rng = np.random.default_rng(6)
    k = 500
    # small stones on soaked ground: carried high up the tire; flaps low enough to catch the pinched ones
    rows = tire_rows(rng, k, fender=40.0, flap=0.05)
    rows[: k // 2, FLAP] = -1.0  # half without mud flaps
    r, mu = rng.uniform(0.002, 0.02, k), rng.uniform(0.5, 1.0, k)
    alpha, v_open, v = throw_world(rows, r, mu, wetness=1.0)
    e = DEFAULTS["restitution"]
    np.testing.assert_allclose(v_open, np_tread_velocity(rows, alpha, mu), rtol=1e-9, atol=1e-9)
    # NumPy: the straight path from the tread point, in the vehicle's frame, at the flap plane 1.1 R behind
    R = rows[:, TIRE_R]
    rel = v_open - np.column_stack([rows[:, VEL:VEL + 2], 0 * R])
    back = -np.einsum("ij,ij->i", rel[:, :2], rows[:, FWD:FWD + 2])
    x0, z0 = R * np.sin(alpha), R * (1 - np.cos(alpha))
    with np.errstate(divide="ignore", invalid="ignore"):
        z_at_flap = z0 + rel[:, 2] * (1.1 * R - x0) / back
    flap = (rows[:, FLAP] >= 0) & (back > 0) & (z_at_flap > rows[:, FLAP])
    fender = alpha > rows[:, FENDER]
    stopped = fender | flap
    assert fender.sum() > 20 and (flap & ~fender).sum() > 20 and (~stopped).sum() > 20
    drop = e * np.column_stack([v_open[:, :2], -np.abs(v_open[:, 2])])
    np.testing.assert_allclose(v[stopped], drop[stopped], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(v[~stopped], v_open[~stopped])
    assert np.all(v[stopped, 2] <= 0)
    assert np.all(np.linalg.norm(v[stopped], axis=1) <= e * np.linalg.norm(v_open[stopped], axis=1) + 1e-12)


# ------------------------------------------------------------------------------------------ the footprint
def rear_tires(bottom, forward, half_width, half_length):
    bottom = np.asarray(bottom, np.float64).reshape(-1, 3)
    t = len(bottom)
    z = np.zeros(t)
    return RearTires(bottom + [0, 0, 0.33], bottom, np.zeros((t, 3)), np.asarray(forward, np.float64).reshape(-1, 2),
                     z + 10.0, np.broadcast_to(half_width, t) + z, np.broadcast_to(half_length, t) + z, z + 0.33,
                     z + 1.0, z - 1.0)


def np_point_triangle_dist2(c, a, b, d):
    """(N,) squared distance from points c (N, 2) to the triangle a, b, d (2,)."""
    def seg(p, q):
        e = q - p
        ee = e @ e
        s = np.zeros(len(c)) if ee == 0 else np.clip((c - p) @ e / ee, 0, 1)
        return ((c - p - s[:, None] * e) ** 2).sum(1)

    cr = lambda p, q: (q[0] - p[0]) * (c[:, 1] - p[1]) - (q[1] - p[1]) * (c[:, 0] - p[0])
    s1, s2, s3 = cr(a, b), cr(b, d), cr(d, a)
    area = (b[0] - a[0]) * (d[1] - a[1]) - (b[1] - a[1]) * (d[0] - a[0])
    inside = (((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))) & (area != 0)
    return np.where(inside, 0.0, np.minimum(np.minimum(seg(a, b), seg(b, d)), seg(d, a)))


def np_footprint_dist(c, corners):
    """Distance from points c to the convex hull of the corners: the hull is the union of the triangles of
    its points (Caratheodory), so it is the least distance to any triangle of three corners."""
    best = np.full(len(c), np.inf)
    for i, j, k in itertools.combinations(range(len(corners)), 3):
        best = np.minimum(best, np_point_triangle_dist2(c, corners[i], corners[j], corners[k]))
    return np.sqrt(best)


def footprint_case(rng, n, b0, f0, b1, f1, hw, hl, real):
    """Rocks around a swept footprint, on the ground; some exactly at its edge, some lifted."""
    tires = rear_tires([b0], [f0], hw, hl), rear_tires([b1], [f1], hw, hl)
    corners = np.concatenate([patch.footprint_corners(t.bottom, t.forward, hw, hl)[0] for t in tires])
    lo, hi = corners.min(0) - 0.1, corners.max(0) + 0.1
    r = rng.uniform(0.01, 0.05, n)
    xy = rng.uniform(lo, hi, (n, 2))
    # exactly at the edge: from a corner, r along the outward diagonal; and r beyond the middle of an edge
    centre = corners.mean(0)
    for q in range(8):
        d = corners[q] - centre
        xy[q] = corners[q] + r[q] * d / np.linalg.norm(d)
    xy[-20:] = rng.dirichlet(np.ones(8), 20) @ corners  # over the footprint but lifted 2 mm: not run over
    pos = np.column_stack([xy, b1[2] + r])
    pos[-20:, 2] += 2e-3
    pos = pos.astype(np.float32 if real == ti.f32 else np.float64).astype(np.float64)
    r = r.astype(np.float32 if real == ti.f32 else np.float64).astype(np.float64)
    return tires, corners, pos, r


CASES = {  # b0, heading0, b1, heading1, half width, half length
    "straight": ([0.0, 0.0, 0.0], 0.0, [0.04, 0.0, 0.0], 0.0, 0.11, 0.06),
    "turning": ([0.3, -0.2, 0.0], 0.4, [0.33, -0.17, 0.0], 0.75, 0.15, 0.08),
    "stationary": ([-0.5, 0.5, 0.0], 2.0, [-0.5, 0.5, 0.0], 2.0, 0.11, 0.06),
    "negative far": ([-3712.25, -981.5, -4.0], -2.5, [-3712.31, -981.6, -4.0], -2.45, 0.25, 0.1),
    "fast": ([0.0, 0.0, 0.0], 1.0, [0.6, 0.9, 0.0], 1.0, 0.11, 0.06),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_patch_finds_every_rock_under_the_tread(case):
    b0, h0, b1, h1, hw, hl = CASES[case]
    real = ti.f64 if case == "negative far" else ti.f32
    rng = np.random.default_rng(sorted(CASES).index(case))
    f0, f1 = [math.cos(h0), math.sin(h0)], [math.cos(h1), math.sin(h1)]
    (t0, t1), corners, pos, r = footprint_case(rng, 2500, np.array(b0), f0, np.array(b1), f1, hw, hl, real)
    rays = np.stack([t1.center, t1.bottom], axis=1)
    prev = np.stack([t0.center, t0.bottom], axis=1)
    probe = Probe(pos, r, cell=0.1, rays=rays, swept=True, patch=True, real=real)
    tread = patch.tread_columns(t0, t1, np.ones(1, bool), np.zeros(3))
    got = probe.hits(prev=prev, tread=tread)
    d = np_footprint_dist(pos[:, :2], corners)
    lifted = pos[:, 2] - r > b1[2] + 1e-3
    # the tire's own (vertical) ray sweeps the segment b0-b1 from the ground up: it hits lifted rocks too
    seg = np.array([b0, b1])[:, :2]
    ray = np_footprint_dist(pos[:, :2], np.concatenate([seg, seg[-1:]]))
    ref = np.flatnonzero(((d <= r) & ~lifted) | (ray <= r))
    assert len(ref) > 50 and lifted.sum() == 20 and np.sum(ray[lifted] > r[lifted]) >= 3  # lifted: not run over
    bad = np.setxor1d(got, ref)
    eps = 1e-9 if real == ti.f64 else 4e-6  # rounding of the f32 footprint and rock positions
    assert np.all(np.abs(d[bad] - r[bad]) < eps * max(1.0, np.abs(b0).max())), (case, bad, d[bad] - r[bad])
    assert len(bad) <= 8


def test_patch_with_no_footprint_launches_what_swept_launches():
    rng = np.random.default_rng(12)
    n = 3000
    pos = np.column_stack([rng.uniform(-0.3, 1.5, n), rng.uniform(-0.15, 0.15, n), np.zeros(n)])
    r = rng.uniform(0.015, 0.03, n)
    pos[:, 2] = r
    prev = np.array([[[0.0, 0.0, 0.33], [0.0, 0.0, 0.0]], [[0.2, 0.05, 0.33], [0.2, 0.05, 0.0]]])
    cur = np.array([[[1.2, 0.0, 0.33], [1.2, 0.0, 0.0]], [[1.1, -0.05, 0.33], [1.1, -0.05, 0.0]]])
    t0 = rear_tires(prev[:, 1], [[1.0, 0.0]] * 2, 0.0, 0.0)
    t1 = rear_tires(cur[:, 1], [[1.0, 0.0]] * 2, 0.0, 0.0)
    tread = patch.tread_columns(t0, t1, np.ones(2, bool), np.zeros(3))
    out = {}
    for mode in ("swept", "patch"):
        probe = Probe(pos, r, cell=0.1, rays=cur, swept=True, patch=mode == "patch", throw="tread", fenders=True)
        set_tread_params(probe.w)
        hits = probe.hits(prev=prev, tread=tread)
        out[mode] = hits, probe.w.vel.to_numpy()[hits]
        del probe  # released before the next is built (its layout's kernels serve the next)
    np.testing.assert_array_equal(out["patch"][0], out["swept"][0])
    np.testing.assert_array_equal(out["patch"][1], out["swept"][1])
    assert len(out["swept"][0]) > 30


def test_one_launch_per_rock_per_step_with_overlapping_treads():
    rng = np.random.default_rng(13)
    n = 2000
    pos = np.column_stack([rng.uniform(-0.3, 0.5, (n, 2)), np.zeros(n)])
    r = rng.uniform(0.015, 0.03, n)
    pos[:, 2] = r
    bottoms = np.array([[0.0, 0.0, 0.0], [0.05, 0.02, 0.0], [0.1, 0.0, 0.0]])
    t = rear_tires(bottoms, [[1.0, 0.0]] * 3, 0.15, 0.1)
    rays = np.stack([t.center, t.bottom], axis=1)
    probe = Probe(pos, r, cell=0.1, rays=rays, swept=True, patch=True)
    hits = probe.hits(tread=patch.tread_columns(t, t, np.ones(3, bool), np.zeros(3)))
    launched = int(probe.w.launches[None])
    assert len(hits) > 50 and launched == len(hits)  # each rock once, whichever tires cover it


def test_huge_coordinates_are_local_to_the_origin():
    """Far from the world origin the hull is written relative to the kernel origin (floating origin): the
    columns of a tire 5e6 m away equal those of the same tire at the origin, shifted."""
    far = np.array([5.0e6, -3.0e6, 0.0])
    t0 = rear_tires([[0.0, 0.0, 0.0]], [[0.6, 0.8]], 0.11, 0.06)
    t1 = rear_tires([[0.03, 0.04, 0.0]], [[0.8, 0.6]], 0.11, 0.06)
    near = patch.tread_columns(t0, t1, np.ones(1, bool), np.zeros(3))
    moved = [rear_tires(t.bottom + far, t.forward, 0.11, 0.06) for t in (t0, t1)]
    shifted = patch.tread_columns(*moved, np.ones(1, bool), far)
    np.testing.assert_allclose(shifted, near, atol=1e-9)
    # and a jumped tire sweeps nothing: its previous pose is the current one
    jumped = patch.tread_columns(t0, t1, np.zeros(1, bool), np.zeros(3))
    still = patch.tread_columns(t1, t1, np.ones(1, bool), np.zeros(3))
    np.testing.assert_array_equal(jumped, still)
