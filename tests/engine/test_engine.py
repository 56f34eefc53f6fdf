"""Launch rules, flight against closed forms, effect switches, reproducibility, far from the origin."""

import gc

import numpy as np
import pytest
import taichi as ti

from scenes_util import scene
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.view import world_kernel
from taichi_rocks.engine.world import FLYING, RESTING

pytestmark = pytest.mark.usefixtures("taichi_cpu")


# ------------------------------------------------------------------------------------------ launch rules
@pytest.fixture(scope="module")
def launch_kernel(taichi_cpu):
    from harness import Probe
    from taichi_rocks.engine.launch import uniform
    from taichi_rocks.engine.params import Par

    probe = Probe(np.zeros((1, 3)), [0.02], cell=0.1)
    w = probe.w
    m = 64
    wheel = ti.Vector.field(3, ti.f32, shape=m)
    fwd = ti.Vector.field(2, ti.f32, shape=m)
    spin = ti.field(ti.f32, shape=m)
    mu = ti.field(ti.f32, shape=m)
    out = ti.Vector.field(3, ti.f32, shape=m)

    @world_kernel
    def run(w: ti.template(), k: ti.i32):
        """uniform.wheel_throw over a batch."""
        for i in range(k):
            out[i] = uniform.wheel_throw(w, wheel[i], fwd[i], spin[i], mu[i], 1, i, 7)

    def call(wheel_v, forward, spin_v, mu_v, angle=(30.0, 30.0), spread=0.0):
        par = w.par.to_numpy()
        par[Par.ANGLE_MIN], par[Par.ANGLE_MAX] = np.radians(angle)
        par[Par.SPREAD] = np.radians(spread)
        w.set_params(par)
        k = len(spin_v)
        for f, v, shape in ((wheel, wheel_v, (m, 3)), (fwd, forward, (m, 2)), (spin, spin_v, (m,)), (mu, mu_v, (m,))):
            buf = np.zeros(shape, np.float32)
            buf[:k] = v
            f.from_numpy(buf)
        run(w, k)
        return out.to_numpy()[:k].astype(np.float64)

    return call


def test_launch_matches_rolling_wheel_kinematics(launch_kernel):
    rng = np.random.default_rng(0)
    k = 50
    heading = rng.uniform(-np.pi, np.pi, k)
    fwd = np.column_stack([np.cos(heading), np.sin(heading)])
    speed = rng.uniform(-20, 30, k)
    lateral = rng.uniform(-2, 2, k)
    wheel = np.column_stack([speed * fwd[:, 0] - lateral * fwd[:, 1], speed * fwd[:, 1] + lateral * fwd[:, 0], 0 * speed])
    spin = speed * 1.15
    mu = rng.uniform(0, 1, k)
    a = np.radians(30.0)
    got = launch_kernel(wheel, fwd, spin, mu)
    expect_xy = wheel[:, :2] - (spin * np.cos(a))[:, None] * fwd
    np.testing.assert_allclose(got[:, :2], expect_xy, rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(got[:, 2], mu * np.abs(spin) * np.sin(a), rtol=1e-5, atol=1e-5)


def test_launch_direction_rules(launch_kernel):
    fwd = np.tile([1.0, 0.0], (4, 1))
    v = np.array([5.0, 10.0, 20.0, 30.0])
    wheel = np.column_stack([v, 0 * v, 0 * v])
    out = launch_kernel(wheel, fwd, v * 1.2, np.full(4, 0.6), angle=(10, 40), spread=10)
    rel = out[:, :2] - wheel[:, :2]
    assert np.all(rel[:, 0] < 0), "rocks leave backwards relative to the wheel"
    assert np.all(np.diff(np.linalg.norm(out - wheel, axis=1)) > 0), "faster wheel, faster launch"
    assert np.all(out[:, 2] > 0)
    no_grip = launch_kernel(wheel, fwd, v * 1.2, np.zeros(4))
    assert np.all(no_grip[:, 2] == 0), "zero friction, no lift"
    # reversing: the wheel travels along -heading, rocks leave towards +heading
    back = launch_kernel(-wheel, fwd, -v * 1.2, np.full(4, 0.6))
    assert np.all(back[:, 0] - (-v) > 0) and np.all(back[:, 2] > 0)


def launched(sim, frames=10, per=10):
    """Velocities of rocks the moment they are launched, with the launching vehicle's pose."""
    rows = []
    for _ in range(frames * per):
        before = sim.state()["phase"]
        sim.step()
        st = sim.state()
        new = (before != FLYING) & (st["phase"] == FLYING)
        if new.any():
            rows.append((st["velocities"][new], st["vehicle_headings"][0], sim.vehicle_poses()[0]))
    return rows


def test_turning_throws_rocks_outwards():
    # a left (counter-clockwise) circle of radius 6 m at 10 m/s: the outside of the turn is the right side
    sc = scene(rocks=20000, radius=8.0, vehicles=[{"name": "car", "path": {
        "kind": "circle", "center": [0.0, 0.0], "radius": 6.0, "speed": 10.0}}])
    sim = Simulation(sc)
    lateral = []
    backward = []
    for vel, heading, pose in launched(sim, frames=8):
        fwd = np.array([np.cos(heading), np.sin(heading)])
        left = np.array([-fwd[1], fwd[0]])
        rel = vel[:, :2] - pose.velocity[:2]
        lateral += list(rel @ left)
        backward += list(rel @ fwd)
    assert len(lateral) > 20
    assert np.mean(lateral) < -0.5, np.mean(lateral)  # outward (right of a left turn)
    assert np.mean(np.array(backward) < 0) > 0.95


def test_convoy_like_launches_rise_and_go_backwards():
    sim = Simulation(scene(rocks=8000, radius=8.0))
    rows = launched(sim, frames=12)
    vel = np.concatenate([r[0] for r in rows])
    assert len(vel) > 10
    assert np.all(vel[:, 2] > 0)
    assert np.all(vel[:, 0] - 10.0 < 0)  # the car drives along +x at 10 m/s


def test_parked_vehicle_launches_nothing():
    sim = Simulation(scene(rocks=8000, radius=8.0, vehicles=[{"name": "car", "path": {
        "points": [[0.0, 0.0], [10.0, 0.0]], "speed": 0.0}}]))
    sim.coast = False  # through the tire pass, which sees the still tires on the rocks
    sim.step(100)
    st = sim.state()
    assert sim.launches_total == 0 and np.all(st["phase"] == RESTING)
    assert np.all(np.isfinite(st["vehicle_headings"]))


# ------------------------------------------------------------------------------------------ flight
def flying_rock_sim(integrator, dt, drag="none", ground="none", gravity=True, precision="f64", **world):
    sc = scene(rocks=1, radius=1000.0, effects={"drag": drag, "ground": ground, "gravity": gravity, "recycle": False},
               sim={"dt": dt, "integrator": integrator, "precision": precision},
               world={"air_density": 1.2, **world},
               vehicles=[{"name": "car", "path": {"points": [[0.0, 0.0], [10.0, 0.0]], "speed": 0.0}}])
    sim = Simulation(sc)
    return sim


def launch_one(sim, x0, v0):
    sim.set_rocks([0], positions=[x0], velocities=[v0], phase=FLYING)


@pytest.mark.parametrize("integrator", ["heun", "rk4"])
def test_parabola_is_exact_for_second_order_methods(integrator):
    sim = flying_rock_sim(integrator, 0.01)
    launch_one(sim, [0, 0, 1.0], [3.0, -1.0, 8.0])
    sim.step(200)
    t = sim.time
    expect = np.array([3.0 * t, -1.0 * t, 1.0 + 8.0 * t - 0.5 * 9.81 * t * t])
    np.testing.assert_allclose(sim.state()["positions"][0], expect, atol=1e-9)


def test_symplectic_euler_converges_first_order():
    errs = []
    for dt in (0.01, 0.005):
        sim = flying_rock_sim("symplectic_euler", dt)
        launch_one(sim, [0, 0, 0], [0, 0, 10.0])
        sim.advance_to(1.0)
        errs.append(abs(sim.state()["positions"][0, 2] - (10.0 - 0.5 * 9.81)))
        del sim  # the next dt takes its World
    assert errs[0] / errs[1] == pytest.approx(2.0, rel=0.05)


def test_linear_drag_closed_form():
    sim = flying_rock_sim("rk4", 0.005, drag="linear", gravity=False, air_viscosity=0.5)
    launch_one(sim, [0, 0, 0], [4.0, 0, 0])
    r = sim.state()["radii"][0]
    k = 9 * 0.5 / (2 * sim.scene.bed.density * r * r)
    sim.advance_to(1.0)
    np.testing.assert_allclose(sim.state()["positions"][0, 0], 4.0 / k * (1 - np.exp(-k)), rtol=1e-7)


def test_quadratic_drag_terminal_fall():
    sim = flying_rock_sim("rk4", 0.002, drag="quadratic", air_density=50.0)
    launch_one(sim, [0, 0, 0], [0, 0, 0])
    r = sim.state()["radii"][0]
    kq = 3 * 50.0 * sim.scene.bed.drag_coefficient / (8 * sim.scene.bed.density * r)
    vt = np.sqrt(9.81 / kq)
    sim.advance_to(1.0)
    t = 1.0
    z = -(vt ** 2 / 9.81) * np.log(np.cosh(9.81 * t / vt))
    np.testing.assert_allclose(sim.state()["positions"][0, 2], z, rtol=1e-6)


def test_ground_stop_and_rest():
    sim = flying_rock_sim("symplectic_euler", 0.004, ground="stop")
    launch_one(sim, [0, 0, 2.0], [1.0, 0, 0])
    sim.step(300)
    st = sim.state()
    assert st["phase"][0] == RESTING
    assert st["positions"][0, 2] == pytest.approx(st["radii"][0], abs=1e-12)
    before = st["positions"].copy()
    sim.step(200)
    np.testing.assert_array_equal(sim.state()["positions"], before)


# ------------------------------------------------------------------------------------------ effects
def run_states(sc, steps=150):
    """(the simulation, its state after ``steps``); ``run_states(...)[1]`` lets the simulation go at once, before
    the next one is built."""
    sim = Simulation(sc)
    sim.step(steps)
    return sim, sim.state()


def test_disabled_drag_equals_zero_drag():
    a = run_states(scene(rocks=6000, effects={"drag": "none"}))[1]
    b = run_states(scene(rocks=6000, effects={"drag": "quadratic"}, world={"air_density": 0.0}))[1]
    assert (a["phase"] == FLYING).sum() > 5
    np.testing.assert_array_equal(a["positions"], b["positions"])
    np.testing.assert_array_equal(a["velocities"], b["velocities"])


def test_splash_off_allocates_and_runs_nothing_of_it():
    sim, st = run_states(scene(rocks=3000, effects={"splash": False}))
    assert sim.launches_total == 0 and np.all(st["phase"] == RESTING)
    assert not sim.world.hashed and sim.world.n_tires == 0
    assert sim.plan.passes() == ["recycle"]


def test_reproducible_and_independent_of_memory_order_and_hash_settings():
    sc = scene(rocks=6000)
    a = run_states(sc)[1]
    b = run_states(sc)[1]
    from taichi_rocks.config.scene import scene_with

    c = run_states(scene_with(sc, {"sim.hash.reorder_every": 0}))[1]
    d = run_states(scene_with(sc, {"sim.hash.insert": "aabb"}))[1]
    e = run_states(scene_with(sc, {"sim.hash.scope": "all"}))[1]
    f = run_states(scene_with(sc, {"sim.hash.scope": "all", "sim.hash.insert": "aabb", "sim.hash.table_size": 97}))[1]
    assert a["launches_total"] > 5
    for other in (b, c, d, e, f):
        np.testing.assert_array_equal(a["positions"], other["positions"])
        np.testing.assert_array_equal(a["velocities"], other["velocities"])


def test_far_from_origin_same_relative_motion():
    base = {"name": "car", "path": {"points": [[0.0, 0.0], [400.0, 0.0]], "speed": 10.0}}
    far = {"name": "car", "path": {"points": [[100_000.0, 0.0], [100_400.0, 0.0]], "speed": 10.0}}
    a = run_states(scene(rocks=6000, vehicles=[base]))[1]
    b = run_states(scene(rocks=6000, vehicles=[far]))[1]
    rel_a = a["positions"] - a["vehicle_positions"][0]
    rel_b = b["positions"] - b["vehicle_positions"][0]
    assert a["launches_total"] > 5
    assert a["launches_total"] == b["launches_total"]
    assert np.max(np.abs(rel_a - rel_b)) < 1e-3


def test_checkpoint_restore_continues_bit_identically():
    sc = scene(rocks=6000, vehicles=[{"name": "car", "path": {"kind": "circle", "center": [0.0, 0.0],
                                                               "radius": 5.0, "speed": 8.0}}])
    a = Simulation(sc)
    a.step(60)
    saved = a.checkpoint()
    a.step(80)
    sa = a.state()
    del a  # one simulation at a time: b is built after a is gone
    b = Simulation(sc)
    b.restore(saved)
    b.step(80)
    sb = b.state()
    assert sa["launches_total"] > 5 and sa["launches_total"] == sb["launches_total"]
    for k in ("positions", "velocities", "phase", "bed_center"):
        np.testing.assert_array_equal(sa[k], sb[k])


# ------------------------------------------------------------------------------------------ coasting
def test_coasting_is_bit_identical_to_stepping():
    """Once every vehicle that matters has stopped for good, steps run as one `coast_pass` launch. A car
    brakes to a stop at t = 2 s; rocks thrown just before fly, bounce, slide, leave the bed and are recycled
    while it coasts. Every state, at whole and fractional step times, equals plain stepping bit for bit."""
    sc = scene(rocks=3000, radius=3.0, world={"restitution": 0.4}, sim={"dt": 0.01, "detection": "swept",
                                                                          "integrator": "rk4"},
               effects={"drag": "quadratic"},
               vehicles=[{"name": "car", "path": {"points": [[-2.0, 0.0], [2.0, 0.0]], "speed": [4.0, 0.0]}}])
    rng = np.random.default_rng(5)
    throw = rng.choice(3000, 1000, replace=False)
    vel = np.column_stack([rng.uniform(-6.0, 6.0, (1000, 2)), rng.uniform(0.5, 5.0, 1000)])
    times = (1.9, 1.95, 2.0, 2.0137, 2.5, 4.0)

    def run(coast):
        """The states at ``times`` and after 777 more steps, and the steps coasted; one run after the other (the
        second compiles only what coasting alone runs)."""
        sim = Simulation(sc)
        sim.coast = coast
        if coast:
            assert sim.fleet.still_after(sim._matter) == pytest.approx(2.0)
        states = []
        for t in times:
            sim.advance_to(t)
            if t == 1.9:  # throw a third of the rocks, the same in both
                sim.set_rocks(throw, velocities=vel, phase=FLYING)
            states.append(sim.state())
        sim.step(777)
        return states + [sim.state()], sim.steps_coasted

    coasting, coasted = run(True)
    stepping, stepped_coasting = run(False)
    for t, a, b in zip(times, coasting, stepping):
        assert a["step"] == b["step"] and a["time"] == b["time"]
        for k in ("positions", "velocities", "phase", "bed_center", "launches_total"):
            np.testing.assert_array_equal(a[k], b[k], err_msg=f"{k} at t = {t}")
    a, b = coasting[-1], stepping[-1]
    for k in ("positions", "velocities", "phase"):
        np.testing.assert_array_equal(a[k], b[k])
    assert coasted > 900 and stepped_coasting == 0
    centres = [st["positions"] for st in coasting[:-1]]
    assert a["launches_total"] > 0  # the car launched rocks before it stopped
    thrown = a["positions"][throw]
    r = np.hypot(*(centres[2][throw, :2] - a["bed_center"][:2]).T)
    assert np.sum(r > 3.0 - 1e-9) == 0  # all inside the bed at t = 2.0 ...
    # ... and rocks left the bed while coasting and were recycled: they sit far from where they flew
    far = np.hypot(*(thrown[:, :2] - centres[3][throw, :2]).T) > 1.0
    assert far.sum() > 20, far.sum()
    assert np.all(a["phase"] == RESTING)


def test_a_second_simulation_of_the_layout_compiles_nothing():
    """Kernels compile once per layout and switches, not per World (engine/view.py): a Simulation of another rock
    count and bed size (the same switches), built while the first still lives, compiles no kernel to build, step,
    checkpoint and read its state; and it steps as a fresh one does (its rocks are its own)."""
    from compiles import compiled

    sc = scene(rocks=1700, radius=5.0, sim={"detection": "swept"})
    a = Simulation(sc)
    a.step(80)
    a.state()
    a.checkpoint()
    other = scene(rocks=2300, radius=6.0, sim={"detection": "swept"})
    with compiled() as names:
        b = Simulation(other)
        b.step(80)
        sb, saved = b.state(), b.checkpoint()
    assert names == [], names
    assert b.world.layout == a.world.layout and b.n_rocks != a.n_rocks
    assert sb["launches_total"] > 0
    del a
    c = Simulation(other)
    c.restore(saved)
    c.step(20)
    b.step(20)
    for k in ("positions", "velocities", "phase", "launches_total"):
        np.testing.assert_array_equal(b.state()[k], c.state()[k])


def test_live_simulations_never_share_their_data():
    """Two live Simulations of one scene hold groups of their own: each runs as a fresh one does, and what is
    done to one leaves the other as it was."""
    sc = scene(rocks=1700, radius=5.0, sim={"detection": "swept"})
    a = Simulation(sc)
    a.step(80)
    sa = a.state()
    assert sa["launches_total"] > 0
    b = Simulation(sc)  # a is alive
    assert all(x is not y for x, y in zip(a.world.groups, b.world.groups))
    b.step(80)
    sb = b.state()
    for k in ("positions", "velocities", "phase", "launches_total"):
        np.testing.assert_array_equal(sb[k], sa[k])
    rng = np.random.default_rng(3)
    ids = rng.choice(1700, 300, replace=False)
    b.set_rocks(ids, velocities=rng.uniform(-3.0, 3.0, (300, 3)), phase=FLYING)
    b.step(40)
    now = a.state()
    for k in ("positions", "velocities", "phase", "launches_total"):
        np.testing.assert_array_equal(now[k], sa[k])


def _every_field_world():
    """A World with every optional field (tiles, the re-sort, the tile store with its step inputs, impacts,
    the drawn mirror): fields of 0 to 3 dimensions in every group."""
    from taichi_rocks.engine.world import World

    return World(101, ti.f32, hash_table=1031, hash_entries=101, n_tires=2, substeps=2, ray_capacity=5,
                 reorder=True, tiles=(3, 3), tile_size=0.5, store=(0.5, 4, 8, True), bodies=(2, 3), events=16,
                 drawn=True, parallel_scan=True)


def _bits(a: np.ndarray) -> np.ndarray:
    """Per component of ``a``: is any of its bits set (NaN, -0.0 and -7 are, 0 is not)?"""
    return np.frombuffer(a.tobytes(), f"u{a.dtype.itemsize}") != 0


def test_a_new_world_starts_zeroed():
    """Every bit of every field of a new World is zero, also where a World dropped just before held garbage (NaN,
    -0.0, -7: every bit set that a last owner could leave) in every element of every field: a Simulation relies
    on it for what it does not write (counters, mirrors, buffers)."""
    used = _every_field_world()
    fs = used.fields()
    assert {len(f.shape) for f in fs} == {0, 1, 2, 3}  # scalars to 3-D (step_rays)
    names = sorted(f.name for f in fs)
    for f in fs:
        bad = np.full(f.shape + ((f.n,) if f.n > 1 else ()), -7 if f.np_dtype.kind == "i" else np.nan, f.np_dtype)
        if f.np_dtype.kind == "f" and f.n > 1:
            bad[..., -1] = -0.0
        f.from_numpy(bad)
        assert _bits(f.to_numpy()).all(), f.name  # the garbage is in every component of every element
    del used, fs
    gc.collect()
    for _ in range(2):  # the second World of the same sizes in the memory the first gave back, if any
        w = _every_field_world()
        assert sorted(f.name for f in w.fields()) == names
        for f in w.fields():
            a = f.to_numpy()
            assert a.shape == f.shape + ((f.n,) if f.n > 1 else ()) and not _bits(a).any(), f.name
        del w
        gc.collect()
