"""Live vehicles on the host (motion/live.py, config/drivefile.py, motion/vehicles.py): the interpolation between
drive() poses against its formulas and against finite differences, the keyframes' own bits, jumps, undriven
frames, derived speeds, checkpoints of the track, the checks of drive() and of drive files, and the wheel spin a
pose gives to the rear tires. No Taichi."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from scenes_util import scene
from taichi_rocks.config.drivefile import DriveFileError, drive_text, read_drive
from taichi_rocks.motion.live import JUMP_SLACK, LivePath, drive_pose
from taichi_rocks.motion.paths import WaypointPath
from taichi_rocks.motion.vehicles import Fleet

finite = st.floats(-50.0, 50.0, allow_nan=False)


def _track(*rows):
    return LivePath([r if len(r) == 7 else (*r, math.nan) for r in rows])


def _drive(path, t0, t1, x, y, h, v=None, w=None, spin=None, at=None):
    path.pending = drive_pose("car", (x, y), h, v, w, spin, at, t0)
    path.bind(t0, t1)


def test_the_keyframes_come_back_to_the_bit_and_the_motion_between_is_c1():
    p = _track((0.0, 0.0, 0.0, 0.0, 10.0, 0.0), (1.0, 10.0, 3.0, 0.4, 12.0, 0.5), (2.0, 21.0, 9.0, 0.7, 11.0, -0.1))
    for row in p.rows():
        x, y, h, v, w, vx, vy, spin = p.pose_values(row[0] + 1e-12)  # within the clock's tolerance
        assert (x, y, h, v, w) == tuple(row[1:6]) and (vx, vy) == (v * math.cos(h), v * math.sin(h))
    eps = 1e-6
    for t in np.linspace(0.01, 1.99, 37):
        a, b, c = (p.pose_values(t + d) for d in (-eps, 0.0, eps))
        np.testing.assert_allclose([(c[0] - a[0]) / (2 * eps), (c[1] - a[1]) / (2 * eps)], b[5:7], atol=1e-5)
        assert math.remainder(c[2] - a[2], 2 * math.pi) / (2 * eps) == pytest.approx(b[4], abs=1e-5)
        assert b[3] == pytest.approx(b[5] * math.cos(b[2]) + b[6] * math.sin(b[2]))
    left, right = p.pose_values(1.0 - 1e-7), p.pose_values(1.0 + 1e-7)  # through a keyframe: C1
    np.testing.assert_allclose(left[4:7], right[4:7], atol=1e-4)
    left, right = p.pose_values(2.0 - 1e-7), p.pose_values(2.0 + 1e-7)  # past the last: straight on, no yaw
    np.testing.assert_allclose(left[5:7], right[5:7], atol=1e-4)
    assert right[4] == 0.0


@given(finite, finite, st.floats(-3.1, 3.1), st.floats(-30, 30), st.floats(-2, 2), st.floats(0.3, 1.0))
@settings(max_examples=60, deadline=None)
def test_the_interpolation_is_the_hermite_cubic(x1, y1, h1, v1, w1, s):
    p = _track((0.0, 1.0, -2.0, 0.3, 5.0, 0.2), (2.0, x1, y1, h1, v1, w1))
    if p._kind[1] != 0:  # a jump: tested below
        return
    t = 2.0 * s
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    want_x = h00 * 1.0 + h01 * x1 + 2.0 * (h10 * 5.0 * math.cos(0.3) + h11 * v1 * math.cos(h1))
    want_y = h00 * -2.0 + h01 * y1 + 2.0 * (h10 * 5.0 * math.sin(0.3) + h11 * v1 * math.sin(h1))
    dh = math.remainder(h1 - 0.3, 2 * math.pi)
    want_h = 0.3 + h01 * dh + 2.0 * (h10 * 0.2 + h11 * w1)
    got = p.pose_values(t)
    assert got[0] == pytest.approx(want_x, abs=1e-9) and got[1] == pytest.approx(want_y, abs=1e-9)
    assert math.remainder(got[2] - want_h, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_headings_interpolate_the_short_way_across_pi():
    p = _track((0.0, 0.0, 0.0, 3.0, 10.0, 0.0), (1.0, 10.0, 0.0, -3.0, 10.0, 0.0))
    hs = [p.pose_values(t)[2] for t in np.linspace(0.0, 1.0, 21)]
    assert all(abs(h) > 2.9 for h in hs)  # through pi, never through 0


def test_without_a_drive_a_live_vehicle_keeps_its_start_heading_and_speed():
    p = LivePath.starting((5.0, 7.0), math.radians(30.0), 12.0)
    for t in (0.0, 0.5, 10.0):
        x, y, h, v, w, *_ = p.pose_values(t)
        assert (x, y) == pytest.approx((5.0 + 12.0 * t * math.cos(h), 7.0 + 12.0 * t * math.sin(h)))
        assert h == pytest.approx(math.radians(30.0)) and v == 12.0 and w == 0.0
    assert p.still_after == math.inf


def test_a_pose_is_bound_to_the_end_of_the_advance_and_missing_rates_are_derived():
    p = LivePath.starting((0.0, 0.0), 0.0, 10.0)
    _drive(p, 0.0, 0.1, 1.0, 0.2, 0.1)
    t, x, y, h, v, w, spin = p.rows()[-1]
    assert t == 0.1 and (x, y, h) == (1.0, 0.2, 0.1) and math.isnan(spin)
    assert v == pytest.approx((1.0 * math.cos(0.1) + 0.2 * math.sin(0.1)) / 0.1)  # mean velocity along h
    assert w == pytest.approx(0.1 / 0.1)
    assert p.horizon == 0.1 and p.pending is None
    _drive(p, 0.1, 0.2, 2.0, 0.2, 0.1, v=9.0, w=0.0, spin=55.0)
    assert tuple(p.rows()[-1][4:]) == (9.0, 0.0, 55.0)
    assert p.pose_values(0.15)[7] == 55.0 and math.isnan(p.pose_values(0.05)[7])  # spin holds up to its pose


def test_undriven_frames_go_straight_on_and_the_next_drive_starts_where_they_got():
    p = LivePath.starting((0.0, 0.0), 0.0, 10.0)
    _drive(p, 0.0, 0.1, 1.0, 0.0, 0.2, v=10.0, w=2.0)  # turning at the end of the first frame
    mid = [p.pose_values(t) for t in (0.15, 0.2)]  # frames nobody drove
    assert all(m[2] == 0.2 and m[4] == 0.0 for m in mid)  # straight on, no yaw
    _drive(p, 0.2, 0.3, 3.0, 0.5, 0.3, v=10.0)
    rows = p.rows()
    assert len(rows) == 4 and rows[2][0] == 0.2 and tuple(rows[2][1:3]) == mid[1][:2]  # a keyframe where it got
    assert p.pose_values(0.15) == mid[0]  # the frames driven straight on stay so, to the bit
    replay = LivePath(rows, live=False)  # and a replay of the keyframes gives every pose again
    for t in np.linspace(0.0, 0.35, 50):
        assert np.array_equal(replay.pose_values(t), p.pose_values(t), equal_nan=True)


def test_a_jump_is_at_the_new_pose_from_the_first_instant_after_it():
    p = LivePath.starting((0.0, 0.0), 0.0, 10.0)
    _drive(p, 0.0, 0.1, 1.0, 0.0, 0.0)
    far = 2.0 * 10.0 * 0.1 + JUMP_SLACK + 0.5
    _drive(p, 0.1, 0.2, 1.0 + far, 40.0, 1.0)  # a respawn 40 m to the side
    assert p._kind[-1] == 1
    t, x, y, h, v, w, _ = p.rows()[-1]
    assert v == 10.0 and w == 0.0  # the speed before it, no yaw
    for s in (0.1 + 1e-6, 0.15, 0.199):
        got = p.pose_values(s)
        assert got[:2] == pytest.approx((x - v * (0.2 - s) * math.cos(h), y - v * (0.2 - s) * math.sin(h)))
    near = LivePath.starting((0.0, 0.0), 0.0, 10.0)
    _drive(near, 0.0, 0.1, 2.0 * 10.0 * 0.1 + JUMP_SLACK - 0.1, 0.0, 0.0)  # just within reach: interpolated
    assert near._kind[-1] == 0


def test_at_and_a_restore_replace_the_future():
    p = LivePath.starting((0.0, 0.0), 0.0, 10.0)
    _drive(p, 0.0, 0.1, 5.0, 0.0, 0.0, v=10.0, at=0.5)  # a pose for later than the advance's end
    assert p.rows()[-1][0] == 0.5 and p.horizon == 0.1
    assert p.pose_values(0.3)[0] == pytest.approx(3.0)
    saved = p.saved(0.1)
    _drive(p, 0.1, 0.2, 1.5, 1.0, 0.2)  # a new drive cuts the pose at 0.5 away
    assert [r[0] for r in p.rows()] == [0.0, 0.1, 0.2]  # cut at where it had got to
    assert p.rows()[1][1] == pytest.approx(1.0) and p.rows()[1][4] == pytest.approx(10.0)
    p.load(saved, 0.1)
    assert [r[0] for r in p.rows()] == [0.0, 0.5] and p.horizon == 0.1 and p.pending is None


@pytest.mark.parametrize("args, what", [
    (((1.0,), 0.0), "position must be (x, y)"), (((1.0, math.nan), 0.0), "position must be finite"),
    (("ab", 0.0), "position must be (x, y)"), (((0, 0), math.inf), "heading must be finite"),
    (((0, 0), 0.0, math.nan), "speed must be finite"), (((0, 0), 0.0, 1.0, "x"), "yaw_rate must be a number"),
    (((0, 0), 0.0, None, None, -math.inf), "wheel_spin must be finite"),
    (((0, 0), 0.0, None, None, None, 0.5), "at = 0.5 s has already passed")])
def test_drive_pose_refuses_bad_values_naming_the_vehicle_and_the_value(args, what):
    with pytest.raises(ValueError) as e:
        drive_pose("player", *args, now=1.0)
    assert str(e.value).startswith("drive('player'): ") and what in str(e.value)


def test_a_drive_file_round_trips_every_bit(tmp_path):
    rng = np.random.default_rng(3)
    rows = np.cumsum(rng.random((40, 7)), axis=0) * [1, 7.3, -3.1, 0.01, 1, 1, 1] + [0, 1e6, -1e5, 0, 0, 0, 0]
    rows[::3, 6] = np.nan
    f = tmp_path / "a.drive"
    f.write_text(drive_text(rows, ["a comment"]))
    back = np.array(read_drive(f))
    assert np.array_equal(back, rows, equal_nan=True)


@pytest.mark.parametrize("text, where", [
    ("drive 1\nt x y heading speed yaw_rate wheel_spin\n0 0 0 0 0 0 -\n", ":1: expected the header"),
    ("taichi-rocks drive 1\nt x y heading speed yaw_rate\n0 0 0 0 0 0\n", ":2: expected the columns"),
    ("taichi-rocks drive 1\n# c\nt x y heading speed yaw_rate wheel_spin\n0 0 0 0 0 0 -\n1 0 0 0\n",
     ":5: expected 7 values"),
    ("taichi-rocks drive 1\nt x y heading speed yaw_rate wheel_spin\n0 0 0 0 0 0 -\n1 0 nan 0 0 0 -\n",
     ":4: y: must be finite"),
    ("taichi-rocks drive 1\nt x y heading speed yaw_rate wheel_spin\n0 0 0 inf 0 0 -\n", ":3: heading: must be"),
    ("taichi-rocks drive 1\nt x y heading speed yaw_rate wheel_spin\n0 0 0 0 0 0 -\n0.5 1 0 0 0 0 -\n"
     "0.5 2 0 0 0 0 -\n", ":5: t: times must increase, got 0.5 after 0.5"),
    ("taichi-rocks drive 1\nt x y heading speed yaw_rate wheel_spin\n-1 0 0 0 0 0 -\n", ":3: t: must be >= 0"),
    ("taichi-rocks drive 1\nt x y heading speed yaw_rate wheel_spin\n0 0 0 0 0 zero -\n", ":3: yaw_rate: expected"),
    ("taichi-rocks drive 1\nt x y heading speed yaw_rate wheel_spin\n", ": no poses"),
    ("taichi-rocks drive 1\n", ": no column line"),
    ("", ":1: expected the header")])
def test_a_broken_drive_file_is_refused_with_its_line(tmp_path, text, where):
    f = tmp_path / "b.drive"
    f.write_text(text)
    with pytest.raises(DriveFileError) as e:
        read_drive(f)
    assert str(e.value).startswith(str(f)) and where in str(e.value), str(e.value)


def _live_scene(**extra):
    return scene(vehicles=[{"name": "car", "path": {"kind": "live", "start": [1.0, 2.0], "speed": 8.0, **extra}},
                           {"name": "van", "path": {"points": [[0.0, 5.0], [300.0, 5.0]], "speed": 9.0}}])


def test_a_wheel_spin_given_sets_the_tread_speed_of_both_rear_tires():
    fleet = Fleet(_live_scene())
    live = fleet.paths[0]
    live.pending = drive_pose("car", (2.0, 2.1), 0.1, 8.0, 0.5, 60.0, None, 0.0)
    live.bind(0.0, 0.125)
    R = fleet.specs[0].tire_radius
    poses = fleet.poses(0.125)
    tires = fleet.rear_tires(poses)
    assert np.array_equal(tires.spin[:2], [60.0 * R, 60.0 * R])  # the live car's two, as the game says
    van = tires.spin[2:]
    assert van == pytest.approx([9.0 * 1.15, 9.0 * 1.15])  # rolling: speed (1 + slip)
    table = fleet.pose_table([0.0625, 0.125])  # the batch gives the same bits as pose by pose
    batch = fleet.rear_tires_table(table)
    for k, t in enumerate((0.0625, 0.125)):
        one = fleet.rear_tires(fleet.poses(t), relative=True)
        for a, b in zip((batch.center[k], batch.velocity[k], batch.spin[k]), (one.center, one.velocity, one.spin)):
            assert np.array_equal(a, b)


def test_the_fleet_plans_no_further_than_the_live_poses_known():
    fleet = Fleet(_live_scene())
    assert fleet.live == [0] and fleet.horizon() == 0.0
    fleet.bind(0.0, 0.25)
    assert fleet.horizon() == 0.25
    assert Fleet(scene()).horizon() == math.inf and Fleet(scene()).live == []


def test_a_recorded_drive_is_a_scripted_path_that_stops_where_its_last_pose_stands():
    p = LivePath([(0.0, 0.0, 0.0, 0.0, 5.0, 0.0, math.nan), (2.0, 10.0, 0.0, 0.0, 0.0, 0.0, math.nan)], live=False)
    assert not p.live and p.still_after == 2.0 and p.horizon == math.inf
    assert p.pose_values(3.0)[:2] == (10.0, 0.0)
    w = WaypointPath([[0, 0], [10, 0]], 5.0)
    assert LivePath([(0.0, 0.0, 0.0, 0.0, 5.0, 0.0, math.nan)], live=False).still_after == math.inf != w.still_after
