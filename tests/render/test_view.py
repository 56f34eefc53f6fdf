"""``taichi-rocks view`` in a real window, under a virtual X display (Xvfb), driven by xdotool.

One viewer process of scenes/minimal.toml at 480x320 serves most tests (each first puts it in the state it
needs: paused or playing, panel shown or hidden); the exit tests start their own. Every wait is on what the
viewer reports: its status file (TAICHI_ROCKS_VIEW_STATUS, written after every frame shown). Xvfb, xdotool
and xdpyinfo are required (tools/setup.sh installs them): without them these tests fail. The display and the
viewer driver: view_util.py.
"""

import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from view_util import ROOT, TIMEOUT, View, _env, xdisplay  # noqa: F401  (xdisplay: the display fixture)

W, H = 480, 320  # View's default resolution


@pytest.fixture(scope="module")
def view(xdisplay, tmp_path_factory):
    v = View(xdisplay, tmp_path_factory.mktemp("view"))
    yield v
    if v.proc.poll() is None:
        v.proc.kill()
    v.finish()


def test_window_opens(view):
    s = view.wait(lambda s: s["shown"] >= 3)
    geometry = view.xdo("getwindowgeometry", view.wid).stdout
    assert f"{W}x{H}" in geometry, geometry
    assert s["camera"] == "chase" and s["panel"] is True and s["frames"] == 60  # 2 s at 30 fps
    assert "view: ready" in view.stderr().splitlines()


def test_pause_stops_time(view):
    view.toggle_until("space", lambda s: not s["paused"], "playing")
    f0 = view.status()["frame"]
    view.wait(lambda s: s["frame"] != f0, "time to move while playing")
    s = view.toggle_until("space", lambda s: s["paused"], "paused")
    later = view.frames_later(10)
    assert later["frame"] == s["frame"] and later["time"] == s["time"]
    view.key("Right")  # one step while paused
    stepped = view.wait(lambda x: x["frame"] != s["frame"], "one frame step")
    assert stepped["frame"] == (s["frame"] + 1) % s["frames"] and stepped["paused"]


def test_key_moves_camera(view):
    view.still(panel=False)
    assert view.status()["camera"] == "chase"  # the scene's view (each test that changes it goes back)
    view.frames_later()
    before = view.screenshot().astype(np.int16)
    view.key("c")
    s = view.wait(lambda s: s["camera"] == "side", "the side camera")
    assert s["frame"] == view.status()["frame"]  # paused: only the camera moved
    view.frames_later()
    after = view.screenshot().astype(np.int16)
    diff = np.abs(after - before).max(axis=2)
    assert (diff > 30).mean() > 0.2, (diff > 30).mean()
    view.key("c")
    view.wait(lambda s: s["camera"] == "low", "the low camera")
    while view.status()["camera"] != "chase":  # back to the scene's own view for the other tests
        cam = view.status()["camera"]
        view.key("c")
        view.wait(lambda s: s["camera"] != cam, "the next camera")


def test_p_writes_a_png_named_after_scene_and_time(view):
    view.still(panel=True)
    img = view.screenshot()
    s = view.status()
    path = Path(s["screenshots"][-1])
    stem = f"minimal_t{s['time']:06.2f}"  # other tests may have taken this moment already: then _2, _3 ...
    assert path.parent == view.cwd and re.fullmatch(re.escape(stem) + r"(_\d+)?\.png", path.name), path.name
    assert img.shape[:2] == (H, W)
    assert img.reshape(-1, img.shape[2])[:, :3].std(axis=0).min() > 10  # not blank: sky, ground, rocks, panel
    view.screenshot()  # same moment: another file, the first kept
    second = Path(view.status()["screenshots"][-1])
    assert second.name.startswith(stem + "_") and second != path and path.exists() and second.exists()


def test_scrubbing_back_shows_the_frame_render_draws(view, tmp_path):
    import imageio.v3 as iio

    k = 10
    render = subprocess.run([sys.executable, "-m", "taichi_rocks", "render", str(ROOT / "scenes" / "minimal.toml"),
                             "--frames", str(k + 1), "--resolution", f"{W}x{H}", "--format", "png", "--out",
                             str(tmp_path)], env=_env(None), capture_output=True, text=True, timeout=600)
    assert render.returncode == 0, render.stderr
    offline = iio.imread(tmp_path / "frames" / f"frame_{k:05d}.png").astype(np.int16)
    view.toggle_until("space", lambda s: not s["paused"], "playing")
    view.wait(lambda s: s["frame"] >= k + 3, f"frame {k + 3}")
    s = view.still(panel=False)
    assert s["params"]["world.wetness"] == 0.0  # the scene's parameters, as render has them
    replayed = s["replayed"]
    while view.status()["frame"] != k:  # back, one frame at a time (Left)
        f = view.status()["frame"]
        view.key("Left" if f > k else "Right")
        view.wait(lambda x: x["frame"] != f, "a frame step")
    s = view.status()
    assert s["replayed"] > replayed  # going back restored a saved state and simulated forward
    shown = view.screenshot()[:, :, :3].astype(np.int16)
    diff = np.abs(shown - offline[:, :, :3]).max(axis=2)
    assert diff.mean() < 2.0 and (diff > 24).mean() < 0.005, (diff.mean(), (diff > 24).mean())


def first_slider(img: np.ndarray, panel_left: int) -> tuple:
    """(row, bar start, bar end, grab centre) in pixels of the first slider right of ``panel_left``, found in a
    screenshot: Dear ImGui draws a slider as a blue bar (its frame) with a brighter blue grab; the panel's
    title bar is blue too but has no grab."""
    rgb = img[:, panel_left:, :3].astype(int)
    grab = (rgb[..., 2] > 180) & (rgb[..., 0] < 120)
    rows = np.flatnonzero(grab.sum(axis=1) >= 3)
    assert len(rows), "no slider grab in the panel"
    run_end = rows[0] + int(np.argmax(np.diff(np.append(rows, rows[-1] + 2)) > 1))  # the first run of rows
    y = (rows[0] + run_end) // 2
    blue = np.flatnonzero(rgb[y, :, 2] - rgb[y, :, 0] > 30)  # the bar (frame and grab; its value's text
    g = np.flatnonzero(grab[y])  # breaks it), then only the label, in grey, to its right
    return int(y), panel_left + int(blue[0]), panel_left + int(blue[-1]), panel_left + int(g.mean())


def test_wetness_slider_dragged_with_the_mouse_reaches_the_kernels(view):
    from taichi_rocks.render.panel import SLIDERS, panel_width

    assert next(iter(SLIDERS)) == "world.wetness"  # the first widget of the "tune" panel
    view.still(panel=True)
    assert view.status()["params"]["world.wetness"] == 0.0
    left = int(round(W * (1.0 - panel_width(W))))  # the panel's left edge, from its layout
    y, x0, x1, grab = first_slider(view.screenshot(), left)
    assert x0 <= grab < x0 + 0.25 * (x1 - x0) and x1 - x0 > 60, (x0, x1, grab)  # at 0: the grab on the left
    s = _drag(view, grab, x0 + int(0.9 * (x1 - x0)), y, lambda s: s["params"]["world.wetness"] > 0.5)
    assert s["params"]["world.wetness"] <= 1.0
    assert s["params"]["world.gravity"] == pytest.approx(9.81, rel=1e-6)  # the other sliders did not move
    # back to the scene's value (the far left: 0) for the other tests
    _drag(view, x0 + (x1 - x0) // 2, x0 - 60, y, lambda s: s["params"]["world.wetness"] == 0.0)


def _drag(view, x_from, x_to, y, done):
    """Drag the mouse along row ``y``, then wait until ``done(status)``; again if the viewer opened a new window
    meanwhile (app/view.py: a drag across two windows is lost)."""
    for _ in range(3):
        before = view.status()["window_refreshes"]
        _drag_once(view, x_from, x_to, y)
        s = view.wait(lambda s: done(s) or s["window_refreshes"] != before, "the dragged value")
        if done(s):
            return s
    raise AssertionError("the drag never took effect")


def _drag_once(view, x_from, x_to, y):
    view.xdo("mousemove", "--window", view.wid, str(x_from), str(y))
    view.frames_later()
    view.xdo("mousedown", "1")
    view.frames_later()
    step = 20 if x_to > x_from else -20
    for x in range(x_from + step, x_to + step, step):
        view.xdo("mousemove", "--window", view.wid, str(x), str(y))
        view.frames_later(2)
    view.xdo("mouseup", "1")
    view.frames_later()
    view.xdo("mousemove", "--window", view.wid, "5", "5")


def test_escape_exits_0_and_record_writes_the_frames_shown(xdisplay, tmp_path):
    rec = tmp_path / "rec"
    v = View(xdisplay, tmp_path, "--record", rec)
    s = v.wait(lambda s: s["recorded"] >= 3, "3 recorded frames")
    for _ in range(3):  # a key sent while the viewer replaces its window is lost: press again
        v.key("Escape")
        try:
            v.proc.wait(timeout=5)
            break
        except subprocess.TimeoutExpired:
            if v.proc.poll() is None:
                v.frames_later(5)
    assert v.finish() == 0, v.stderr()
    frames = sorted(rec.glob("frame_*.png"))
    assert len(frames) >= s["recorded"] and frames[0].name == "frame_00000.png"
    assert "Traceback" not in v.stderr() and "frames written to" in (tmp_path / "stdout.txt").read_text()


def test_record_refuses_a_folder_with_files(xdisplay, tmp_path):
    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "keep.txt").write_text("x")
    r = subprocess.run([sys.executable, "-m", "taichi_rocks", "view", str(ROOT / "scenes" / "minimal.toml"),
                        "--record", str(rec)], env=_env(xdisplay), capture_output=True, text=True, timeout=TIMEOUT)
    assert r.returncode == 2 and "not empty" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert sorted(p.name for p in rec.iterdir()) == ["keep.txt"]


@pytest.mark.parametrize("display", [None, ":9999"])
def test_no_display_exits_2_pointing_to_render(display):
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "taichi_rocks", "view", str(ROOT / "scenes" / "minimal.toml")],
                       env=_env(display), capture_output=True, text=True, timeout=TIMEOUT)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "display" in lines[0] and "taichi-rocks render" in lines[0]
    assert "Starting on arch" not in r.stdout + r.stderr  # Taichi never started
    assert time.perf_counter() - t < TIMEOUT


def test_the_viewer_plays_the_scene_shots_and_its_camera_keys_keep_working(xdisplay, tmp_path):
    """A scene with [[camera.shot]] tables opens on its own camera ("shots"): every frame shown, playing and
    stepped back across a cut, has the shot's camera at that time (tests/shots_util.py); c goes on to the
    presets (the chase view, then the others) and round again to "shots", which plays them again."""
    from shots_util import CUTS, expected_eyes, write_shots_scene
    from taichi_rocks.config.scene import load_scene

    path = write_shots_scene(tmp_path, name="shots")
    scene = load_scene(path)
    fps = scene.render.fps
    frames = int(round(scene.duration * fps))
    want, shot = expected_eyes(scene, [k / fps for k in range(frames)])
    v = View(xdisplay, tmp_path, scene=path)
    try:
        seen = {}
        s = v.wait(lambda s: s["camera"] == "shots", "the scene's own camera")
        while len(set(shot[k] for k in seen)) < 3:  # play until frames of all three shots were shown
            s = v.frames_later(1)
            assert s["camera"] == "shots"
            seen[s["frame"]] = np.array(s["eye"])
        for k, eye in seen.items():
            np.testing.assert_allclose(eye, want[k], rtol=0, atol=2e-4, err_msg=f"frame {k}")
        s = v.still(panel=False)
        cut = int(np.ceil(CUTS[0] * fps - 1e-9))
        while v.status()["frame"] != cut - 1:  # step to just before the first cut, then across it
            f = v.status()["frame"]
            v.key("Left" if f > cut - 1 else "Right")
            v.wait(lambda x: x["frame"] != f, "a frame step")
        for k in (cut - 1, cut):
            if k == cut:
                v.key("Right")
            s = v.wait(lambda x: x["frame"] == k, f"frame {k}")
            np.testing.assert_allclose(s["eye"], want[k], rtol=0, atol=2e-4, err_msg=f"frame {k}")
        v.key("c")
        s = v.wait(lambda x: x["camera"] == "chase", "the chase preset after the shots")
        while v.status()["camera"] != "shots":  # round the presets, back to the scene's own camera
            cam = v.status()["camera"]
            v.key("c")
            v.wait(lambda x: x["camera"] != cam, "the next camera")
        s = v.frames_later(2)
        np.testing.assert_allclose(s["eye"], want[s["frame"]], rtol=0, atol=2e-4)
    finally:
        if v.proc.poll() is None:
            v.proc.kill()
        v.finish()
