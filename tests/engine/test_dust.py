"""Dust's kernels (engine/effects/dust.py) against NumPy references written from config/effects/dust.py: the
emission count against the speed law, settling against the Stokes closed form, the fade law, the ring pool,
the random walk's variance, determinism; and off = nothing allocated, the memory estimate unchanged."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import taichi as ti

from scenes_util import scene
from taichi_rocks.config.effects import dust as decl
from taichi_rocks.engine.effects import RUNTIMES, effect_specs
from taichi_rocks.engine.effects.dust import Dust
from taichi_rocks.engine.randomness import uniform01_np
from taichi_rocks.engine.layout import estimate_memory
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.runtime import init_taichi
from taichi_rocks.config.plan import Plan

DT = 0.01


@pytest.fixture(autouse=True, scope="module")
def taichi_on_the_cpu():
    init_taichi("cpu")


def dust_scene(**table):
    """A scene with dust moving every step it is called with (the kernels' tests)."""
    return scene(rocks=0, effects={"dust": True}, dust={"step": 0.0, **table}, world={"ground_z": 0.0})


def pose(x=0.0, speed=10.0, heading=0.0, z=0.0):
    """A vehicle's pose (motion/vehicles.py VehiclePose's fields dust reads); z > 0 puts it in the air."""
    f = np.array([math.cos(heading), math.sin(heading), 0.0])
    return SimpleNamespace(position=np.array([x, 0.0, z]), velocity=speed * f, heading=heading, speed=speed)


def run(d, steps, speed=10.0, origin=np.zeros(3), x0=0.0):
    for k in range(steps):
        d.after_step([pose(x0 + speed * DT * (k + 1), speed)], origin, k + 1, DT)
    return d.arrays(origin)


def test_every_declared_effect_has_its_kernels():
    from taichi_rocks.config.effects import EFFECTS
    assert set(RUNTIMES) == set(EFFECTS)


@pytest.mark.parametrize("speed", [0.0, 2.9, 3.0, 4.5, 12.0, 30.0])
def test_emission_count_follows_the_speed_law(speed):
    table = dict(rate=2.0, lift_speed=3.0, capacity=1 << 16, life=100.0, fade=100.0)
    d = Dust(dust_scene(**table), ti.f32)
    steps = 50
    got = run(d, steps, speed)
    carried, expect = 0.0, 0
    for _ in range(steps):  # the host's law, step by step: N' dt carried, whole particles leave
        carried += table["rate"] * max(speed - table["lift_speed"], 0.0) ** 2 * DT
        n = math.floor(carried)
        carried -= n
        expect += n
    assert d.emitted == expect == len(got["positions"])
    assert expect == (0 if speed <= 3.0 else int(np.floor(steps * DT * 2.0 * (speed - 3.0) ** 2 + 1e-9)))


def test_new_particles_start_in_the_box_behind_the_vehicle():
    sc = dust_scene(rate=50.0, lift_speed=0.0, spread=1.0, height=0.4, life=100.0, fade=100.0)
    d = Dust(sc, ti.f32)
    d.after_step([pose(0.0, 10.0)], np.zeros(3), 1, DT)
    p = d.arrays(np.zeros(3))["positions"]
    v = sc.vehicles[0]
    assert len(p) == 50
    assert np.all(p[:, 0] <= -v.length / 2 + 1e-5) and np.all(p[:, 0] >= -v.length / 2 - 1.0 - 1e-5)
    assert np.all(np.abs(p[:, 1]) <= v.width / 2 + 1e-5) and np.all((p[:, 2] >= 0) & (p[:, 2] <= 0.4 + 1e-5))


def test_settling_follows_stokes():
    """No wake, no lift, no diffusion: v_z(t) = -v_s (1 - exp(-t / tau_p)), v_s = rho_p g d^2 / (18 mu); the
    height against the same exact-exponential scheme in float64."""
    sc = dust_scene(rate=100.0, lift_speed=0.0, carry=0.0, lift=0.0, diffusion=0.0, diameter=1e-4,
                    density=2000.0, height=0.0, life=100.0, fade=100.0)
    d = Dust(sc, ti.f32)
    origin = np.array([3.0, 0.0, 20.0])  # any origin: the ground is at world z = 0, the particle starts at 50 m
    d.after_step([pose(0.0, 1.0, z=50.0)], origin, 1, DT)  # 100 (1 m/s)^2 dt: one particle
    tau = 2000.0 * 1e-8 / (18 * sc.world.air_viscosity)
    vs = decl.settling_velocity(sc.dust, sc.world.gravity, sc.world.air_viscosity)
    assert vs == pytest.approx(tau * sc.world.gravity)
    z, v = 50.0, 0.0
    for k in range(200):
        d.after_step([pose(0.0, 0.0)], origin, k + 2, DT)
        a = math.exp(-DT / tau)
        v = v * a - vs * (1 - a)
        z += v * DT
    got = d.arrays(origin)
    (pz,) = got["positions"][:, 2]
    t = 200 * DT
    assert v == pytest.approx(-vs * (1 - math.exp(-t / tau)), rel=1e-9)
    assert pz == pytest.approx(z, abs=2e-4)
    assert z < 50.0 - 0.9 * vs * (t - tau)


def test_fade_law_and_life():
    sc = dust_scene(rate=100.0, lift_speed=0.0, fade=0.5, life=1.0, opacity=0.8)
    d = Dust(sc, ti.f32)
    d.after_step([pose(0.0, 1.0, z=10.0)], np.zeros(3), 1, DT)  # one particle, age 0
    for k, steps in enumerate([10, 40, 30]):
        for _ in range(steps):
            d.after_step([pose(0.0, 0.0)], np.zeros(3), 2, DT)
        age = DT * sum([10, 40, 30][:k + 1])
        got = d.arrays(np.zeros(3))["opacity"]
        if age < 1.0:
            assert got == pytest.approx([0.8 * math.exp(-age / 0.5)], rel=1e-5)
    d.after_step([pose(0.0, 0.0)], np.zeros(3), 2, 0.25)
    assert len(d.arrays(np.zeros(3))["opacity"]) == 0  # age 1.05 s > life: gone


def test_the_ring_keeps_a_constant_count_of_the_newest():
    sc = dust_scene(rate=10.0, lift_speed=0.0, capacity=64, life=100.0, fade=100.0, diffusion=0.0, carry=0.0,
                    lift=0.0, height=0.0, spread=0.0)
    d = Dust(sc, ti.f32)
    counts = []
    for k in range(40):  # 10 * 10^2 * 0.01 = 10 particles a step: 400 in all
        d.after_step([pose(float(k), 10.0)], np.zeros(3), k + 1, DT)
        counts.append(len(d.arrays(np.zeros(3))["positions"]))
    assert counts[:6] == [10, 20, 30, 40, 50, 60] and set(counts[7:]) == {64}
    assert d.emitted == 400
    x = d.arrays(np.zeros(3))["positions"][:, 0]
    # the newest 64 (steps 34..39: 4 of step 33) were emitted behind positions 33..39
    assert x.min() >= 33 - sc.vehicles[0].length / 2 - 1e-4


def test_random_walk_variance_is_2_k_t():
    K = 0.5
    sc = dust_scene(rate=1e4, lift_speed=0.0, capacity=20000, diffusion=K, carry=0.0, lift=0.0, spread=0.0,
                    height=0.0, life=100.0, fade=100.0, diameter=1e-6)
    origin = np.zeros(3)
    d2 = Dust(sc, ti.f32)
    d2.after_step([pose(0.0, 4.0, z=100.0)], origin, 1, DT)  # 1e4 4^2 dt: 1600 particles at once, 100 m up
    for k in range(100):
        d2.after_step([pose(0.0, 0.0)], origin, k + 2, DT)
    p2 = d2.arrays(origin)["positions"]
    assert len(p2) == 1600
    var_y = float(np.var(p2[:, 1]))  # they start on one line across y: var of the start (w^2/3) + 2 K t
    start = sc.vehicles[0].width ** 2 / 12.0
    assert var_y - start == pytest.approx(2 * K * 1.0, rel=0.15)


def test_same_seed_same_bits_other_seed_other_bits():
    def positions(seed):
        sc = scene(rocks=0, effects={"dust": True}, dust={"rate": 5.0, "step": 0.0}, seed=seed)
        d = Dust(sc, ti.f32)
        return run(d, 30, 15.0)["positions"]

    a, b, c = positions(4), positions(4), positions(5)
    assert a.tobytes() == b.tobytes() and len(a) > 100
    assert a.shape == c.shape and not np.array_equal(a, c)


def test_off_allocates_nothing_and_on_counts_the_pool():
    off = scene(rocks=500)
    on = scene(rocks=500, effects={"dust": True}, dust={"capacity": 1000})
    assert effect_specs(off, Plan.from_scene(off)) == []
    assert estimate_memory(on) - estimate_memory(off) == 1000 * (3 + 3 + 3 + 1) * 4
    sim = Simulation(off)
    assert sim.plan.effects == () and sim.effect_arrays() == {}
    sim.step(3)
    assert sim.effect_arrays() == {}


def test_a_simulation_with_dust_emits_behind_the_car_and_a_restore_to_the_start_clears_it():
    sim = Simulation(scene(rocks=200, effects={"dust": True}, dust={"rate": 1.0}))  # its own step: 1/60 s
    saved = sim.checkpoint()
    sim.advance_to(0.5)
    d = sim.effect_arrays()["dust"]
    car = sim.vehicle_poses()[0].position
    assert len(d["positions"]) > 10 and np.all(d["positions"][:, 0] < car[0])
    sim.restore(saved)
    assert len(sim.effect_arrays()["dust"]["positions"]) == 0


def test_checkpoints_carry_the_dust_and_a_restored_run_goes_on_bit_identically():
    """The dust's ring, its carried fractions, particle count and pending time travel in a checkpoint (through a
    file too): a fresh simulation restored from it, and the same one sent back to it, reach the same dust bits
    as the run that went on. Its own step (1/60 s) is not a whole number of steps (4 ms): a step is pending."""
    import io

    sc = scene(rocks=200, effects={"dust": True}, dust={"rate": 3.0, "diffusion": 0.5})
    sim = Simulation(sc)
    sim.advance_to(0.45)
    cp = sim.checkpoint()
    assert cp["dust_pending"] > 0 and cp["dust_emitted"] > 50 and cp["dust_pos"].shape == (sc.dust.capacity, 3)
    buf = io.BytesIO()
    np.savez(buf, **cp)
    sim.advance_to(0.9)
    want = sim.effect_arrays()["dust"]
    again = Simulation(sc)
    again.restore(np.load(io.BytesIO(buf.getvalue())))
    assert again.effect_arrays()["dust"]["positions"].tobytes() == _live_positions(cp, sim)
    again.advance_to(0.9)
    sim.restore(cp)
    sim.advance_to(0.9)
    for other in (again, sim):
        got = other.effect_arrays()["dust"]
        assert len(got["positions"]) == len(want["positions"]) > 100
        assert got["positions"].tobytes() == want["positions"].tobytes()
        assert got["opacity"].tobytes() == want["opacity"].tobytes()


def _live_positions(cp, sim) -> bytes:
    """The live particles' world positions of checkpoint ``cp`` (its ring: age in [0, life)), as bytes."""
    age, life = cp["dust_age"], sim.scene.dust.life
    live = (age >= 0) & (age < life)
    return (cp["dust_pos"][live].astype(np.float64) + cp["origin"]).tobytes()


def test_a_checkpoint_with_bad_dust_is_refused_and_changes_nothing():
    sim = Simulation(scene(rocks=200, effects={"dust": True}, dust={"rate": 3.0}))
    sim.advance_to(0.3)
    cp = sim.checkpoint()
    sim.advance_to(0.4)
    before = sim.effect_arrays()["dust"]["positions"].tobytes(), sim.time
    for key, bad in (("dust_pos", cp["dust_pos"][:10]), ("dust_age", np.full_like(cp["dust_age"], np.nan)),
                     ("dust_carried", np.array([2.0]))):
        with pytest.raises(ValueError, match=f"checkpoint: {key}"):
            sim.restore({**cp, key: bad})
    with pytest.raises(ValueError, match="checkpoint: no dust_emitted"):
        sim.restore({k: v for k, v in cp.items() if k != "dust_emitted"})
    assert (sim.effect_arrays()["dust"]["positions"].tobytes(), sim.time) == before


def test_more_particles_than_the_ring_holds_in_a_step_places_the_newest_in_their_own_slots():
    """10^10 particles in one step (rate 10^4 at 10^4 m/s): past an int32, and 10^10 times the ring. The ring
    gets exactly the newest ``capacity`` (particle k in slot k mod capacity, from k's random draws), at once."""
    sc = dust_scene(rate=1e4, lift_speed=0.0, capacity=64, life=100.0, fade=100.0, spread=1.0, height=0.4)
    d = Dust(sc, ti.f32)
    d.after_step([pose(0.0, 1e4)], np.zeros(3), 1, DT)
    n = 10 ** 10
    assert d.emitted == n
    got = d.arrays(np.zeros(3))["positions"]  # slot order: slot k holds particle number n - 64 + ... = k mod 64
    car, seed = sc.vehicles[0], sc.seed
    want = np.zeros((64, 3))
    for number in range(n - 64, n):
        pid = number % 2 ** 32
        u = [float(uniform01_np(seed, pid, 1, s)) for s in (decl.S_ACROSS, decl.S_ALONG, decl.S_UP)]
        want[number % 64] = (-(car.length / 2 + 1.0 * u[1]), car.width / 2 * (2 * u[0] - 1), 0.4 * u[2])
    np.testing.assert_allclose(got, want, atol=1e-4)


def test_newest_leaves_out_the_oldest_particles_of_a_step():
    from taichi_rocks.engine.effects.dust import newest

    assert newest(np.array([3, 4]), 10).tolist() == [3, 4]  # all fit
    assert newest(np.array([3, 4]), 5).tolist() == [1, 4]  # the first source's 2 oldest left out
    assert newest(np.array([3, 4, 2]), 2).tolist() == [0, 0, 2]
    assert newest(np.array([0, 10 ** 12]), 8).tolist() == [0, 8]


def test_dust_drifts_on_while_the_rocks_coast():
    """Once the vehicles stop for good, steps coast as one launch; dust keeps drifting and settling."""
    car = {"name": "car", "path": {"points": [[0.0, 0.0], [20.0, 0.0]], "speed": [12.0, 0.0]}}
    sim = Simulation(scene(rocks=200, vehicles=[car], effects={"dust": True},
                           dust={"rate": 5.0, "life": 60.0, "fade": 60.0, "diffusion": 0.0}))
    sim.advance_to(4.0)  # stopped after 20 m at a mean 6 m/s: 3.3 s
    a = sim.effect_arrays()["dust"]["positions"]
    sim.advance_to(6.0)
    b = sim.effect_arrays()["dust"]["positions"]
    assert sim.steps_coasted > 0 and len(a) == len(b) > 10
    assert np.all(b[:, 2] >= sim.scene.world.ground_z) and np.any(np.abs(b - a) > 1e-3)  # still moving


def test_its_own_step_moves_after_whole_steps_adding_up_to_it():
    d = Dust(dust_scene(rate=100.0, lift_speed=0.0, step=0.025, life=100.0, fade=100.0), ti.f32)
    emitted = []
    for k in range(10):  # 0.01 s steps: the dust moves at the 3rd, 6th and 9th (0.03 s each)
        d.after_step([pose(0.0, 1.0, z=10.0)], np.zeros(3), k + 1, DT)
        emitted.append(d.emitted)
    assert emitted == [0, 0, 3, 3, 3, 6, 6, 6, 9, 9]
    assert d.pending == pytest.approx(0.01)


def reference(sc, poses, steps_dt, seed):
    """A NumPy twin of config/effects/dust.py without diffusion: the emission box from the same hashes
    (engine/randomness.py uniform01_np), then the exact relaxation towards the decaying wake plus wind."""
    t, w = sc.dust, sc.world
    tau = t.density * t.diameter ** 2 / (18 * w.air_viscosity) if w.air_viscosity > 0 else math.inf
    car = sc.vehicles[0]
    pos, vel, wake, age = [], [], [], []
    carried, number = 0.0, 0
    for k, (p, dt) in enumerate(zip(poses, steps_dt)):
        for i in range(len(pos)):  # move, then emit
            if pos[i][2] > w.ground_z:
                u = wake[i] * math.exp(-age[i] / t.wake_time) + np.array([*t.wind, 0.0])
                a = math.exp(-dt / tau) if math.isfinite(tau) else 1.0
                b = dt if not math.isfinite(tau) else tau * (1 - a)
                v = u + (vel[i] - u) * a - np.array([0, 0, w.gravity * b])
                x = pos[i] + v * dt
                if x[2] <= w.ground_z:
                    x[2], v = w.ground_z, np.zeros(3)
                pos[i], vel[i] = x, v
            age[i] += dt
        carried += decl.emission_rate(p.speed, t) * dt
        n = math.floor(carried)
        carried -= n
        f = np.array([math.cos(p.heading), math.sin(p.heading), 0.0])
        side = np.array([-f[1], f[0], 0.0])
        for j in range(n):
            pid = number + j
            u = [float(uniform01_np(seed, pid, k + 1, s)) for s in (decl.S_ACROSS, decl.S_ALONG, decl.S_UP,
                                                                      decl.S_LIFT)]
            x = (p.position - f * (car.length / 2 + t.spread * u[1]) + side * (car.width / 2 * (2 * u[0] - 1))
                 + np.array([0, 0, t.height * u[2]]))
            wk = np.array([t.carry * p.velocity[0], t.carry * p.velocity[1], t.lift * p.speed * (0.5 + u[3])])
            pos.append(x), vel.append(wk.copy()), wake.append(wk), age.append(0.0)
        number += n
    return np.array(pos), np.array([t.opacity * math.exp(-a / t.fade) for a in age])


@pytest.mark.parametrize("heading, viscosity, wind", [(0.0, 1.81e-5, (0.0, 0.0)), (1.9, 1.81e-5, (3.0, -1.0)),
                                                      (-2.5, 0.0, (0.0, 2.0))])
def test_trajectories_match_the_numpy_twin(heading, viscosity, wind):
    """Any heading, a wind, and no air viscosity (no drag: free fall) against the reference above."""
    sc = scene(rocks=0, seed=7, effects={"dust": True}, world={"ground_z": 0.0, "air_viscosity": viscosity},
               dust={"step": 0.0, "rate": 8.0, "diffusion": 0.0, "wind": list(wind), "diameter": 5e-5,
                     "life": 100.0, "fade": 2.0})
    d = Dust(sc, ti.f32)
    poses = [pose(0.0, 9.0 - 0.1 * k, heading, z=2.0) for k in range(40)]
    for k, p in enumerate(poses):
        d.after_step([p], np.zeros(3), k + 1, DT)
    got = d.arrays(np.zeros(3))
    want, alpha = reference(sc, poses, [DT] * len(poses), 7)
    assert len(got["positions"]) == len(want) > 50
    np.testing.assert_allclose(got["positions"], want, atol=2e-4)
    np.testing.assert_allclose(got["opacity"], alpha, rtol=2e-5)
