"""The scene's camera on the host (motion/camera.py, motion/cabin.py): shots resolved from the scene, switched
at their times with a snap, a saved state that frames every later time as an uninterrupted run does, the
driver's eye inside the body behind the windscreen, fixed to the body in a turn."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from scenes_util import scene as make_scene
from shots_util import CUTS, VIEWS, expected_eyes, rot, write_shots_scene
from taichi_rocks.config.scene import load_scene, scene_with
from taichi_rocks.motion.bodies import vehicle_kind
from taichi_rocks.motion.cabin import cabin_of
from taichi_rocks.motion.camera import SceneCamera, scene_camera, shots_of, view_preset
from taichi_rocks.motion.vehicles import Fleet

FPS = 30.0


@pytest.fixture(scope="module")
def shots_scene(tmp_path_factory):
    return load_scene(write_shots_scene(tmp_path_factory.mktemp("shots")))


def _step(camera, fleet, frames, start=0):
    out = []
    for k in range(start, frames):
        p = fleet.poses(k / FPS)
        out.append(camera.update(np.array([q.position for q in p]), [q.heading for q in p], k / FPS))
    return out


def test_shots_of_the_scene(shots_scene):
    """The [camera] table's view from 0, then each shot; keys a shot leaves out come from the table, its offset
    and aim from its view; a shot at 0 replaces the table's view; a preset asked for replaces them all."""
    s = shots_scene
    shots = shots_of(s)
    assert [x.view for x in shots] == list(VIEWS) and [x.at for x in shots] == [0.0, *CUTS]
    assert [(x.rides, x.target) for x in shots] == [(0, 0), (0, 0), (1, 1)]  # driver: the car; side: the van
    eye, aim = view_preset("driver", s.vehicles[0], s.vehicles[0], s.camera.look_ahead)
    assert shots[1].offset == tuple(eye) and shots[1].aim == tuple(aim)
    assert shots[1].offset == cabin_of(s.vehicles[0]).eye
    first = scene_with(s, {"camera.shot[0].at": 0.0})
    assert [x.view for x in shots_of(first)] == ["driver", "side"]
    assert [x.view for x in shots_of(s, "bonnet")] == ["bonnet"]


def test_shots_switch_at_their_times_with_a_snap(shots_scene):
    """Stepped at 30 frames/s on the circle, the camera is the chase rig until 0.75 s, then the driver's seat
    (fixed to the car: its own heading), then the side view of the van, from the first frame at or after each
    shot's at; each cut snaps the smoothed heading to the vehicle ridden with."""
    s = shots_scene
    fleet = Fleet(s)
    n = int(s.duration * FPS)
    got = _step(scene_camera(s), fleet, n)
    eyes, shot = expected_eyes(s, [k / FPS for k in range(n)])
    np.testing.assert_allclose([g[0] for g in got], eyes, rtol=0, atol=1e-12)
    assert sorted(set(shot)) == [0, 1, 2] and np.all(np.diff(shot) >= 0)
    for k in np.flatnonzero(np.diff(shot)) + 1:  # the first frame of a shot: the heading snapped
        assert got[k][2] == fleet.poses(k / FPS)[shots_of(s)[shot[k]].rides].heading
        assert k / FPS >= CUTS[shot[k] - 1] - 1e-9 > (k - 1) / FPS
    lag = [abs(math.remainder(got[k][2] - fleet.poses(k / FPS)[0].heading, 2 * math.pi)) for k in range(n)]
    assert max(lag[:int(CUTS[0] * FPS)]) > 0.1  # the chase view smooths: its heading lags the turning car


def test_a_restored_camera_frames_as_an_uninterrupted_one(shots_scene):
    """The camera's state is its heading and clock: restored into a new camera after any frame (before,
    at and after a cut), it gives every later frame bit for bit as the camera that never stopped."""
    s = shots_scene
    fleet = Fleet(s)
    n = int(s.duration * FPS)
    ref = scene_camera(s)
    whole = _step(ref, fleet, n)
    for k in range(0, n - 1):
        first = scene_camera(s)
        _step(first, fleet, k + 1)
        again = scene_camera(s)
        again.heading, again.t = first.heading, first.t
        rest = _step(again, fleet, n, start=k + 1)
        for a, b in zip(rest, whole[k + 1:]):
            assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]) and a[2] == b[2], k


def test_a_camera_without_shots_refuses_to_exist():
    with pytest.raises(ValueError, match="at least one shot"):
        SceneCamera((), 6.0, 0.3, 20.0)


def test_the_mounted_eye_stays_in_its_seat_and_its_gaze_follows_smoothly():
    """In a turn the driver's eye turns with the car (it stays in its seat), while the gaze follows the car's
    heading with the rig's smoothing: looking along the smoothed heading."""
    s = make_scene(vehicles=[{"name": "car", "path": {"kind": "circle", "radius": 10.0, "speed": 10.0}}],
                   camera={"view": "driver", "smoothing": 0.5})
    fleet = Fleet(s)
    cam = scene_camera(s)
    seat = np.array(cabin_of(s.vehicles[0]).eye)
    for k, (eye, look, heading) in enumerate(_step(cam, fleet, 60)):
        p = fleet.poses(k / FPS)[0]
        np.testing.assert_allclose(eye, p.position + rot(p.heading) @ seat, atol=1e-12)
        gaze = (look - eye)[:2]
        assert abs(math.remainder(math.atan2(gaze[1], gaze[0]) - heading, 2 * math.pi)) < 1e-12
    assert abs(math.remainder(heading - p.heading, 2 * math.pi)) > 0.3  # 1 rad/s, 0.5 s: the gaze lags


SIZES = st.fixed_dictionaries({"length": st.floats(2.5, 16.0), "width": st.floats(1.2, 3.0),
                               "height": st.floats(1.0, 4.0), "kind": st.sampled_from(["car", "van", "truck",
                                                                                       "auto"])})


@settings(max_examples=300, deadline=None)
@given(SIZES)
def test_the_drivers_eye_is_inside_the_body_behind_the_windscreen(sizes):
    """For any body the scene may hold: the eye is inside the body's box, in the cabin (above the belt line,
    below the roof, inside the cabin's half width, in front of its back) and behind the windscreen; the bonnet
    camera stands in front of the windscreen's foot, above the bonnet."""
    L, W, H = sizes["length"], sizes["width"], sizes["height"]
    spec = make_scene(vehicles=[{"name": "v", "kind": sizes["kind"], "length": L, "width": W, "height": H,
                                 "wheelbase": 0.6 * L, "track": 0.85 * W, "tire_radius": min(0.3 * H, 0.45),
                                 "tire_width": 0.2}]).vehicles[0]
    cab = cabin_of(spec)
    x, y, z = cab.eye
    z0 = 0.8 * spec.tire_radius
    assert abs(x) < L / 2 and 0 < y < W / 2 and z0 < z < z0 + H  # the body box; the seat on the left
    assert cab.belt < z < cab.roof and y < cab.half_inside and x > cab.back_at(z)
    assert x < cab.windscreen_x(z) - 0.05 * L  # behind the glass, by more than a hand
    bx, by, bz = cab.bonnet_eye
    assert bx > cab.base_x and by == 0.0 and bz > cab.bonnet_z and bx <= L / 2 + 0.05
    assert cab.kind == vehicle_kind(spec)


def test_views_are_one_table(shots_scene):
    """motion/camera.py VIEW_TABLE has a row for every view of the scene's list, in its order, and nothing else;
    a name without a row is refused (ValueError naming camera.view), never framed as another view."""
    from taichi_rocks.config.models import CAMERA_VIEWS
    from taichi_rocks.motion.camera import VIEW_TABLE, view_of

    s = shots_scene
    assert tuple(VIEW_TABLE) == CAMERA_VIEWS
    assert {n for n, v in VIEW_TABLE.items() if v.mounted} == {"driver", "bonnet"}
    assert {n for n, v in VIEW_TABLE.items() if v.inside} == {"driver"}
    assert {n for n, v in VIEW_TABLE.items() if v.rides == "follow"} == {"chase", "driver", "bonnet"}
    assert all(v.rides in ("follow", "target") for v in VIEW_TABLE.values())
    for bad in ("nope", "Low", "", None):
        with pytest.raises(ValueError, match="camera.view"):
            view_of(bad)
        with pytest.raises(ValueError, match="camera.view"):
            view_preset(bad, s.vehicles[0], s.vehicles[0], s.camera.look_ahead)
        if bad is not None:  # None: the scene's own camera
            with pytest.raises(ValueError, match="camera.view"):
                scene_camera(s, bad)


def test_a_view_is_one_row(shots_scene, monkeypatch):
    """A row added to the table is a view: the shots, the rig (mounted, orbiting) and the vehicle ridden with
    follow from it alone."""
    from taichi_rocks.motion import camera
    from taichi_rocks.motion.camera import CameraView

    s = shots_scene
    eye, aim = np.array([0.5, -0.3, 2.4]), np.array([3.0, 0.0, 1.0])
    row = CameraView("roof", mounted=True, rides="follow", inside=False, pose=lambda f, t, la: (eye, aim))
    monkeypatch.setitem(camera.VIEW_TABLE, "roof", row)
    (shot,) = shots_of(s, "roof")
    assert shot.view == "roof" and shot.offset == tuple(eye) and shot.aim == tuple(aim)
    assert shot.rides == shot.target  # mounted: the aim is in the frame of the vehicle ridden with
    rig, i, j = camera.camera_of(s, "roof")
    assert rig.mounted and rig.orbit_period is None and (i, j) == (shot.rides, shot.target)
    np.testing.assert_array_equal(rig.offset, eye)
    orbiting = CameraView("spin", mounted=False, rides="target", inside=False, pose=lambda f, t, la: (eye, aim),
                          orbits=True)
    monkeypatch.setitem(camera.VIEW_TABLE, "spin", orbiting)
    rig, _, _ = camera.camera_of(s, "spin")
    assert not rig.mounted and rig.orbit_period == s.camera.orbit_period
