"""Camera shots in ``render`` (app/render.py): the camera of every frame is the shot's rig at that time
(tests/shots_util.py writes the rules out), the cuts fall on their frames, and a render resumed from a state
saved before a cut, replayed across it, gives the uninterrupted render's frames. (The same shots in ``view``:
tests/render/test_view.py; in ``export``: tests/output/test_export_values.py.)"""

import os

import numpy as np
import pytest

from shots_util import CUTS, VIEWS, expected_eyes, write_shots_scene

W, H = 160, 96
FRAMES, FPS = 48, 30.0  # 1.6 s: both cuts (frames 23 and 41)


def _spy(monkeypatch, eyes, shots):
    """Record, for every frame the render draws, the renderer's camera (world eye) and its shot's view."""
    from taichi_rocks.render.renderer import Renderer

    real = Renderer.render_frame

    def render_frame(self, view=None):
        img = real(self, view)
        eyes.append(np.asarray(self.view().eye, np.float64) + self.sim.origin)
        shots.append(self.rig.shot.view)
        return img

    monkeypatch.setattr(Renderer, "render_frame", render_frame)


@pytest.fixture(scope="module")
def shots_render(taichi_cpu, tmp_path_factory):
    """The shots scene rendered uninterrupted: its frames, each frame's camera and shot."""
    from taichi_rocks.app.render import render_scene
    from taichi_rocks.config.scene import load_scene

    d = tmp_path_factory.mktemp("shots")
    scene = load_scene(write_shots_scene(d))
    eyes, shots, frames = [], [], []
    with pytest.MonkeyPatch.context() as mp:
        _spy(mp, eyes, shots)
        render_scene(scene, out_dir=d / "render", frames=FRAMES, fps=FPS, resolution=(W, H), fmt="png",
                     progress=False, on_frame=lambda k, img: frames.append(img.copy()))
    return scene, np.array(eyes), shots, frames


def test_every_frame_is_the_shots_camera_and_cuts_fall_on_their_frames(shots_render):
    scene, eyes, shots, _ = shots_render
    want, shot = expected_eyes(scene, [k / FPS for k in range(FRAMES)])
    np.testing.assert_allclose(eyes, want, rtol=0, atol=2e-4)  # the renderer's local f32 camera + its origin
    assert shots == [VIEWS[k] for k in shot]
    first = [shots.index(v) for v in VIEWS]
    assert first == [0] + [int(np.ceil(c * FPS - 1e-9)) for c in CUTS] == [0, 23, 41]


def test_the_frames_change_at_the_cuts(shots_render):
    """The picture jumps at a cut, far more than between two frames of one shot."""
    _, _, _, frames = shots_render
    step = [np.abs(frames[k].astype(int) - frames[k - 1].astype(int)).mean() for k in range(1, FRAMES)]
    cuts = [step[22], step[40]]
    others = [x for k, x in enumerate(step) if k not in (22, 40)]
    assert min(cuts) > 3 * np.percentile(others, 90), (cuts, np.percentile(others, 90))


@pytest.mark.parametrize("stop_at, lose, resumed_from, replayed_from", [(26, True, 24, 20), (31, False, 31, 30)])
def test_a_resumed_render_equals_the_uninterrupted_one_across_cuts(shots_render, tmp_path, stop_at, lose,
                                                                     resumed_from, replayed_from):
    """Interrupted with a state saved every 5 frames. At frame 26, the newest state and the frames after the
    one before it lost: resuming restores the state after frame 19 (before the cut at frame 23) and replays the
    simulation and the camera across the cut without drawing. At frame 31: the state after frame 29, inside
    the driver's shot, whose gaze is smoothing into the turn. Either way the frames from there on (across the
    second cut) are the uninterrupted render's."""
    import imageio.v3 as iio

    from taichi_rocks.app.render import render_scene

    scene, _, _, reference = shots_render

    def stop(k, img):
        if k == stop_at:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render_scene(scene, out_dir=tmp_path, frames=FRAMES, fps=FPS, resolution=(W, H), fmt="png", progress=False,
                     on_frame=stop, checkpoint_every=5)
    if lose:
        (tmp_path / ".resume" / "frame_00024.npz").unlink()  # the newest state: lost, as if still queued
        for k in (24, 25):  # and the frames after the state kept: drawn again
            (tmp_path / "frames" / f"frame_{k:05d}.png").unlink(missing_ok=True)
    res = render_scene(scene, out_dir=tmp_path, frames=FRAMES, fps=FPS, resolution=(W, H), fmt="png",
                       progress=False, resume=True, checkpoint_every=5)
    assert (res["resumed_from"], res["replayed_from"]) == (resumed_from, replayed_from)
    names = sorted(os.listdir(tmp_path / "frames"))
    assert names == [f"frame_{k:05d}.png" for k in range(FRAMES)]
    for k in range(FRAMES):
        np.testing.assert_array_equal(iio.imread(tmp_path / "frames" / names[k]), reference[k], err_msg=names[k])
