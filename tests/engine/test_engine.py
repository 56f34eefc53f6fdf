"""Launch rules, flight against closed forms, effect switches, reproducibility, far from the origin."""

import gc
import warnings

import numpy as np
import pytest
import taichi as ti

from scenes_util import scene
from taichi_rocks.engine.simulation import Simulation
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

    @ti.kernel
    def run(k: ti.i32):
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
        run(k)
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
    """(the simulation, its state after ``steps``); ``run_states(...)[1]`` lets the simulation go at once, so that
    the next one of the same layout takes its World from the pool."""
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
    del a  # b takes its World, zeroed (engine/world.py acquire): a restore into a World used before
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
        """The states at ``times`` and after 777 more steps, and the steps coasted; one run after the other, so
        that the second takes the first's World (engine/world.py acquire) instead of compiling its own."""
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


def test_a_simulation_dropped_in_a_reference_cycle_hands_on_its_world():
    """A dropped Simulation that a reference cycle still holds (the collector has not run) does not cost the next
    one of its layout a new World: the pool collects before it builds one (engine/trees.py Pool.lease)."""
    sc = scene(rocks=1700, radius=5.0, sim={"detection": "swept"})  # the layout of the test below
    a = Simulation(sc)
    a.cycle = a  # held by itself alone once dropped
    used = a.world
    gc.disable()  # no collection but the pool's own
    try:
        del a
        b = Simulation(sc)
    finally:
        gc.enable()
    assert b.world is used


def test_released_fields_are_reused_zeroed_and_never_shared():
    """A Simulation no longer referenced hands its World (fields and compiled kernels) to the next one of the
    same layout, zeroed (every bit: no NaN or -0.0 left): the run is bit-identical to a fresh World's; two live
    simulations never share."""
    import gc

    sc = scene(rocks=1700, radius=5.0, sim={"detection": "swept"})  # a layout of its own in this suite
    a = Simulation(sc)
    a.step(80)
    sa = a.state()
    assert sa["launches_total"] > 0
    used = a.world
    b = Simulation(sc)
    assert b.world is not used  # a is alive
    del a
    gc.collect()
    c = Simulation(sc)
    assert c.world is used  # handed on
    for sim in (b, c):
        sim.step(80)
        s = sim.state()
        assert s["launches_total"] == sa["launches_total"]
        for k in ("positions", "velocities", "phase"):
            np.testing.assert_array_equal(s[k], sa[k])
    # what a World is handed on with: zeros, their bits too (no NaN or -0.0 of the last owner: f * 0 keeps both),
    # in every element of every field, whatever its shape (world._zero_fields indexes them all from one loop)
    from taichi_rocks.engine.world import _zero

    fs = used.fields()
    assert {len(f.shape) for f in fs} == {0, 1, 2, 3}  # every indexing the zeroing has: scalars to 3-D (step_rays)
    total = sum(int(np.prod(f.shape)) for f in fs)
    with warnings.catch_warnings():  # static loops over every field: Taichi warns past 32 of them
        warnings.simplefilter("ignore", SyntaxWarning)
        _soil(used)
        assert _dirty(used) == total  # the garbage is in every element, its bits not zero
        _zero(used)
        assert _dirty(used) == 0


@ti.func
def _bits_nonzero(x, dt: ti.template()):
    """1 if any bit of ``x`` (a scalar of type ``dt``) is set: NaN, -0.0 and -7 are, 0 is not."""
    out = 0
    if ti.static(dt == ti.f32):
        out = ti.bit_cast(x, ti.i32) != 0
    elif ti.static(dt == ti.f64):
        out = ti.bit_cast(x, ti.i64) != 0
    else:
        out = x != 0
    return out


@ti.kernel
def _soil(w: ti.template()):
    """Garbage a World's last owner could leave, in every element of every field: NaN in reals, -0.0 in the
    last component of vectors (a sign bit alone), -7 in integers. A loop per field, as world.py once zeroed."""
    for f in ti.static(w.fields()):
        for I in ti.grouped(f):
            if ti.static(f.dtype in (ti.f32, ti.f64)):
                if ti.static(isinstance(f, ti.lang.matrix.MatrixField)):
                    v = f[I]
                    for c in ti.static(range(f.n)):
                        v[c] = ti.cast(-0.0, f.dtype) if ti.static(c == f.n - 1) else ti.math.nan
                    f[I] = v
                else:
                    f[I] = ti.math.nan
            else:
                if ti.static(isinstance(f, ti.lang.matrix.MatrixField)):
                    f[I] = ti.Vector([-7] * f.n, dt=f.dtype)
                else:
                    f[I] = -7


@ti.kernel
def _dirty(w: ti.template()) -> ti.i64:
    """Elements of the World's fields with a bit set in any component."""
    n = ti.i64(0)
    for f in ti.static(w.fields()):
        for I in ti.grouped(f):
            bad = 0
            if ti.static(isinstance(f, ti.lang.matrix.MatrixField)):
                for c in ti.static(range(f.n)):
                    bad |= _bits_nonzero(f[I][c], f.dtype)
            else:
                bad = _bits_nonzero(f[I], f.dtype)
            n += bad
    return n
