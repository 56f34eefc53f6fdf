"""Stones that tumble (engine/tumble.py): the rotation against its closed form, the contact impulse and the
launch spin against NumPy references (random and adversarial inputs), and in a simulation: launched stones spin
backwards about the axle, the orientation integrates the spin in flight, a bounce changes the spin by the
closed form, resting rocks keep their orientation through the tiles and checkpoints (active = full), and
without tumbling nothing of it is allocated while every position is the same bit for bit."""

import math

import numpy as np
import pytest
import taichi as ti

from scenes_util import scene
from taichi_rocks.config.plan import Plan
from taichi_rocks.config.scene import scene_with
from taichi_rocks.config.streams import LAUNCH_SPIN
from taichi_rocks.engine import tumble
from taichi_rocks.engine.randomness import uniform01_np
from taichi_rocks.engine.rockfields import FLYING, RESTING, SLIDING
from taichi_rocks.engine.setup import initial_orientations
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.view import world_kernel
from taichi_rocks.engine.world import FWD, RAY_FIELDS, SPIN, TIRE_R, VEL, IPar, Par, World

pytestmark = pytest.mark.usefixtures("taichi_cpu")

CAR = {"length": 4.0, "width": 1.8, "wheelbase": 2.6, "track": 1.5, "tire_radius": 0.33}


# ------------------------------------------------------------------------------------------ NumPy references
def np_quat_mul(a, b):
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def np_exp(omega, t):
    """exp(omega t / 2) as quaternions (x, y, z, w): the rotation by |omega| t about omega."""
    omega = np.asarray(omega, np.float64)
    wn = np.linalg.norm(omega, axis=-1, keepdims=True)
    axis = np.divide(omega, wn, out=np.zeros_like(omega), where=wn > 0)
    half = 0.5 * wn * np.asarray(t, np.float64).reshape(-1, 1)
    return np.concatenate([axis * np.sin(half), np.cos(half)], axis=-1)


def np_rotate(q, p):
    """p turned by the unit quaternions q."""
    qp = np.concatenate([p, np.zeros(p.shape[:-1] + (1,))], axis=-1)
    conj = q * np.array([-1.0, -1.0, -1.0, 1.0])
    return np_quat_mul(np_quat_mul(q, qp), conj)[..., :3]


def same_rotation(a, b):
    """|a . b| (1: the same rotation, q and -q alike)."""
    return np.abs(np.sum(a * b, axis=-1))


def random_quats(rng, k):
    q = rng.normal(size=(k, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# ------------------------------------------------------------------------------------------ kernels alone
@pytest.fixture(scope="module")
def turn_kernel(taichi_cpu):
    m = 256
    fields = {dt: (ti.Vector.field(4, dt, shape=m), ti.Vector.field(3, dt, shape=m), ti.field(dt, shape=m))
              for dt in (ti.f32, ti.f64)}

    def make(dt):
        q, om, h = fields[dt]

        @ti.kernel
        def run(k: ti.i32, steps: ti.i32):
            for i in range(k):
                for _ in range(steps):
                    q[i] = tumble.unit(tumble.turn(q[i], om[i], h[i]))

        return run

    runs = {dt: make(dt) for dt in fields}

    def call(q0, omega, h, steps, dt=ti.f64):
        q, om, hh = fields[dt]
        npd = np.float64 if dt == ti.f64 else np.float32
        k = len(q0)
        pad = lambda a, shape: np.concatenate([a, np.zeros((m - k,) + shape)]).astype(npd)
        q.from_numpy(pad(q0, (4,)))
        om.from_numpy(pad(omega, (3,)))
        hh.from_numpy(pad(h, ()))
        runs[dt](k, steps)
        return q.to_numpy()[:k].astype(np.float64)

    return call


@pytest.mark.parametrize("precision, tol", [(ti.f64, 1e-12), (ti.f32, 3e-5)])
def test_orientation_integrates_the_angular_velocity(turn_kernel, precision, tol):
    """n steps of q <- exp(omega h / 2) q equal the closed form exp(omega n h / 2) q0 (constant omega),
    including omega = 0, a tiny and a huge spin, h = 0 and a turn past 2 pi per step."""
    rng = np.random.default_rng(1)
    k, steps = 200, 250
    q0 = random_quats(rng, k)
    omega = rng.normal(size=(k, 3)) * rng.uniform(0.0, 80.0, (k, 1))
    omega[0] = 0.0
    omega[1] = [1e-9, 0.0, 0.0]
    omega[2] = [0.0, 0.0, 3000.0]
    h = rng.uniform(1e-4, 0.02, k)
    h[3] = 0.0
    h[4] = 0.05  # |omega| h > 2 pi below
    omega[4] = [0.0, 200.0, 0.0]
    got = turn_kernel(q0, omega, h, steps, precision)
    want = np_quat_mul(np_exp(omega, h * steps), q0)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=tol)
    # f32: the angle accumulates round-off of |omega| h per step (~1e-7 relative each)
    slack = tol * (1.0 + np.linalg.norm(omega, axis=1) * h * steps * (precision == ti.f32))
    assert np.all(1.0 - same_rotation(got, want) <= slack), np.max(1.0 - same_rotation(got, want))
    np.testing.assert_allclose(got[0], q0[0], atol=4 * tol)  # no spin: the orientation stays (renormalised)


@pytest.fixture(scope="module")
def spin_world(taichi_cpu):
    """A World whose ray rows are per-case tires: tumble.launch_spin and tumble.kick over batches."""
    m = 512
    w = World(1, ti.f64, n_tires=m, ray_capacity=1)
    inp = ti.Vector.field(3, ti.f64, shape=m)  # the stone's velocity
    arm = ti.Vector.field(3, ti.f64, shape=m)
    sc = ti.field(ti.f64, shape=(m, 2))  # alpha, r
    out = ti.Vector.field(3, ti.f64, shape=m)
    kicked = ti.Vector.field(3, ti.f64, shape=m)

    @world_kernel
    def run(w: ti.template(), k: ti.i32, step: ti.i32):
        """tumble.launch_spin and tumble.kick over a batch."""
        for i in range(k):
            out[i] = tumble.launch_spin(w, i, sc[i, 0], inp[i], sc[i, 1], i, step)
            kicked[i] = tumble.kick(out[i], arm[i], inp[i], sc[i, 1])

    def call(rows, alpha, v, r, arms=None, spread=0.0, step=7, seed=5):
        k = len(r)
        data = np.zeros((m, RAY_FIELDS))
        data[:k] = rows
        w.ray.from_numpy(data)
        par = np.zeros(Par.COUNT)
        par[Par.SPIN_SPREAD] = spread
        ipar = np.zeros(IPar.COUNT, np.int64)
        ipar[IPar.SEED] = seed
        w.set_params(par, ipar)
        pad = lambda a, shape: np.concatenate([a, np.zeros((m - k,) + shape)])
        inp.from_numpy(pad(v, (3,)))
        arm.from_numpy(pad(np.zeros((k, 3)) if arms is None else arms, (3,)))
        sc.from_numpy(pad(np.column_stack([alpha, r]), (2,)))
        run(w, k, step)
        return out.to_numpy()[:k], kicked.to_numpy()[:k]

    return call


def np_tread_point(rows, alpha):
    s = rows[:, SPIN]
    f = np.column_stack([rows[:, FWD:FWD + 2], np.zeros(len(s))])
    sg = np.where(s >= 0.0, 1.0, -1.0)
    v_t = rows[:, VEL:VEL + 3] - (s * np.cos(alpha))[:, None] * f
    v_t[:, 2] += np.abs(s) * np.sin(alpha)
    n = -(sg * np.sin(alpha))[:, None] * f
    n[:, 2] = -np.cos(alpha)
    return v_t, n


def np_launch_spin(rows, alpha, v, r, spread, step, seed):
    v_t, n = np_tread_point(rows, alpha)
    roll = np.cross(v_t - v, n) / r[:, None]
    ids = np.arange(len(r))
    u = [uniform01_np(seed, ids, step, s) for s in LAUNCH_SPIN.ids]  # float32, as the kernel draws them
    z = np.float32(2.0) * u[0] - np.float32(1.0)
    phi = np.float32(6.283185307179586) * u[1]
    rho = np.power(u[2], np.float32(1.0 / 3.0))
    sxy = np.sqrt(np.maximum(np.float32(1.0) - z * z, np.float32(0.0)))
    ball = np.column_stack([sxy * np.cos(phi), sxy * np.sin(phi), z]) * rho[:, None]
    return roll, roll + spread * np.linalg.norm(roll, axis=1)[:, None] * ball.astype(np.float64)


def tires(rng, k, reverse=False, lateral=0.0):
    heading = rng.uniform(-np.pi, np.pi, k)
    f = np.column_stack([np.cos(heading), np.sin(heading)])
    V = rng.uniform(1.0, 35.0, k) * (-1.0 if reverse else 1.0)
    lat = rng.uniform(-lateral, lateral, k)
    rows = np.zeros((k, RAY_FIELDS))
    rows[:, VEL] = V * f[:, 0] - lat * f[:, 1]
    rows[:, VEL + 1] = V * f[:, 1] + lat * f[:, 0]
    rows[:, FWD:FWD + 2] = f
    rows[:, SPIN] = V * (1.0 + rng.uniform(0.02, 0.3, k))
    rows[:, TIRE_R] = rng.uniform(0.25, 0.6, k)
    return rows, f


def axle(f):
    """l = z x f, the axle's direction (the wheel spins by +s / R about it)."""
    return np.column_stack([-f[:, 1], f[:, 0], np.zeros(len(f))])


@pytest.mark.parametrize("reverse", [False, True])
def test_a_stone_rolling_off_the_tread_spins_backwards_about_the_axle(spin_world, reverse):
    """Stones leaving a rolling tread slower than it (v = k v_t, k < 1, no lateral scatter): the spin is along
    the axle and opposite to the wheel's own spin; its size is the tread's speed relative to the stone along the
    tread over r; the reference over random tires, angles (0 and pi among them) and radii."""
    rng = np.random.default_rng(11 + reverse)
    k = 400
    rows, f = tires(rng, k, reverse=reverse)
    alpha = rng.uniform(0.0, 1.2, k)
    alpha[:3] = [0.0, np.pi, 1e-7]
    r = rng.uniform(0.003, 0.05, k)
    kk = rng.uniform(0.3, 0.95, k)
    v_t, n = np_tread_point(rows, alpha)
    v = kk[:, None] * v_t
    got, _ = spin_world(rows, alpha, v, r)
    roll, _ = np_launch_spin(rows, alpha, v, r, 0.0, 7, 5)
    np.testing.assert_allclose(got, roll, rtol=1e-9, atol=1e-9)
    l = axle(f)
    along = np.sum(got * l, axis=1)
    np.testing.assert_allclose(np.linalg.norm(got - along[:, None] * l, axis=1), 0.0, atol=1e-9 * np.abs(along).max())
    wheel = rows[:, SPIN]  # the wheel spins by s / R about l
    assert np.all(np.sign(along) == -np.sign(wheel))  # backwards, at alpha = 0 and pi too
    t_dir = np.cross(l, n)  # the tread's direction of motion at the release point (for s > 0)
    np.testing.assert_allclose(along, -np.sum((v_t - v) * t_dir, axis=1) / r, rtol=1e-9, atol=1e-9)


def test_the_spin_scatter_and_its_adversarial_cases(spin_world):
    """The scatter: omega_roll + spread |omega_roll| u with u in the unit ball, drawn from (seed, rock, step);
    a stone moving with the tread does not spin; lateral motion and a parked tire (s = 0) are handled."""
    rng = np.random.default_rng(13)
    k = 400
    rows, _ = tires(rng, k, lateral=2.0)
    rows[:5, SPIN] = 0.0  # a parked tire
    alpha = rng.uniform(0.0, 0.9, k)
    r = rng.uniform(0.003, 0.05, k)
    v_t, _ = np_tread_point(rows, alpha)
    v = v_t * rng.uniform(0.3, 1.0, (k, 1)) + rng.normal(size=(k, 3))  # any velocity, even faster than the tread
    v[5:10] = v_t[5:10]  # moving with the tread: no spin
    for spread in (0.0, 0.5, 2.0):
        got, _ = spin_world(rows, alpha, v, r, spread=spread)
        roll, want = np_launch_spin(rows, alpha, v, r, spread, 7, 5)
        np.testing.assert_allclose(got, want, rtol=2e-6, atol=1e-6 * np.abs(want).max())
        size = np.linalg.norm(roll, axis=1)
        assert np.all(np.linalg.norm(got - roll, axis=1) <= spread * size * (1 + 1e-6) + 1e-12)
        np.testing.assert_array_equal(got[5:10], 0.0)
    once, _ = spin_world(rows, alpha, v, r, spread=0.5)
    again, _ = spin_world(rows, alpha, v, r, spread=0.5)
    other, _ = spin_world(rows, alpha, v, r, spread=0.5, step=8)
    np.testing.assert_array_equal(again, once)  # counter-based: the same draws again, others at another step
    assert np.mean(np.any(other[10:] != again[10:], axis=1)) > 0.9


def test_an_impulse_changes_the_spin_by_its_moment_over_the_inertia(spin_world):
    """kick: omega + (a x J) / I with J = m dv and I = 2/5 m r^2 (the solid sphere); a normal impulse (dv
    along the arm) does not change it; the angular momentum about the contact point is conserved by the
    impulse J there (L = I omega + m x_c x v changes by a x J at the centre, 0 about the contact)."""
    rng = np.random.default_rng(17)
    k = 300
    rows, _ = tires(rng, k)
    alpha = rng.uniform(0.0, 0.5, k)
    r = rng.uniform(0.003, 0.05, k)
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    arms = -r[:, None] * n
    dv = rng.normal(size=(k, 3)) * 3.0
    dv[:20] = n[:20] * rng.normal(size=(20, 1))  # normal impulses
    om0, om1 = spin_world(rows, alpha, dv, r, arms=arms)
    m = 4.0 / 3.0 * np.pi * 2600.0 * r ** 3
    inertia = 0.4 * m * r ** 2
    want = om0 + np.cross(arms, m[:, None] * dv) / inertia[:, None]
    np.testing.assert_allclose(om1, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
    np.testing.assert_allclose(om1[:20], om0[:20], rtol=1e-12, atol=1e-12 * np.abs(om0).max())


# ------------------------------------------------------------------------------------------ in a simulation
def _straight(reverse=False, **launch):
    lead = {"name": "lead", **CAR, "path": {"points": [[6.0, 0.0], [406.0, 0.0]], "speed": 20.0}}
    player = {"name": "player", **CAR, "splash": False, "path": {"points": [[0.0, 0.0], [400.0, 0.0]],
                                                                 "speed": 20.0}}
    if reverse:
        lead["path"] = {"points": [[-6.0, 0.0], [394.0, 0.0]], "speed": 15.0, "reverse": True}
        player["path"] = {**player["path"], "speed": 15.0, "reverse": True}
    return scene(rocks=3000, radius=6.0, bed={"follow": "player"}, sim={"detection": "patch", "dt": 0.004},
                 vehicles=[lead, player], launch=launch)


BASE = _straight()
MODES = {"active": {"sim.stepping": "active"},
         "full": {"sim.stepping": "full", "sim.hash.scope": "all", "sim.hash.reorder_every": 8}}


@pytest.mark.parametrize("reverse", [False, True])
def test_launched_stones_spin_backwards_about_the_axle(reverse):
    """With no lateral scatter and no spin scatter, on a straight path, every stone a tire launches spins about
    the axle, backwards: opposite to the wheel (about -l driving forwards, +l reversing, l = z x heading)."""
    sim = Simulation(_straight(reverse, spread=0.0, spin_spread=0.0), tumble=True)
    spins = []
    for _ in range(100):
        sim.step()
        if sim.last_launches:
            st = sim.state()
            new = sim.rock_arrays()["hit_step"] == sim.step_count
            spins.append(st["angular_velocities"][new])
    st = sim.state()
    f = np.array([math.cos(st["vehicle_headings"][0]), math.sin(st["vehicle_headings"][0])])  # the lead's body
    assert abs(f[0]) > 0.999
    om = np.concatenate(spins).astype(np.float64)
    assert len(om) > 20
    l = np.array([-f[1], f[0], 0.0])
    along = om @ l
    wheel = sim._host.tires_prev.spin[0]  # the lead's rear tires' tread speed: > 0 forwards, < 0 reversing
    assert (wheel < 0) == reverse
    assert np.all(np.sign(along) == -np.sign(wheel)), along
    np.testing.assert_allclose(np.linalg.norm(om - along[:, None] * l, axis=1), 0.0, atol=1e-4 * np.abs(along).max())
    assert 5.0 < np.median(np.abs(along)) < 500.0  # tens of rad/s for gravel at 15-20 m/s


def test_flight_keeps_the_spin_and_the_orientation_follows_it_exactly():
    """No torque in the air: a rock set flying with a spin keeps it, and its orientation is the closed form
    exp(omega t / 2) q0 after any number of steps (f64)."""
    sc = scene_with(BASE, {"sim.precision": "f64", "effects.ground": "none", "effects.recycle": False})
    sim = Simulation(sc, tumble=True)
    rng = np.random.default_rng(3)
    ids = np.arange(5)
    omega = rng.normal(size=(5, 3)) * 30.0
    q0 = random_quats(rng, 5)
    pos = sim.state()["positions"][ids] + [0.0, 0.0, 2.0]
    sim.set_rocks(ids, positions=pos, velocities=np.zeros((5, 3)) + [0.0, 0.0, 8.0], phase=FLYING, spin=omega,
                  orient=q0)
    sim.step(137)
    st = sim.state()
    assert np.all(st["phase"][ids] == FLYING)
    np.testing.assert_array_equal(st["angular_velocities"][ids], omega)
    want = np_quat_mul(np_exp(omega, np.full(5, 137 * sc.sim.dt)), q0)
    assert np.all(1.0 - same_rotation(st["orientations"][ids], want) < 1e-12)


def test_a_bounce_changes_the_spin_by_the_closed_form():
    """A rock falling onto the ground with a horizontal velocity and a spin: in the step of the bounce the
    Coulomb impulse takes dv = v_t,after - v_t,before from the centre's horizontal velocity and adds
    5 (-r z x dv) / (2 r^2) to the spin; the orientation turns with the old spin until the impact and with the
    new one after it (symplectic Euler, no drag, f64); the translation is the same as without tumbling."""
    sc = scene_with(BASE, {"sim.precision": "f64", "effects.drag": "none", "effects.recycle": False,
                           "world.restitution": 0.5, "world.ground_friction": 0.3})
    sims = [Simulation(sc, tumble=True), Simulation(sc)]
    ids = np.arange(3)
    v0 = np.array([[3.0, 1.0, -2.0], [-1.0, 4.0, -5.0], [0.5, -0.2, -1.0]])
    omega0 = np.array([[0.0, 0.0, 0.0], [10.0, -5.0, 3.0], [0.0, 40.0, 0.0]])
    q0 = random_quats(np.random.default_rng(2), 3)
    r = sims[0].state()["radii"][ids]
    z0 = sc.world.ground_z + r + 0.003  # reaches the ground within one step of dt = 4 ms
    for sim in sims:
        pos = sim.state()["positions"][ids].copy()
        pos[:, 2] = z0
        extra = {"spin": omega0, "orient": q0} if sim.plan.spin else {}
        sim.set_rocks(ids, positions=pos, velocities=v0, phase=FLYING, **extra)
        sim.step()
    st, plain = sims[0].state(), sims[1].state()
    for k in ("positions", "velocities", "phase"):
        np.testing.assert_array_equal(st[k], plain[k])
    dt, g = sc.sim.dt, sc.world.gravity
    v1 = v0 + [0.0, 0.0, -g * dt]  # symplectic Euler: v, then x
    depth = r - (z0 - sc.world.ground_z + dt * v1[:, 2])
    assert np.all(depth > 0)
    tau = (-v1[:, 2] - np.sqrt(v1[:, 2] ** 2 - 2.0 * g * depth)) / g
    dv = st["velocities"][ids] - v1
    dv[:, 2] = 0.0
    assert np.all(np.linalg.norm(dv, axis=1) > 0.1)  # the friction acted
    arm = np.array([0.0, 0.0, -1.0]) * r[:, None]
    omega1 = omega0 + 2.5 * np.cross(arm, dv) / (r ** 2)[:, None]
    np.testing.assert_allclose(st["angular_velocities"][ids], omega1, rtol=1e-12, atol=1e-12)
    want = np_quat_mul(np_exp(omega1, tau), np_quat_mul(np_exp(omega0, dt - tau), q0))
    assert np.all(1.0 - same_rotation(st["orientations"][ids], want) < 1e-12)
    assert st["angular_velocities"][0][1] > 0.0  # friction against +x motion spins it about +y, as it would roll


def _rocks_of(data):
    return {k: v for k, v in data.items() if k.startswith("rock_")}


@pytest.mark.parametrize("into", ["active", "full"])
@pytest.mark.parametrize("source", ["active", "full"])
def test_resting_rocks_keep_their_orientation_through_tiles_and_checkpoints(source, into):
    """Both stepping modes give the same spins and orientations bit for bit (active = full); rocks that flew,
    landed and rest keep their orientation over later steps (active stepping: through the tiles) and a
    checkpoint of either mode restores into the other and goes on identically; resting rocks do not spin."""
    sims = {m: Simulation(scene_with(BASE, MODES[m]), tumble=True) for m in {source, into}}
    for s in sims.values():
        s.step(200)
    a, b = sims[source].state(), sims[into].state()
    for k in ("positions", "phase", "orientations", "angular_velocities"):
        assert a[k].tobytes() == b[k].tobytes(), k
    q_start = initial_orientations(BASE.seed, BASE.bed.rocks)
    moved = same_rotation(a["orientations"].astype(np.float64), q_start) < 1.0 - 1e-3
    landed = moved & (a["phase"] == RESTING)
    assert landed.sum() > 10 and (a["phase"] == FLYING).sum() > 5
    assert not a["angular_velocities"][a["phase"] == RESTING].any()
    data = sims[source].checkpoint()
    sims[source].step(40)
    c = sims[source].state()
    del sims, s  # one simulation at a time: other takes the World of one of them (engine/world.py acquire)
    other = Simulation(scene_with(BASE, MODES[into]), tumble=True)
    other.restore(data)
    assert _rocks_of(other.checkpoint()).keys() == _rocks_of(data).keys()
    for k, v in _rocks_of(data).items():
        assert np.asarray(other.checkpoint()[k]).tobytes() == np.asarray(v).tobytes(), k
    other.step(40)
    d = other.state()
    for k in ("positions", "orientations", "angular_velocities"):
        assert c[k].tobytes() == d[k].tobytes(), k
    still = landed & (c["phase"] == RESTING) & np.all(c["positions"] == a["positions"], axis=1)
    assert still.sum() > 10
    assert c["orientations"][still].tobytes() == a["orientations"][still].tobytes()


def test_without_tumbling_nothing_is_allocated_and_positions_do_not_change():
    """A Simulation that does not ask for tumbling has no spin or orientation fields, reports none, and its
    rocks move exactly as those of one that does (the spin never feeds back into the translation); the scene's
    ``tumble = "always"`` asks for them anyway."""
    plain, spun = Simulation(BASE), Simulation(BASE, tumble=True)
    assert not plain.plan.spin and spun.plan.spin
    assert not hasattr(plain.world, "spin") and not hasattr(plain.world, "orient")
    for s in (plain, spun):
        s.step(100)
    a, b = plain.state(), spun.state()
    assert "orientations" not in a and "angular_velocities" not in a
    for k in a:
        if isinstance(a[k], np.ndarray):
            assert a[k].tobytes() == b[k].tobytes(), k
    always = scene_with(BASE, {"effects.tumble": "always"})
    assert Plan.from_scene(always).spin and not Plan.from_scene(scene_with(BASE, {"bed.rocks": 0}), True).spin
    assert "tumble (spin and orientation)" in Plan.from_scene(always).passes()


def test_a_checkpoint_without_orientations_restores_the_initial_ones():
    plain = Simulation(BASE)
    plain.step(20)
    spun = Simulation(BASE, tumble=True)
    spun.restore(plain.checkpoint())
    st = spun.state()
    np.testing.assert_allclose(st["orientations"], initial_orientations(BASE.seed, BASE.bed.rocks), atol=1e-7)
    assert not st["angular_velocities"].any()
    spun.step(5)


def test_sliding_rocks_spin_with_the_friction_and_stop_at_rest():
    """A rock sliding on the ground: each step the friction's impulse adds 5 (-r z x dv) / (2 r^2) to the
    spin; the orientation turns with it; at rest the spin is zero and the orientation stays."""
    sc = scene_with(BASE, {"sim.precision": "f64", "effects.recycle": False})
    sim = Simulation(sc, tumble=True)
    ids = np.array([0])
    r = float(sim.state()["radii"][0])
    q0 = random_quats(np.random.default_rng(4), 1)
    sim.set_rocks(ids, velocities=[[1.0, 0.0, 0.0]], phase=SLIDING, spin=np.zeros((1, 3)), orient=q0)
    sim.step()
    st = sim.state()
    v1 = st["velocities"][0]
    dv = v1 - [1.0, 0.0, 0.0]
    om = 2.5 * np.cross([0.0, 0.0, -r], dv) / r ** 2
    np.testing.assert_allclose(st["angular_velocities"][0], om, rtol=1e-12)
    assert om[1] > 0.0  # friction against +x spins it about +y, the way it would roll
    want = np_quat_mul(np_exp(om[None], np.array([sc.sim.dt])), q0)
    assert 1.0 - same_rotation(st["orientations"][:1], want)[0] < 1e-12
    sim.step(100)
    st2 = sim.state()
    assert st2["phase"][0] == RESTING and not st2["angular_velocities"][0].any()
    q_rest = st2["orientations"][0].copy()
    sim.step(20)
    assert sim.state()["orientations"][0].tobytes() == q_rest.tobytes()
