"""Live vehicles in the simulation (``Simulation.drive``, motion/live.py): a live vehicle driven with its scripted
twin's poses gives the scripted run to the bit where the same sub-step poses reach the kernels (one step a frame)
and within the run-to-run spread where the steps between frames are interpolated; the bed follows a live player
off the road and recycles ahead of it; a teleport throws no streak; a wheel spinning at twice its rolling rate
throws higher; checkpoints, step-by-step host work and a recorded drive give the same bits; bad input is refused
with the simulation unchanged."""

import math

import numpy as np
import pytest

from scenes_util import scene
from taichi_rocks.config.drivefile import drive_text
from taichi_rocks.config.presets import PRESETS
from taichi_rocks.config.scene import parse_scene, scene_to_dict, scene_with
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.motion import live
from taichi_rocks.motion.live import JUMP_SLACK
from taichi_rocks.motion.paths import WaypointPath

pytestmark = pytest.mark.usefixtures("taichi_cpu")

ROAD = [[0.0, 0.0], [12.0, 0.0], [24.0, 2.5], [36.0, -2.5], [48.0, 2.5], [60.0, 0.0], [400.0, 0.0]]


def _scripted(rocks=4000, dt=None, seed=3, detection="patch", **kw):
    """A splashing player on a winding road and a van behind it that stones hit."""
    vehicles = [{"name": "player", "path": {"points": ROAD, "speed": 12.0}},
                {"name": "van", "splash": False, "path": {"points": [[-6.0, 0.0], [400.0, 0.0]], "speed": 12.0}}]
    sim = {"accuracy": "game", "dt": PRESETS["game"]["dt"]} if dt is None else {"dt": dt}  # game: a step a frame
    sim["detection"] = detection  # the tread's footprint, as the shipped scenes
    return scene(rocks=rocks, radius=8.0, vehicles=vehicles, effects={"impacts": True}, sim=sim, seed=seed, **kw)


def _live(sc, speed=12.0, heading=None):
    """``sc`` with the player live, starting where the road does (its heading there: the spline's)."""
    h = math.degrees(WaypointPath(ROAD, 12.0).pose(0.0).heading) if heading is None else heading
    return scene_with(sc, {"vehicle[0].path": {"kind": "live", "start": [0.0, 0.0], "heading": h, "speed": speed}})


def _same(a, b) -> bool:
    sa, sb = a.state(), b.state()
    return all(np.array_equal(sa[k], sb[k]) for k in ("positions", "velocities", "phase", "bed_center",
                                                      "vehicle_positions", "vehicle_headings"))


def test_driven_with_its_twins_poses_at_the_step_times_a_live_player_gives_the_scripted_run_bit_for_bit():
    sc = _scripted()
    a, b = Simulation(sc), Simulation(_live(sc))
    twin = WaypointPath(ROAD, 12.0)
    for f in range(1, 61):  # one step a frame: the pose given is the pose of the step
        p = twin.pose(b.time + b.dt)
        b.drive("player", p.position, p.heading, speed=p.speed, yaw_rate=p.yaw_rate)
        a.advance_to(f / 60)
        b.advance_to(f / 60)
        assert _same(a, b), f
    assert a.launches_total == b.launches_total > 50
    ea, eb = a.impacts(), b.impacts()
    assert len(ea) and np.array_equal(ea, eb)


def test_between_frames_the_interpolated_poses_differ_from_the_spline_by_micrometres_and_the_launches_little():
    """dt = 4 ms, 60 frames a second: the poses given at the frame times are the twin's to the bit; the 3-4 steps
    between are the Hermite cubic through them, not the road's spline: within 10 um of it on this winding road
    (0.5 um measured). The rocks then part (a chaotic system: a nudge of 1e-6 m does as much, tools/nudge.py),
    and the launches stay within a few percent."""
    sc = _scripted(dt=0.004)
    a, b = Simulation(sc), Simulation(_live(sc))
    twin = WaypointPath(ROAD, 12.0)
    for f in range(1, 91):
        p = twin.pose(f / 60)
        b.drive("player", p.position, p.heading, speed=p.speed, yaw_rate=p.yaw_rate)
        a.advance_to(f / 60)
        b.advance_to(f / 60)
        assert np.array_equal(a.state(rocks=False).vehicle_positions, b.state(rocks=False).vehicle_positions)
    live = b.fleet.paths[0]
    err = max(np.hypot(*(live.pose(t).position - twin.pose(t).position)) for t in np.linspace(0.001, 1.499, 600))
    assert 0.0 < err < 1e-5, err
    assert abs(a.launches_total - b.launches_total) <= 0.05 * a.launches_total + 3, (a.launches_total,
                                                                                      b.launches_total)


def test_the_bed_follows_a_live_player_off_the_road_and_recycles_to_its_leading_edge():
    sim = Simulation(_live(_scripted(rocks=6000), heading=0.0))
    heading, x, y = 0.0, 0.0, 0.0
    ahead = behind = 0
    prev = sim.state().positions
    for f in range(1, 121):  # a 12 m/s turn to the left, a quarter circle and more, off any road
        heading += 0.9 / 60
        x, y = x + 12.0 / 60 * math.cos(heading), y + 12.0 / 60 * math.sin(heading)
        sim.drive("player", (x, y), heading, speed=12.0)
        sim.advance_to(f / 60)
        st = sim.state()
        player = st.vehicle_positions[0]
        assert np.array_equal(st.bed_center, player), f  # the bed's centre is the player's, every frame
        moved = np.linalg.norm((st.positions - prev)[:, :2], axis=1) > 4.0  # recycled: across the bed
        rel = (st.positions[moved] - player)[:, :2] @ np.array([math.cos(heading), math.sin(heading)])
        ahead, behind = ahead + int((rel > 0).sum()), behind + int((rel <= 0).sum())
        prev = st.positions
    assert sim.recycles_total > 1000 and ahead > 0.97 * (ahead + behind), (ahead, behind)
    assert math.hypot(x, y) > 10 and y > 5  # far off the straight road along +x


def _teleport():
    """Launches per frame of a live player at 12 m/s that jumps 5.4 m ahead in frame 31 (a respawn), and the
    positions (world x) of the rocks thrown in that frame; the rear axle's x after the jump. dt = 2 ms: the
    frame's 8-9 steps would sweep the tires along the jump if it were taken for a drive."""
    sc = _live(_scripted(rocks=8000, dt=0.002, bed={"radius": 12.0}), heading=0.0)
    sim = Simulation(sc)
    jump = 2 * 12.0 / 60 + JUMP_SLACK + 4.0  # in one frame at 12 m/s
    counts, xs = [], None
    for f in range(1, 36):
        sim.drive("player", (0.2 * f + (jump if f >= 31 else 0.0), 0.0), 0.0, speed=12.0)
        before = sim.rock_arrays()["hit_step"].copy() if f == 31 else None
        n = sim.launches_total
        sim.advance_to(f / 60)
        counts.append(sim.launches_total - n)
        if before is not None:
            r = sim.rock_arrays()
            thrown = r["hit_step"] != before
            xs = r["pos"][thrown, 0] + sim.origin[0]
    return counts, xs, 6.2 + jump - 0.5 * sc.vehicles[0].wheelbase


def test_a_teleport_throws_no_streak_of_launches_along_the_jump(monkeypatch):
    counts, xs, axle = _teleport()
    assert counts[30] <= max(counts[10:30]) and np.all(np.abs(xs - axle) < 1.0), (counts, xs, axle)
    monkeypatch.setattr(live, "JUMP_SLACK", 1e9)  # the jump taken for a drive: the tires sweep the 5.4 m
    streak, xs, axle = _teleport()
    assert streak[30] > 3 * max(counts[10:30]) and xs.min() < axle - 3.0, (streak, counts)


def _throw_height(wheel_spin_factor, seed):
    """The mean top height (m) of the rocks a live player going straight at 10 m/s threw in 0.5 s (after 0.25 s
    at rest: a standing start), its wheels at ``wheel_spin_factor`` times the rolling rate (None: the rule)."""
    sc = _live(_scripted(rocks=6000, dt=0.002, seed=seed), speed=10.0, heading=0.0)
    sim = Simulation(sc)
    R, g = sc.vehicles[0].tire_radius, sc.world.gravity
    tops = []
    for f in range(1, 31):
        spin = None if wheel_spin_factor is None else wheel_spin_factor * 10.0 / R
        sim.drive("player", (10.0 * f / 60, 0.0), 0.0, speed=10.0, yaw_rate=0.0, wheel_spin=spin)
        sim.advance_to(f / 60)
        st = sim.state()
        flying = (st.phase == 1) & (st.velocities[:, 2] > 0)
        tops += list(st.positions[flying, 2] + st.velocities[flying, 2] ** 2 / (2 * g))
    return float(np.mean(tops)), sim.launches_total


def test_a_wheel_spinning_at_twice_its_rolling_rate_throws_higher():
    for seed in (1, 2):
        rolling, n0 = _throw_height(1.0, seed)
        rule, _ = _throw_height(None, seed)  # the rule: 1 + slip = 1.15 times
        burnout, n2 = _throw_height(2.0, seed)
        assert n0 > 20 and n2 > 20
        assert burnout > 1.5 * rolling and rule > rolling, (seed, rolling, rule, burnout)


def _game(sim, f):
    """A game's drive in frame f (1/30 s frames): a weave off the road with frames not driven, speeds and yaw
    rates left to the engine in half of them, a teleport at frame 40 and a burnout from 20 to 30."""
    if f % 7 == 3:
        return
    t = f / 30
    x, y = 10 * t + (8.0 if f >= 40 else 0.0), 6 * math.sin(t)
    sim.drive("player", (x, y), math.atan2(6 * math.cos(t), 10), None if f % 2 else 11.0, None,
              60.0 if 20 < f < 30 else None)


def _run(sim, frames, start=1):
    out = []
    for f in range(start, frames):
        _game(sim, f)
        sim.advance_to(f / 30)
        out.append(sim.state())
    return out


def _all_same(xs, ys) -> bool:
    return len(xs) == len(ys) and all(np.array_equal(x.positions, y.positions) and np.array_equal(
        x.vehicle_positions, y.vehicle_positions) and x.launches_total == y.launches_total for x, y in zip(xs, ys))


@pytest.fixture(scope="module", params=[0.004, None], ids=["dt 4 ms", "a step a frame"])
def weave(request):
    """The weave at dt = 4 ms (batches of a frame's steps) and at one step a 30 Hz frame (engine/livesteps.py)."""
    sc = _live(_scripted(rocks=3000, dt=request.param or 1 / 30), heading=0.0)
    return sc, _run(Simulation(sc), 60)


def test_checkpoints_and_step_by_step_host_work_continue_a_drive_bit_for_bit(weave):
    sc, whole = weave
    b = Simulation(sc)
    first = _run(b, 25)
    cp = b.checkpoint()
    assert cp.drives is not None and cp.drives.shape[1] == 8
    _run(b, 45, start=25)  # a future that the restore forgets
    b.restore(cp)
    assert _all_same(whole, first + _run(b, 60, start=25))
    c = Simulation(sc)
    c.restore({**cp})  # into a Simulation that never drove
    assert _all_same(whole[24:], _run(c, 60, start=25))
    d = Simulation(sc)
    d.lookahead = 0
    assert _all_same(whole, _run(d, 60))


def test_a_recorded_drive_replays_the_live_run_bit_for_bit(weave, tmp_path):
    sc, whole = weave
    a = Simulation(sc)
    _run(a, 60)
    track = a.drive_track("player")
    assert len(track) > 50 and np.isnan(track[:, 6]).sum() < len(track)  # with the burnout's spins
    (tmp_path / "weave.drive").write_text(drive_text(track, ["a test drive"]))
    data = scene_to_dict(sc)
    data["vehicle"][0]["path"] = {"kind": "recorded", "file": "weave.drive"}
    replay = Simulation(parse_scene(data, source=str(tmp_path / "weave.toml")))  # read beside the scene
    got = []
    for f in range(1, 60):
        replay.advance_to(f / 30)
        got.append(replay.state())
    assert _all_same(whole, got)


def test_a_tires_ray_row_in_plain_floats_is_the_numpy_rows_bit_for_bit():
    """engine/livesteps.py ``ray_row`` (the live tires' rows a step) against engine/host.py ``ray_rows``: random
    tires far from the origin, still, creeping, moving, jumping, turning and not."""
    from taichi_rocks.engine.host import ray_rows
    from taichi_rocks.engine.livesteps import ray_row
    from taichi_rocks.engine.world import ACTIVE
    from taichi_rocks.motion.vehicles import RearTires

    rng = np.random.default_rng(5)

    def tires(c, fwd=None):
        n = len(c)
        h = rng.uniform(-4, 4, n)
        f = np.column_stack([np.cos(h), np.sin(h)]) if fwd is None else fwd
        return RearTires(c, np.column_stack([c[:, :2], np.zeros(n)]),
                         np.column_stack([rng.normal(0, 20, (n, 2)), np.zeros(n)]), f, rng.normal(0, 20, n),
                         rng.uniform(0.05, 0.2, n), rng.uniform(0.03, 0.1, n), np.full(n, 0.33), np.full(n, 0.8),
                         np.full(n, -1.0))

    for trial in range(400):
        c0 = np.column_stack([rng.uniform(-1e5, 1e5, (4, 2)), np.full(4, 0.33)])
        move = rng.choice([0.0, 1e-9, 0.01, 0.3, 3.0])
        c1 = c0 + np.column_stack([rng.normal(0, 1, (4, 2)) * move, np.zeros(4)])
        prev = tires(c0)
        cur = tires(c1, prev.forward if trial % 3 == 0 else None)
        dt = (0.002, 1 / 60)[trial % 2]
        want, _ = ray_rows(prev, cur, dt, np.zeros(2), 1e9)
        want[:, ACTIVE] = 1.0
        got = np.array([ray_row(prev, t, cur, t, dt) for t in range(4)])
        assert got.tobytes() == want.tobytes(), trial


def test_bad_drive_input_is_refused_naming_the_vehicle_and_the_value_and_changes_nothing():
    sc = _live(_scripted(rocks=2000))
    sim, ref = Simulation(sc), Simulation(sc)
    sim.advance_to(1 / 60)
    ref.advance_to(1 / 60)
    sim.drive("player", (0.4, 0.0), 0.0)
    ref.drive("player", (0.4, 0.0), 0.0)
    for args, kw, words in [(("truck", (0, 0), 0.0), {}, "drive('truck'): no vehicle of that name"),
                            (("van", (0, 0), 0.0), {}, "drive('van'): a scripted vehicle"),
                            (("player", (math.nan, 0), 0.0), {}, "position must be finite"),
                            (("player", (0, 0), math.inf), {}, "heading must be finite"),
                            (("player", (0, 0), 0.0), {"speed": float("nan")}, "speed must be finite"),
                            (("player", (0, 0, 0), 0.0), {}, "position must be (x, y)"),
                            (("player", (0, 0), 0.0), {"at": 0.01}, "has already passed")]:
        with pytest.raises(ValueError) as e:
            sim.drive(*args, **kw)
        assert words in str(e.value) and str(e.value).startswith(f"drive({args[0]!r})"), str(e.value)
    sim.advance_to(2 / 60)
    ref.advance_to(2 / 60)
    assert _same(sim, ref) and np.array_equal(sim.drive_track("player"), ref.drive_track("player"), equal_nan=True)
    with pytest.raises(ValueError, match="a scripted vehicle"):
        sim.drive_track("van")


def test_a_scene_with_a_live_vehicle_runs_undriven_straight_on_at_its_start_speed():
    sc = scene_with(_scripted(rocks=2000), {"vehicle[0].path": {"kind": "live", "start": [3.0, -1.0],
                                                                "heading": 90.0, "speed": 6.0}})
    sim = Simulation(sc)
    sim.step(50)
    st = sim.state(rocks=False)
    np.testing.assert_allclose(st.vehicle_positions[0, :2], [3.0, -1.0 + 6.0 * sim.time], atol=1e-9)
    assert st.vehicle_headings[0] == pytest.approx(math.pi / 2) and sim.launches_total > 0
