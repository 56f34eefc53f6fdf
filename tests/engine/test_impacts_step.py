"""The impacts pass in the step (engine/impact_pass.py): a car 6 m behind another at 20 m/s on chippings.

- after every step no stone's centre is closer to a part of a body than its radius (the phase-1 NumPy
  reference ``Hull``, independent of the kernel), to 1e-5 m;
- the events through ``sim.impacts()``: consistent with their own definitions, the thrower set at launch
  (only the car in front throws), full and active stepping give the same arrays, a second run gives them
  again, draining every step keeps the host's list and the device buffer empty;
- an overflow (a buffer of 32 events, drained only at the end) is counted: kept + dropped = every event, and a
  restore keeps the count of its checkpoint;
- an elastic, frictionless hit (e = 1, mu = 0) keeps the speed relative to the body and reverses its normal part;
- ``simulate``'s run file and CSV hold the same events; Vulkan (a subprocess) gives the same events as the CPU,
  every field of them (the scene with 4 ms steps on both: 33 hits);
- active stepping's rows on the device, taken from its lookahead batch, have the bits full stepping is given.

One World layout for every case (its kernels compile once per stepping mode): the restitution, friction
and step are runtime parameters, the drain interval a host setting.
"""

import csv

import numpy as np
import pytest

from cli_util import reaped, start_cli
from impacts_util import Hull
from taichi_rocks import load_run
from taichi_rocks.app.simulate import simulate_scene
from taichi_rocks.config.impacts import DAMAGE_CLASSES
from taichi_rocks.config.scene import load_scene, scene_with
from taichi_rocks.engine import rocks
from taichi_rocks.engine.events import EVENT_DTYPE
from taichi_rocks.engine.impact_pass import pose_rows, time_row
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.motion.bodies import LABELS, body_parts

STEPS = 500
SCENE = """
name = "under_fire"
duration = 1.2
seed = 3

[effects]
impacts = true

[impacts]
capacity = 32

[bed]
radius = 10.0
rocks = 8000
rock_radius = [0.004, 0.015]

[sim]
detection = "patch"

[[vehicle]]
name = "player"
splash = false
path = { points = [[0.0, 0.0], [260.0, 0.0]], speed = 20.0 }

[[vehicle]]
name = "lead"
path = { points = [[6.0, 0.0], [266.0, 0.0]], speed = 20.0 }
"""


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("impacts") / "under_fire.toml"
    path.write_text(SCENE)
    return path


@pytest.fixture(scope="module")
def scene(scene_file):
    return load_scene(scene_file)


def _hulls(sc):
    """Per vehicle hit: its parts' Hulls in the body frame (x forward, y left, z up from the world's zero)."""
    gz = float(sc.world.ground_z)
    return [[Hull(p.corners()) for p in body_parts(v, gz).parts] for v in sc.vehicles]


def _closest_gap(sim, hulls) -> float:
    """The least (distance to a part - radius) over the moving rocks and every part of every body now (a
    stone and the body of the vehicle that threw it excepted: that is the fenders' business)."""
    arrays = sim.rock_arrays()  # read once: the state's arrays and the throwers
    st = rocks.state_arrays(sim.world, arrays, sim.origin)
    moving = st["phase"] != 0
    x, r = st["positions"][moving], st["radii"][moving]
    thrower = arrays["thrower"][moving]
    worst = np.inf
    for v, (pose, parts) in enumerate(zip(sim.fleet.poses(sim.time), hulls)):
        c, s = np.cos(pose.heading), np.sin(pose.heading)
        d = x - pose.position
        p = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], x[:, 2]])
        near = (np.hypot(p[:, 0], p[:, 1]) < 8.0) & (thrower != v)
        for hull in parts:
            if near.any():
                worst = min(worst, float(np.min(hull.distance(p[near]) - r[near])))
    return worst


def _same(a, b) -> bool:
    """Equal events; ``time`` to 1e-6 s (the device keeps it relative to the last drain, in float32, so
    draining at other steps rounds it differently)."""
    if len(a) != len(b):
        return False
    rest = [k for k in EVENT_DTYPE.names if k != "time"]
    return all(np.array_equal(a[k], b[k]) for k in rest) and np.allclose(a["time"], b["time"], rtol=0, atol=1e-6)


def _run(sc, drain_every_step=True, check=None):
    sim = Simulation(sc)
    events, flat = [], True
    for _ in range(STEPS):
        sim.step()
        if drain_every_step:
            events.append(sim.impacts())
            flat &= not sim._impacts.chunks and int(sim.world.events.count[None]) == 0
        if check is not None:
            check(sim)
    if not drain_every_step:
        events.append(sim.impacts())
    return sim, np.concatenate(events), flat


@pytest.fixture(scope="module")
def full_run(scene):
    hulls = _hulls(scene)
    gaps = []
    sim, events, flat = _run(scene, check=lambda s: gaps.append(_closest_gap(s, hulls)))
    return dict(events=events, gaps=np.array(gaps), flat=flat, dropped=sim.impacts_dropped)


def test_no_stone_inside_a_body_after_any_step(full_run):
    assert len(full_run["gaps"]) == STEPS
    assert np.min(full_run["gaps"]) >= -1e-5, np.argmin(full_run["gaps"])


def test_events_are_what_they_say(full_run, scene):
    ev = full_run["events"]
    assert ev.dtype == EVENT_DTYPE
    assert len(ev) >= 40 and full_run["dropped"] == 0
    assert np.all(ev["vehicle"] == 0) and np.all(ev["thrower"] == 1)  # the car in front threw every one
    dt = scene.sim.dt
    assert np.all(ev["time"] <= ev["step"] * dt + 1e-6) and np.all(ev["time"] >= (ev["step"] - 1) * dt - 1e-6)
    m = 4.0 / 3.0 * np.pi * scene.bed.density * ev["radius"] ** 3
    np.testing.assert_allclose(ev["normal_momentum"], m * ev["normal_speed"], rtol=1e-5)
    np.testing.assert_allclose(ev["energy"], 0.5 * m * ev["speed"] ** 2, rtol=1e-5)
    assert np.all(ev["normal_speed"] <= ev["speed"] * (1 + 1e-6)) and np.all(ev["normal_speed"] >= 0.5)
    np.testing.assert_allclose(np.linalg.norm(ev["normal"], axis=1), 1.0, atol=1e-5)
    key = np.lexsort((ev["vehicle"], ev["rock"], ev["step"]))
    assert np.array_equal(key, np.arange(len(ev)))  # in (step, rock, vehicle) order
    assert set(ev["part"]) <= set(range(len(LABELS))) and set(ev["damage"]) <= set(range(len(DAMAGE_CLASSES)))


def test_draining_every_step_keeps_memory_flat(full_run):
    assert full_run["flat"]


def test_run_after_run_and_active_stepping_give_the_same_events(full_run, scene):
    _, again, _ = _run(scene)
    assert np.array_equal(again, full_run["events"])
    _, active, _ = _run(scene_with(scene, {"sim.stepping": "active"}))
    assert np.array_equal(active, full_run["events"])


def test_overflow_is_counted(full_run, scene):
    sim = Simulation(scene)
    sim._impacts.every = 10 ** 9  # never drained before the end: 32 places for every event of the run
    for _ in range(STEPS):
        sim.step()
    kept = sim.impacts()
    assert len(kept) == 32
    assert sim.impacts_dropped == len(full_run["events"]) - 32 > 0


def test_a_restore_keeps_the_events_dropped_before_its_checkpoint(full_run, scene):
    """impacts_dropped after restore() is the checkpoint's count (the steps after it drop theirs again), in this
    simulation and in a fresh one; a run restored and finished drops what the whole run drops."""
    sim = Simulation(scene)
    sim._impacts.every = 10 ** 9  # drained only by the checkpoint and at the end: the 32 places overflow
    sim.step(300)
    cp = sim.checkpoint()
    at_cp = sim.impacts_dropped
    assert at_cp > 0 and int(cp["impacts_dropped"]) == at_cp
    sim.step(STEPS - 300)
    sim.impacts()
    whole = sim.impacts_dropped
    assert whole > at_cp
    fresh = Simulation(scene)
    fresh._impacts.every = 10 ** 9
    for other in (sim, fresh):
        other.restore(cp)
        assert other.impacts_dropped == at_cp
        other.step(STEPS - 300)
        other.impacts()
        assert other.impacts_dropped == whole


def test_elastic_frictionless_hit_keeps_the_relative_speed(scene):
    sc = scene_with(scene, {"impacts.restitution": 1.0, "impacts.friction": 0.0})
    sim = Simulation(sc)
    sim.step(10)
    pose = sim.fleet.poses(sim.time)[0]
    front = max(float(p.corners()[:, 0].max()) for p in body_parts(sc.vehicles[0], 0.0).parts)
    rock = 17
    start = pose.position + np.array([front + 0.3, 0.2, 0.45])
    v = np.array([12.0, 1.0, 0.5])  # the body at 20 m/s: closing at 8 m/s, sliding sideways and up
    sim.set_rocks([rock], positions=start[None], velocities=v[None], phase=np.array([1], np.int8))
    sim.impacts()
    for _ in range(40):
        sim.step()
        ev = sim.impacts()
        ev = ev[ev["rock"] == rock]
        if len(ev):
            break
    assert len(ev) == 1 and LABELS[ev["part"][0]] == "front_bumper"
    st = sim.state()
    body = sim.fleet.poses(sim.time)[0].velocity
    u = st["velocities"][rock] - body
    assert abs(np.linalg.norm(u) - ev["speed"][0]) < 1e-4 * ev["speed"][0]
    assert u[0] > 0  # away from the bumper, its normal part reversed (~8 m/s)
    assert abs(u[0] - ev["normal_speed"][0]) < 2e-2


def test_run_file_and_csv_hold_the_events(full_run, scene, tmp_path):
    out, table = tmp_path / "run.npz", tmp_path / "hits.csv"
    info = simulate_scene(scene, out=out, frames=12, fps=20.0, impacts=table, progress=False)
    ev = load_run(out)["impacts"]
    want = full_run["events"][full_run["events"]["step"] <= round(0.55 / scene.sim.dt)]
    assert _same(ev, want) and np.array_equal(info["impacts"], ev) and len(want) > 10
    with open(table, newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(want)
    for row, e in zip(rows, ev):
        assert row["part"] == LABELS[e["part"]] and row["damage"] == DAMAGE_CLASSES[e["damage"]]
        assert int(row["rock"]) == e["rock"] and float(row["time"]) == e["time"]
        assert float(row["point_z"]) == e["point"][2] and float(row["energy"]) == e["energy"]
    with pytest.raises(FileExistsError):
        simulate_scene(scene, out=tmp_path / "other.npz", frames=2, fps=20.0, impacts=table, progress=False)


# Vulkan on lavapipe takes ~0.1 s a step of this scene however few stones fly (half of it the impacts pass): the
# comparison runs 4 ms steps, which bring the stones onto the car behind in half the steps (33 hits in the 104
# steps to 0.4 s, where 2 ms steps give 36 in the 275 to 0.55 s). The step is a runtime parameter: the same
# World layout. Not further: one stone, launched by the lead's tire at ~0.3 s, flies differently on the two
# backends (2 mm apart a frame later, then decimetres) and hits the car at 0.41 s on Vulkan only.
DT_4MS = 'detection = "patch"\ndt = 0.004\n'


def test_vulkan_gives_the_cpu_events(tmp_path):
    path = tmp_path / "under_fire_4ms.toml"
    assert SCENE.count('detection = "patch"\n') == 1
    path.write_text(SCENE.replace('detection = "patch"\n', DT_4MS))
    frames = dict(frames=9, fps=20.0)
    with reaped(start_cli("simulate", path, "--arch", "vulkan", "--frames", frames["frames"], "--fps",
                          frames["fps"], "--out", tmp_path / "vk.npz", "--impacts", tmp_path / "vk.csv")) as vk:
        # the CPU's run of the same scene here, meanwhile
        info = simulate_scene(load_scene(path), out=tmp_path / "cpu.npz", progress=False, **frames)
        _, err = vk.communicate(timeout=900)
    assert vk.returncode == 0, err[-2000:]
    assert "running on the CPU" not in err
    vk, cpu = load_run(tmp_path / "vk.npz")["impacts"], info["impacts"]
    assert len(cpu) >= 30 and info["impacts_dropped"] == 0
    exact = ("step", "rock", "vehicle", "part", "damage", "thrower")
    close = ("time", "speed", "normal_speed", "normal_momentum", "energy", "radius")
    vectors = ("point", "normal")
    assert set(exact + close + vectors) == set(EVENT_DTYPE.names)  # every field of an event is compared
    for k in exact:
        assert np.array_equal(vk[k], cpu[k]), k
    for k in close:
        np.testing.assert_allclose(vk[k], cpu[k], rtol=1e-4, err_msg=k)
    for k in vectors:
        np.testing.assert_allclose(vk[k], cpu[k], atol=1e-4, err_msg=k)


def test_a_restore_records_the_steps_after_it_again(full_run, scene):
    sim = Simulation(scene)
    sim.step(200)
    saved = sim.checkpoint()
    sim.step(150)
    first = sim.impacts()
    sim.restore(saved)
    sim.step(150)
    again = sim.impacts()
    want = full_run["events"][(full_run["events"]["step"] > 200) & (full_run["events"]["step"] <= 350)]
    assert len(want) > 5 and _same(again, want) and _same(first, full_run["events"][full_run["events"]["step"] <= 350])


def test_active_steps_read_the_rows_full_stepping_gets(scene):
    """Active stepping takes each step's impacts rows from its lookahead batch on the device (engine/stepdata.py
    ``take_bodies``): after every step ``body_rows`` holds the bits of the rows full stepping is given (the
    start time relative to the events' reference time, which a drain moves in the middle of a batch, and
    ``pose_rows``), over batches, drains every 64 steps and a restore."""
    sim = Simulation(scene_with(scene, {"sim.stepping": "active"}))
    targets = sim.plan.targets
    bad, checked = [], 0
    for j in range(230):
        if j == 100:
            saved = sim.checkpoint()
        if j == 150:
            sim.restore(saved)
        prev, t_ref = sim._host.poses, sim.world.events.t_ref
        sim.step()
        want = np.concatenate([time_row(sim._host.time - sim.dt - t_ref),
                               pose_rows(prev, sim._host.poses, targets, sim._host.shift)])
        got = sim.world.body_rows.to_numpy()  # row 0: (the start time, the reference time it is relative to)
        checked += 1
        if got[0, 0].tobytes() != want[0, 0].tobytes() or got[1:].tobytes() != want[1:].tobytes():
            bad.append(sim.step_count)
    assert sim._host_side.ahead.batches >= 3 and sim._impacts.buf.t_ref > 0.0
    assert not bad, f"steps {bad[:5]} differ ({len(bad)} of {checked})"
