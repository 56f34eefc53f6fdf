"""The view's clock (app/timeline.py) without a window: scrubbing back equals playing straight to the frame,
the saved states stay bounded, playback speed and looping; and the viewer's file helpers."""

import numpy as np
import pytest

FPS = 30.0


@pytest.fixture(scope="module")
def scene(taichi_cpu, scenes_dir):
    from taichi_rocks.config.scene import load_scene

    return load_scene(scenes_dir / "minimal.toml")


def _live(scene):
    """A simulation, its camera rig and the view() the Renderer would call (rig advanced to sim.time)."""
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.render.camera import camera_of, look

    sim = Simulation(scene)
    rig, follow, _ = camera_of(scene)

    def view():
        p = sim.vehicle_poses()[follow]
        return look(rig, p.position, p.heading, sim.time, sim.origin)

    view()
    return sim, rig, view


def test_scrubbing_back_equals_playing_straight_to_the_frame(scene):
    from taichi_rocks.app.timeline import Timeline

    sim, rig, view = _live(scene)
    tl = Timeline(FPS, 60, every=5, keep=3)
    tl.save(sim, rig)
    tl.seek(23, sim, rig, view)
    assert tl.frame == 23 and len(tl.saved) <= 4 and 0 in tl.saved and tl.every > 5  # thinned
    tl.seek(12, sim, rig, view)
    got, heading = sim.state(), rig.heading
    ref, ref_rig, ref_view = _live(scene)
    for k in range(1, 13):  # as render does: every frame time in turn, the camera at each
        ref.advance_to(k / FPS)
        ref_view()
    want = ref.state()
    for key in ("positions", "velocities", "phase", "launches_total", "time"):
        assert np.array_equal(np.asarray(got[key]), np.asarray(want[key])), key
    assert heading == ref_rig.heading and tl.time == pytest.approx(12 / FPS)


def test_playback_speed_pause_and_loop(scene):
    from taichi_rocks.app.timeline import MAX_CATCH_UP, Timeline

    sim, rig, view = _live(scene)
    tl = Timeline(FPS, 10, every=4)
    tl.save(sim, rig)
    tl.playing = False
    assert tl.tick(0.1, sim, rig, view) == 0 and tl.frame == 0
    tl.playing, tl.speed = True, 2.0
    assert tl.tick(0.1, sim, rig, view) == 6  # 0.2 s of simulated time at 30 fps
    tl.speed = 4.0
    # 0.4 s more would be 12 frames: frames 7, 8, 9 (the last), then round to frame 0 (counted as one)
    assert tl.tick(0.1, sim, rig, view) == 4 and tl.frame == 0 and sim.time == 0.0
    assert tl.tick(0.1, sim, rig, view) == MAX_CATCH_UP  # behind: at most this many frames per frame shown


def test_speed_steps_between_a_quarter_and_four():
    from taichi_rocks.app.timeline import Timeline

    tl = Timeline(FPS, 10)
    for _ in range(5):
        tl.faster(False)
    assert tl.speed == 0.25
    for _ in range(9):
        tl.faster(True)
    assert tl.speed == 4.0


def test_screenshot_names_never_overwrite(tmp_path):
    from taichi_rocks.app.view import screenshot_path

    p = screenshot_path(tmp_path, "convoy", 3.25)
    assert p.name == "convoy_t003.25.png"
    p.write_bytes(b"x")
    assert screenshot_path(tmp_path, "convoy", 3.25).name == "convoy_t003.25_2.png"


def test_record_folder_must_be_empty_unless_overwrite(tmp_path):
    from taichi_rocks.app.view import check_record_dir

    check_record_dir(tmp_path / "new", False)  # missing: fine
    (tmp_path / "frame_00000.png").write_bytes(b"x")
    with pytest.raises(FileExistsError, match="not empty"):
        check_record_dir(tmp_path, False)
    check_record_dir(tmp_path, True)
    assert not list(tmp_path.glob("frame_*.png"))


def test_tread_patch_corners_against_a_direct_construction():
    from taichi_rocks.render.overlays import patch_corners

    rng = np.random.default_rng(3)
    n = 5
    bottom = rng.normal(size=(n, 3))
    ang = rng.uniform(0, 2 * np.pi, n)
    fwd = np.stack([np.cos(ang), np.sin(ang)], 1)
    hl, hw = rng.uniform(0.05, 0.2, n), rng.uniform(0.05, 0.2, n)
    got = patch_corners(bottom, fwd, hl, hw)
    for i in range(n):
        f = np.array([fwd[i, 0], fwd[i, 1], 0.0])
        s = np.array([-fwd[i, 1], fwd[i, 0], 0.0])
        want = [bottom[i] + a * hl[i] * f + b * hw[i] * s for a, b in ((1, 1), (1, -1), (-1, -1), (-1, 1))]
        np.testing.assert_allclose(got[i], want, atol=1e-12)
    assert np.allclose(got[:, :, 2], bottom[:, None, 2])  # flat on the ground
