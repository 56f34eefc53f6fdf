"""Scripted vehicle paths: closed forms, independent arc lengths (scipy quad) and finite differences."""

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from taichi_rocks.motion.paths import CirclePath, WaypointPath, path_from_spec, sample

CURVY = [[0.0, 0.0], [20.0, 5.0], [35.0, -4.0], [60.0, 10.0], [70.0, 30.0]]
LOOP = [[0.0, 0.0], [30.0, -5.0], [50.0, 20.0], [10.0, 30.0]]


def reference_spline(points, loop=False):
    """The curve as specified: chord-length CubicSpline; returns (spline, knots, segment arc lengths)."""
    P = np.asarray(points, float)
    if loop:
        P = np.vstack([P, P[:1]])
    u = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    cs = CubicSpline(u, P, bc_type="periodic" if loop else "natural")
    seg = [quad(lambda x: np.hypot(*cs(x, 1)), a, b, epsabs=1e-12, epsrel=1e-12, limit=200)[0]
           for a, b in zip(u[:-1], u[1:])]
    return cs, u, np.array(seg)


def profile_times(lengths, speeds):
    """Arrival time at each knot for constant acceleration: a segment takes 2 L / (v0 + v1)."""
    return np.r_[0.0, np.cumsum(2.0 * np.asarray(lengths) / (np.asarray(speeds[:-1]) + np.asarray(speeds[1:])))]


def angle_diff(a, b):
    return np.abs((np.asarray(a) - np.asarray(b) + np.pi) % (2 * np.pi) - np.pi)


def assert_all_finite(d):
    for key, value in d.items():
        assert np.all(np.isfinite(value)), key


@pytest.mark.parametrize("smooth", [True, False])
def test_straight_line_constant_speed(smooth):
    p = WaypointPath([[0, 0], [40, 0], [100, 0]], 10.0, smooth=smooth)
    assert p.duration == pytest.approx(10.0, rel=1e-12)
    t = np.linspace(0.0, 9.99, 50)
    d = sample(p, t)
    np.testing.assert_allclose(d["position"], np.c_[10 * t, 0 * t], atol=1e-9)
    np.testing.assert_allclose(d["heading"], 0.0, atol=1e-12)
    np.testing.assert_allclose(d["yaw_rate"], 0.0, atol=1e-12)
    np.testing.assert_allclose(d["speed"], 10.0)
    np.testing.assert_allclose(d["velocity"], np.c_[10 + 0 * t, 0 * t], atol=1e-9)


@pytest.mark.parametrize("clockwise", [False, True])
def test_circle_closed_form(clockwise):
    c, R, v, a0 = np.array([3.0, -2.0]), 7.0, 5.0, 0.3
    p = CirclePath(c, R, v, clockwise=clockwise, start_angle=a0)
    sgn = -1.0 if clockwise else 1.0
    assert p.duration == pytest.approx(2 * np.pi * R / v)
    t = np.linspace(0.0, 3 * p.duration, 97)
    d = sample(p, t)
    a = a0 + sgn * v * t / R
    np.testing.assert_allclose(d["position"], c + R * np.c_[np.cos(a), np.sin(a)], atol=1e-9)
    assert angle_diff(d["heading"], a + sgn * np.pi / 2).max() < 1e-9
    np.testing.assert_allclose(d["yaw_rate"], sgn * v / R)
    np.testing.assert_allclose(d["velocity"], sgn * v * np.c_[-np.sin(a), np.cos(a)], atol=1e-9)


def test_spline_arc_length_and_inverse_are_accurate():
    p = WaypointPath(CURVY, 10.0)
    cs, u, seg = reference_spline(CURVY)
    assert p.length == pytest.approx(seg.sum(), rel=1e-9)
    arc = lambda b: quad(lambda x: np.hypot(*cs(x, 1)), 0.0, b, epsabs=1e-12, epsrel=1e-12, limit=200)[0]
    for t in [0.37, 2.9, 5.55, 8.1, p.duration - 0.01]:
        ut = brentq(lambda x: arc(x) - 10.0 * t, 0.0, u[-1], xtol=1e-13)
        np.testing.assert_allclose(p.pose(t).position, cs(ut), atol=1e-6)


def test_spline_hits_waypoints_at_profile_times():
    speeds = [4.0, 10.0, 6.0, 12.0, 3.0]
    p = WaypointPath(CURVY, speeds)
    _, _, seg = reference_spline(CURVY)
    times = profile_times(seg, speeds)
    assert p.duration == pytest.approx(times[-1], rel=1e-9)
    for i, (ti, pt) in enumerate(zip(times, CURVY)):
        pose = p.pose(ti)
        np.testing.assert_allclose(pose.position, pt, atol=1e-6)
        if i < len(CURVY) - 1:  # the end is parked (speed 0)
            assert pose.speed == pytest.approx(speeds[i], abs=1e-6)
    # constant acceleration: mid-time speed is the mean of the end speeds
    for i in range(len(seg)):
        assert p.pose(0.5 * (times[i] + times[i + 1])).speed == pytest.approx(0.5 * (speeds[i] + speeds[i + 1]))
    d = sample(p, np.linspace(0.0, p.duration, 400))
    np.testing.assert_allclose(np.linalg.norm(d["velocity"], axis=1), np.abs(d["speed"]), atol=1e-9)


@pytest.mark.parametrize("loop", [False, True])
def test_finite_differences_match_velocity_and_yaw_rate(loop):
    p = WaypointPath(LOOP, [4.0, 10.0, 6.0, 12.0], loop=True) if loop else WaypointPath(CURVY, [4.0, 10.0, 6.0, 12.0, 3.0])
    h = 1e-4
    for t in np.linspace(0.3, p.duration - 0.3, 60):
        a, b, c = p.pose(t - h), p.pose(t), p.pose(t + h)
        np.testing.assert_allclose((c.position - a.position) / (2 * h), b.velocity, atol=1e-5 * (1 + abs(b.speed)))
        dh = math.remainder(c.heading - a.heading, 2 * math.pi) / (2 * h)
        assert dh == pytest.approx(b.yaw_rate, rel=1e-5, abs=1e-5)


@pytest.mark.parametrize("smooth", [True, False])
def test_loop_is_periodic(smooth):
    p = WaypointPath(LOOP, [8.0, 12.0, 5.0, 9.0], loop=True, smooth=smooth)
    T = p.duration
    for t in np.linspace(0.0, T, 23)[1:-1]:  # (a polyline's heading jumps at the closing corner)
        for k in (1, 3):
            a, b = p.pose(t), p.pose(t + k * T)
            np.testing.assert_allclose(b.position, a.position, atol=1e-6)
            assert angle_diff(a.heading, b.heading) < 1e-6
            assert b.speed == pytest.approx(a.speed, abs=1e-6)
            assert b.yaw_rate == pytest.approx(a.yaw_rate, abs=1e-6)
    if smooth:  # periodic spline: continuous through the closing point
        a, b = p.pose(T - 1e-7), p.pose(0.0)
        np.testing.assert_allclose(a.position, b.position, atol=1e-5)
        assert angle_diff(a.heading, b.heading) < 1e-5
        assert a.yaw_rate == pytest.approx(b.yaw_rate, abs=1e-4)


def test_loop_closing_point_is_dropped():
    a = WaypointPath(LOOP + LOOP[:1], 10.0, loop=True)
    b = WaypointPath(LOOP, 10.0, loop=True)
    assert a.duration == pytest.approx(b.duration)
    np.testing.assert_allclose(a.pose(3.3).position, b.pose(3.3).position)


@pytest.mark.parametrize("smooth", [True, False])
def test_stop_at_middle_waypoint_and_restart(smooth):
    pts = [[0, 0], [30, 4], [55, -6]]
    p = WaypointPath(pts, [10.0, 0.0, 8.0], smooth=smooth)
    lengths = reference_spline(pts)[2] if smooth else np.linalg.norm(np.diff(pts, axis=0), axis=1)
    t_stop = 2 * lengths[0] / (10.0 + 0.0)
    assert p.duration == pytest.approx(t_stop + 2 * lengths[1] / 8.0, rel=1e-9)
    stop = p.pose(t_stop)
    np.testing.assert_allclose(stop.position, pts[1], atol=1e-6)
    assert stop.speed == pytest.approx(0.0, abs=1e-9) and stop.yaw_rate == pytest.approx(0.0, abs=1e-9)
    assert p.pose(t_stop - 0.1).speed == pytest.approx(10.0 * 0.1 / t_stop, rel=1e-6)  # decelerating
    after = p.pose(t_stop + 0.5)
    assert after.speed == pytest.approx(8.0 * 0.5 / (2 * lengths[1] / 8.0), rel=1e-6)  # accelerating again
    assert np.linalg.norm(after.position - stop.position) > 0.1


def test_constant_zero_speed_is_parked_and_finite():
    p = WaypointPath(CURVY, 0.0)
    moving = WaypointPath(CURVY, 1.0)
    assert p.duration is None
    start_dir = moving.pose(1e-3).position - moving.pose(0.0).position
    for t in [-1.0, 0.0, 5.0, 1e9]:
        pose = p.pose(t)
        np.testing.assert_array_equal(pose.position, CURVY[0])
        assert pose.speed == 0.0 and pose.yaw_rate == 0.0 and np.all(pose.velocity == 0.0)
        assert angle_diff(pose.heading, math.atan2(start_dir[1], start_dir[0])) < 1e-4
    c = CirclePath([1, 1], 5.0, 0.0)
    assert c.duration is None
    assert_all_finite(sample(c, [0.0, 10.0]))


def test_two_zero_speeds_in_a_row_park_there_forever():
    pts = [[0, 0], [10, 0], [20, 5], [30, 5]]
    p = WaypointPath(pts, [5.0, 0.0, 0.0, 5.0])
    assert p.duration is None
    t_arrive = 2 * reference_spline(pts)[2][0] / 5.0
    for t in [t_arrive, t_arrive + 1.0, 1e6]:
        pose = p.pose(t)
        np.testing.assert_allclose(pose.position, pts[1], atol=1e-6)
        assert pose.speed == pytest.approx(0.0, abs=1e-9)


def test_open_path_ends_parked():
    p = WaypointPath(CURVY, 10.0)
    T = p.duration
    end_dir = p.pose(T - 1e-6).velocity
    for t in [T, T + 1.0, T + 1e6]:
        pose = p.pose(t)
        np.testing.assert_allclose(pose.position, CURVY[-1], atol=1e-6)
        assert pose.speed == 0.0 and pose.yaw_rate == 0.0
        assert angle_diff(pose.heading, math.atan2(end_dir[1], end_dir[0])) < 1e-5


def test_negative_time_clamps_to_start():
    p = WaypointPath(CURVY, [4.0, 10.0, 6.0, 12.0, 3.0])
    a, b = p.pose(-3.0), p.pose(0.0)
    np.testing.assert_array_equal(a.position, b.position)
    assert a.speed == b.speed == 4.0 and a.heading == b.heading


@pytest.mark.parametrize("smooth", [True, False])
def test_reverse_drives_backwards_along_same_positions(smooth):
    fwd = WaypointPath(CURVY, [4.0, 10.0, 6.0, 12.0, 3.0], smooth=smooth)
    rev = WaypointPath(CURVY, [4.0, 10.0, 6.0, 12.0, 3.0], smooth=smooth, reverse=True)
    assert rev.duration == fwd.duration
    t = np.linspace(0.0, fwd.duration - 0.01, 120)
    f, r = sample(fwd, t), sample(rev, t)
    np.testing.assert_allclose(r["position"], f["position"], atol=1e-12)
    np.testing.assert_allclose(r["velocity"], f["velocity"], atol=1e-9)
    np.testing.assert_allclose(r["speed"], -f["speed"])
    np.testing.assert_allclose(r["yaw_rate"], f["yaw_rate"])
    assert np.all(r["speed"] < 0)
    assert angle_diff(r["heading"], f["heading"] + np.pi).max() < 1e-12
    nose = np.c_[np.cos(r["heading"]), np.sin(r["heading"])]
    assert np.all(np.sum(nose * r["velocity"], axis=1) < 0)  # velocity opposite to the nose
    h = 1e-4  # yaw rate is d(heading)/dt of the reversed heading
    for ti in t[5:-5:10]:
        dh = math.remainder(rev.pose(ti + h).heading - rev.pose(ti - h).heading, 2 * math.pi) / (2 * h)
        assert dh == pytest.approx(rev.pose(ti).yaw_rate, abs=1e-4 if smooth else 1e-12)
    c = CirclePath([0, 0], 10.0, 5.0, reverse=True)
    assert c.pose(1.0).speed == -5.0 and c.pose(1.0).yaw_rate == pytest.approx(0.5)


def test_heading_is_wrapped():
    p = WaypointPath([[0, 0], [-10, 0]], 1.0)
    assert p.pose(1.0).heading == math.pi  # (-pi, pi]: not -pi
    assert WaypointPath([[0, 0], [10, 0]], 1.0, reverse=True).pose(1.0).heading == math.pi
    d = sample(CirclePath([0, 0], 3.0, 7.0, start_angle=-2.0), np.linspace(0, 20, 1001))
    assert np.all(d["heading"] > -np.pi) and np.all(d["heading"] <= np.pi)
    assert np.ptp(d["heading"]) > 6.0


@pytest.mark.parametrize("make", [
    lambda o: WaypointPath(np.asarray(CURVY) + o, [4.0, 10.0, 6.0, 12.0, 3.0]),
    lambda o: WaypointPath(np.asarray(CURVY) + o, 9.0, loop=True),
    lambda o: WaypointPath(np.asarray(CURVY) + o, 9.0, smooth=False),
    lambda o: CirclePath(o + np.array([1.0, 2.0]), 12.0, 6.0),
])
def test_huge_coordinates_keep_relative_motion(make):
    off = np.array([1e6, -2e6])
    near, far = make(np.zeros(2)), make(off)
    t = np.linspace(0.0, 12.0, 61)
    a, b = sample(near, t), sample(far, t)
    np.testing.assert_allclose(b["position"] - off, a["position"], atol=1e-6, rtol=0)
    assert angle_diff(a["heading"], b["heading"]).max() < 1e-9
    np.testing.assert_allclose(b["yaw_rate"], a["yaw_rate"], atol=1e-9)


def test_slalom_apex_yaw_rate():
    # y = A sin(k x) has radius 1 / (A k^2) at its apexes: A = 2 m, R = 3 m
    A, R, v = 2.0, 3.0, 8.0
    k = 1.0 / math.sqrt(A * R)
    x = np.arange(0.0, 4 * 2 * np.pi / k, 0.5)
    p = WaypointPath(np.c_[x, A * np.sin(k * x)], v)
    d = sample(p, np.arange(0.0, p.duration, 0.002))
    y, yaw = d["position"][:, 1], d["yaw_rate"]
    apex = [i for i in range(1, len(y) - 1) if abs(y[i]) >= abs(y[i - 1]) and abs(y[i]) > abs(y[i + 1])
            and abs(y[i]) > 0.9 * A and 5.0 < d["position"][i, 0] < x[-1] - 5.0]
    assert len(apex) >= 6
    for i in apex:
        assert abs(yaw[i]) == pytest.approx(v / R, rel=0.10)
        assert np.sign(yaw[i]) == -np.sign(y[i])  # turning right at a left apex


def test_polyline_corners():
    pts = [[0, 0], [10, 0], [10, 10], [0, 10]]
    p = WaypointPath(pts, 5.0, smooth=False)
    assert p.duration == pytest.approx(6.0)
    for t, pos, h in [(1.0, [5, 0], 0.0), (2.0, [10, 0], np.pi / 2), (3.0, [10, 5], np.pi / 2), (5.0, [5, 10], np.pi)]:
        pose = p.pose(t)
        np.testing.assert_allclose(pose.position, pos, atol=1e-12)
        assert pose.heading == pytest.approx(h) and pose.yaw_rate == 0.0


@pytest.mark.parametrize("loop", [False, True])
def test_circle_arc(loop):
    p = CirclePath([0, 0], 10.0, 5.0, start_angle=0.0, sweep=np.pi / 2, loop=loop)
    T = p.duration
    assert T == pytest.approx(np.pi)
    np.testing.assert_allclose(p.pose(T - 1e-9).position, [0, 10], atol=1e-6)
    later = p.pose(T + 0.5)
    if loop:  # restarts from the start
        np.testing.assert_allclose(later.position, p.pose(0.5).position, atol=1e-9)
        assert later.speed == 5.0
    else:  # parked at the end, nose along the tangent
        np.testing.assert_allclose(later.position, [0, 10], atol=1e-9)
        assert later.speed == 0.0 and later.yaw_rate == 0.0
        assert later.heading == pytest.approx(np.pi)


def test_path_from_spec():
    c = path_from_spec("circle", center=[1.0, 2.0], radius=4.0, speed=2.0, start_angle=90.0, sweep=180.0,
                       loop=False, clockwise=True)
    np.testing.assert_allclose(c.pose(0.0).position, [1.0, 6.0], atol=1e-12)
    assert c.duration == pytest.approx(np.pi * 4.0 / 2.0)
    np.testing.assert_allclose(c.pose(100.0).position, [1.0, -2.0], atol=1e-12)  # clockwise via +x
    np.testing.assert_allclose(c.pose(c.duration / 2).position, [5.0, 2.0], atol=1e-9)
    w = path_from_spec("waypoints", points=[[0, 0], [3, 4]], speed=5.0, smooth=False, reverse=True)
    np.testing.assert_allclose(w.pose(0.5).position, [1.5, 2.0])
    with pytest.raises(ValueError):
        path_from_spec("spiral")


@pytest.mark.parametrize("bad", [
    lambda: WaypointPath([[0, 0], [0, 0], [1, 1]], 1.0),
    lambda: WaypointPath([[0, 0]], 1.0),
    lambda: WaypointPath([[0, 0], [1, 1]], -1.0),
    lambda: WaypointPath([[0, 0], [1, 1]], [1.0, 2.0, 3.0]),
    lambda: WaypointPath([[0, 0], [np.nan, 1]], 1.0),
    lambda: CirclePath([0, 0], 0.0, 1.0),
    lambda: CirclePath([0, 0], 1.0, 1.0, sweep=0.0),
    lambda: WaypointPath([[0, 0], [1, 1]], 1.0).pose(float("nan")),
])
def test_invalid_input_raises(bad):
    with pytest.raises(ValueError):
        bad()


@pytest.mark.parametrize("path", [
    WaypointPath([[0, 0], [10, 0], [10 + 1e-9, 1e-9], [20, 3]], [5.0, 5.0, 0.0, 5.0]),
    WaypointPath([[0, 0], [1e-7, 0], [5, 1]], 3.0, loop=True),
    WaypointPath(np.cumsum(np.random.default_rng(0).normal(size=(3000, 2)), axis=0), 7.0),
    WaypointPath([[0, 0], [10, 0], [0, 0.01]], 4.0, reverse=True),  # hairpin
    WaypointPath(CURVY, 0.0, reverse=True, loop=True),
], ids=["tiny-segment", "tiny-loop", "many-points", "hairpin", "parked-reverse-loop"])
def test_never_nan(path):
    T = path.duration if path.duration is not None else 10.0
    d = sample(path, np.r_[-1.0, np.linspace(0.0, 1.5 * T, 3001), 1e7])
    assert_all_finite(d)
    assert np.all(np.abs(d["heading"]) <= np.pi)
