"""The response of a stone to a body (engine/impacts.py: bounce, surface_velocity) and the damage class, against
closed forms written as impulses: J_n = m (1 + e) |u_n| along n, J_t = -min(mu J_n, m |u_t|) along u_t."""

import math

import numpy as np
import pytest
import taichi as ti
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from scenes_util import scene
from taichi_rocks.engine.impacts import bounce, damage_class, stone_mass, surface_velocity
from taichi_rocks.motion.bodies import FACES, body_parts, hexahedron_planes

pytestmark = pytest.mark.usefixtures("taichi_cpu")

SETTINGS = dict(deadline=None, derandomize=True, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
N = 1024


@pytest.fixture(scope="module")
def response(taichi_cpu):
    """bounce(v, surface_velocity(v_body, yaw, arm), n, e, mu) over a batch, float64."""
    f = {k: ti.Vector.field(3, ti.f64, N) for k in ("v", "v_body", "arm", "n", "out")}
    s = {k: ti.field(ti.f64, N) for k in ("yaw", "e", "mu", "un", "value", "chip", "crack", "r", "k3", "mass")}
    cls = ti.field(ti.i32, N)

    @ti.kernel
    def run(k: ti.i32):
        for i in range(k):
            vs = surface_velocity(f["v_body"][i], s["yaw"][i], f["arm"][i])
            f["out"][i], s["un"][i] = bounce(f["v"][i], vs, f["n"][i], s["e"][i], s["mu"][i])
            cls[i] = damage_class(s["value"][i], s["chip"][i], s["crack"][i])
            s["mass"][i] = stone_mass(s["r"][i], s["k3"][i])

    def call(**inp):
        k = max(len(np.atleast_1d(v)) if np.ndim(v) < 2 else len(v) for v in inp.values())
        defaults = dict(v_body=np.zeros(3), yaw=0.0, arm=np.zeros(3), e=0.5, mu=0.3, value=0.0, chip=1.0,
                        crack=2.0, r=0.01, k3=4.0 / 3.0 * math.pi * 2600.0)
        for key, val in {**defaults, **inp}.items():
            field = f[key] if key in f else s[key]
            a = np.asarray(val, np.float64)
            a = np.broadcast_to(a, (k, 3) if key in f else (k,))
            buf = np.zeros((N, 3) if key in f else N)
            buf[:k] = a
            field.from_numpy(buf)
        run(k)
        return f["out"].to_numpy()[:k], s["un"].to_numpy()[:k], cls.to_numpy()[:k], s["mass"].to_numpy()[:k]

    return call


def np_bounce(v, v_body, yaw, arm, n, e, mu, m=1.0):
    """The new velocity from the impulses, and the impulse."""
    vs = v_body + yaw[:, None] * np.stack([-arm[:, 1], arm[:, 0], np.zeros(len(arm))], 1)
    u = v - vs
    un = np.sum(u * n, axis=1)
    ut = u - un[:, None] * n
    ut_norm = np.linalg.norm(ut, axis=1)
    jn = m * (1 + e) * np.maximum(-un, 0.0)
    jt_mag = np.minimum(mu * jn, m * ut_norm)
    with np.errstate(invalid="ignore", divide="ignore"):
        t_dir = np.where(ut_norm[:, None] > 0, ut / ut_norm[:, None], 0.0)
    impulse = jn[:, None] * n - jt_mag[:, None] * t_dir
    return v + impulse / m, un, impulse


def vec(draw, lo=-40.0, hi=40.0):
    return np.array([draw(st.floats(lo, hi)) for _ in range(3)])


@st.composite
def impacts(draw):
    k = draw(st.integers(1, 16))
    rows = []
    for _ in range(k):
        n = vec(draw, -1, 1) + np.array([0.0, 0.0, 1e-3])
        rows.append((vec(draw), vec(draw, -35, 35), draw(st.floats(-1.0, 1.0)), vec(draw, -5, 5),
                     n / np.linalg.norm(n), draw(st.floats(0.0, 1.0)), draw(st.floats(0.0, 2.0))))
    return [np.array([r[q] for r in rows]) for q in range(7)]


@settings(max_examples=150, **SETTINGS)
@given(case=impacts())
def test_bounce_matches_the_impulses(response, case):
    v, v_body, yaw, arm, n, e, mu = case
    out, un, _, _ = response(v=v, v_body=v_body, yaw=yaw, arm=arm, n=n, e=e, mu=mu)
    want, un_ref, impulse = np_bounce(v, v_body, yaw, arm, n, e, mu)
    np.testing.assert_allclose(un, un_ref, atol=1e-9)
    np.testing.assert_allclose(out, want, atol=1e-9)
    # the impulse never pulls the stone into the body, and friction never reverses the sliding
    vs = v_body + yaw[:, None] * np.stack([-arm[:, 1], arm[:, 0], np.zeros(len(arm))], 1)
    u_after, u_before = out - vs, v - vs
    closing = un_ref < 0
    assert np.all(np.sum(u_after * n, axis=1)[closing] >= -1e-9)
    ut_b = u_before - np.sum(u_before * n, axis=1)[:, None] * n
    ut_a = u_after - np.sum(u_after * n, axis=1)[:, None] * n
    assert np.all(np.sum(ut_a * ut_b, axis=1) >= -1e-9)
    np.testing.assert_array_equal(out[~closing], v[~closing])  # separating: untouched


def test_energy_and_momentum_in_closed_form(response):
    rng = np.random.default_rng(5)
    k = 500
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    v_body = rng.uniform(-30, 30, (k, 3))
    u = rng.normal(size=(k, 3)) * 20
    u += (np.minimum(np.sum(u * n, axis=1), -0.5) - np.sum(u * n, axis=1))[:, None] * n  # closing: u_n <= -0.5
    v = v_body + u
    un = np.sum(u * n, axis=1)
    ut = u - un[:, None] * n
    # e = 1, mu = 0: the relative speed is kept, the normal part reversed
    out, _, _, _ = response(v=v, v_body=v_body, n=n, e=1.0, mu=0.0)
    np.testing.assert_allclose(np.linalg.norm(out - v_body, axis=1), np.linalg.norm(u, axis=1), rtol=1e-12)
    np.testing.assert_allclose(np.sum((out - v_body) * n, axis=1), -un, rtol=1e-12)
    # e = 0, mu = 0: the normal part is gone, the tangential part kept; energy lost = 1/2 m u_n^2
    out, _, _, _ = response(v=v, v_body=v_body, n=n, e=0.0, mu=0.0)
    np.testing.assert_allclose(np.sum((out - v_body) * n, axis=1), 0.0, atol=1e-12)
    np.testing.assert_allclose(out - v_body, ut, atol=1e-12)
    lost = 0.5 * (np.sum(u * u, axis=1) - np.sum((out - v_body) ** 2, axis=1))
    np.testing.assert_allclose(lost, 0.5 * un ** 2, rtol=1e-9)
    # sticking: friction enough to stop the sliding (mu (1 + e) |u_n| >= |u_t|)
    out, _, _, _ = response(v=v, v_body=v_body, n=n, e=0.5, mu=1e6)
    np.testing.assert_allclose(out - v_body, -0.5 * un[:, None] * n, atol=1e-9)
    # oblique, sliding: |u_t| shrinks by mu (1 + e) |u_n|; the momentum change is the impulse
    e, mu = 0.4, 0.05
    out, _, _, mass = response(v=v, v_body=v_body, n=n, e=e, mu=mu, r=0.01, k3=4.0 / 3.0 * math.pi * 2600.0)
    sliding = np.linalg.norm(ut, axis=1) > mu * (1 + e) * -un
    ut_after = (out - v_body) - np.sum((out - v_body) * n, axis=1)[:, None] * n
    np.testing.assert_allclose(np.linalg.norm(ut_after, axis=1)[sliding],
                               (np.linalg.norm(ut, axis=1) - mu * (1 + e) * -un)[sliding], rtol=1e-9, atol=1e-12)
    m = 4.0 / 3.0 * math.pi * 0.01 ** 3 * 2600.0
    np.testing.assert_allclose(mass, m, rtol=1e-14)
    dp = m * (out - v)
    np.testing.assert_allclose(np.sum(dp * n, axis=1), m * (1 + e) * -un, rtol=1e-9)
    assert sliding.sum() > 100


def test_a_stone_met_by_a_car_leaves_forwards_and_up(response):
    """A stone at rest (or falling slowly) in the road meets a car at 30 m/s on its bonnet, its windscreen or
    its front: in the world it leaves forwards (faster than nothing), and off the sloping glass also upwards;
    a yawing car moves its windscreen's edge sideways and the stone with it."""
    (car,) = scene(vehicles=[{"name": "c", "kind": "car"}]).vehicles
    body = body_parts(car)
    front = FACES.index("front")
    glass = hexahedron_planes(body.part("cabin").corners())[front, :3]
    nose = hexahedron_planes(body.part("lower").corners())[front, :3]
    assert glass[0] > 0 and glass[2] > 0
    v_car = np.array([30.0, 0.0, 0.0])
    for n, up in ((glass, True), (nose, False)):
        for v in (np.zeros(3), np.array([2.0, 0.5, -3.0])):
            out, un, _, _ = response(v=v[None], v_body=v_car[None], n=n[None], e=0.5, mu=0.3)
            assert un[0] < -0.6 * 30.0  # the glass leans back ~45 degrees: ~0.7 of the speed is normal
            assert out[0, 0] > 30.0 * (1 - 0.3 * 1.5)  # forwards, at a good share of the car's speed
            if up:
                assert out[0, 2] > 5.0
    arm = np.array([1.0, 0.6, 1.2])  # a point of the windscreen left of the centre line
    out, _, _, _ = response(v=np.zeros((1, 3)), v_body=v_car[None], yaw=[0.5], arm=arm[None], n=glass[None],
                            e=0.5, mu=1e6)
    # turning left at 0.5 rad/s, the glass 1 m ahead of the centre moves left at 0.5 m/s: yaw z x arm =
    # (-0.3, 0.5, 0); a stone that sticks (large friction) leaves with it, and 0.3 m/s slower forwards
    assert out[0, 1] == pytest.approx(0.5, abs=1e-12)
    assert out[0, 0] == pytest.approx(29.7 - 0.5 * np.sum((np.zeros(3) - [29.7, 0.5, 0.0]) * glass) * glass[0],
                                      abs=1e-9)


@pytest.mark.parametrize("chip,crack", [(0.0055, 0.14), (0.0011, 0.0055), (1.0, 1.0 + 1e-9)])
def test_damage_class_against_numpy(response, chip, crack):
    rng = np.random.default_rng(11)
    values = np.concatenate([rng.uniform(0.0, 3 * crack, 600), [0.0, chip, crack, np.nextafter(chip, 0),
                                                                np.nextafter(crack, 0)]])
    _, _, cls, _ = response(v=np.zeros((len(values), 3)), value=values, chip=chip, crack=crack)
    np.testing.assert_array_equal(cls, np.digitize(values, [chip, crack]))
