"""``taichi-rocks view`` as a process, in a real window under a virtual X display (Xvfb), driven by xdotool: how
it ends and what it leaves behind. ``--quit-after`` closes the window by itself (exit 0, a summary line) and
``--record DIR --overwrite`` replaces DIR's old frames with every frame shown; a scene with camera shots plays
them (every frame shown, playing and stepped back across a cut, has the shot's camera) and keeps its camera
keys, and Escape then ends that viewer with exit 0, its ``--record`` frames written; ``--record`` refuses a
folder with files, and without a display ``view`` exits 2 pointing to ``render`` before Taichi starts.

Each viewer here is a process of its own (its end is what is tested): one ended by ``--quit-after``, one by
Escape. The controls, on one shared viewer: test_view_controls.py. Every wait is on what the viewer reports:
its status file (TAICHI_ROCKS_VIEW_STATUS, written after every frame shown). Xvfb, xdotool and xdpyinfo are
required (tools/setup.sh installs them): without them these tests fail. The display and the viewer driver:
view_util.py.
"""

import json
import subprocess
import sys
import time

import numpy as np
import pytest

from view_util import ROOT, TIMEOUT, View, _env, xdisplay  # noqa: F401  (xdisplay: the display fixture)


def test_quit_after_ends_the_window_and_record_overwrite_replaces_old_frames(xdisplay, tmp_path):
    """--quit-after: the viewer closes by itself that long after its first frame (exit 0, a summary line);
    --record DIR --overwrite: DIR's old frames are gone, every frame shown is written, other files stay;
    --seed: the window's simulation has that seed; the user's imgui.ini in the folder it started from is left
    alone, the panel's layout kept in the per-user configuration folder instead."""
    import imageio.v3 as iio

    rec = tmp_path / "rec"
    rec.mkdir()
    for k in range(300):  # more than 1.5 s can show (at most 30 frames a second)
        (rec / f"frame_{k:05d}.png").write_bytes(b"old")
    (rec / "notes.txt").write_text("mine")
    status_file = tmp_path / "status.json"
    (tmp_path / "imgui.ini").write_text("mine")
    r = subprocess.run([sys.executable, "-m", "taichi_rocks", "view", str(ROOT / "scenes" / "minimal.toml"),
                        "--resolution", "320x180", "--seed", "5", "--quit-after", "1.5", "--record", str(rec),
                        "--overwrite"], cwd=tmp_path, env=_env(xdisplay, TAICHI_ROCKS_VIEW_STATUS=str(status_file),
                                                               XDG_CONFIG_HOME=str(tmp_path / "config")),
                       capture_output=True, text=True, timeout=300 + TIMEOUT)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "imgui.ini").read_text() == "mine"
    assert (tmp_path / "config" / "taichi-rocks" / "imgui.ini").is_file()
    assert "view: ready" in r.stderr.splitlines() and "Traceback" not in r.stderr
    status = json.loads(status_file.read_text())
    n = status["recorded"]
    assert status["seed"] == 5 and status["shown"] == n >= 2
    head, seconds, tail = r.stdout.strip().partition(" frames shown in ")
    assert head == f"view: {n}" and tail.endswith(f" s, {n} frames written to {rec}"), r.stdout
    assert float(tail.split(" s,")[0]) >= 1.5
    frames = sorted(p.name for p in rec.glob("frame_*.png"))
    assert frames == [f"frame_{k:05d}.png" for k in range(n)]  # none of the 300 old ones left
    assert (rec / "notes.txt").read_text() == "mine" and len(list(rec.iterdir())) == n + 1
    assert iio.imread(rec / frames[-1]).shape[:2] == (180, 320)


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


def _check_shots(v, want, shot, cut):
    """The scene's shots, played and stepped (see the test)."""
    seen = {}

    def play_until(done):
        while not done():
            s = v.frames_later(1)
            assert s["camera"] == "shots"
            seen[s["frame"]] = np.array(s["eye"])

    v.wait(lambda s: s["camera"] == "shots", "the scene's own camera")
    # paused a few frames before the first cut (or after it, on a slow machine), forward to the cut, one step back
    # across it (the newest saved state, frame 0, restored and simulated forward) and forward again: few steps
    # back, each of which replays the frames since frame 0
    play_until(lambda: any(k >= cut - 5 for k in seen))
    v.still(panel=False)
    v.step_to(cut)
    for key, k in (("Left", cut - 1), ("Right", cut)):
        s = v.press(key, lambda x: x["frame"] == k, f"frame {k}")
        np.testing.assert_allclose(s["eye"], want[k], rtol=0, atol=2e-4, err_msg=f"frame {k}")
    v.toggle_until("space", lambda s: not s["paused"], "playing")
    play_until(lambda: len(set(shot[k] for k in seen)) == 3)  # until frames of all three shots were shown
    for k, eye in seen.items():
        np.testing.assert_allclose(eye, want[k], rtol=0, atol=2e-4, err_msg=f"frame {k}")
    v.still(panel=False)
    v.press("c", lambda x: x["camera"] == "chase", "the chase preset after the shots")
    while v.status()["camera"] != "shots":  # round the presets, back to the scene's own camera
        cam = v.status()["camera"]
        v.press("c", lambda x: x["camera"] != cam, "the next camera")
    s = v.frames_later(2)
    np.testing.assert_allclose(s["eye"], want[s["frame"]], rtol=0, atol=2e-4)


def _escape(v) -> int:
    """Press Escape until the viewer ends; its exit status."""
    for _ in range(3):  # a key sent while the viewer replaces its window is lost: press again
        v.key("Escape")
        try:
            v.proc.wait(timeout=5)
            break
        except subprocess.TimeoutExpired:
            if v.proc.poll() is None:
                v.frames_later(5)
    return v.finish()


def test_the_viewer_plays_the_scene_shots_its_camera_keys_work_and_escape_exits_0_with_the_frames_recorded(
        xdisplay, tmp_path):
    """A scene with [[camera.shot]] tables opens on its own camera ("shots"): every frame shown, playing and
    stepped back across a cut, has the shot's camera at that time (tests/shots_util.py); c goes on to the
    presets (the chase view, then the others) and round again to "shots", which plays them again. Escape then
    ends the viewer: exit 0, and --record wrote the frames shown from frame_00000.png on."""
    from shots_util import CUTS, expected_eyes, write_shots_scene
    from taichi_rocks.config.scene import load_scene

    path = write_shots_scene(tmp_path, name="shots")
    scene = load_scene(path)
    fps = scene.render.fps
    frames = int(round(scene.duration * fps))
    want, shot = expected_eyes(scene, [k / fps for k in range(frames)])
    rec = tmp_path / "rec"
    v = View(xdisplay, tmp_path, "--record", rec, scene=path)
    try:
        _check_shots(v, want, shot, int(np.ceil(CUTS[0] * fps - 1e-9)))
        s = v.wait(lambda s: s["recorded"] >= 3, "3 recorded frames")
        assert _escape(v) == 0, v.stderr()
    finally:
        if v.proc.poll() is None:
            v.proc.kill()
        v.finish()
    frames = sorted(rec.glob("frame_*.png"))
    assert len(frames) >= s["recorded"] and frames[0].name == "frame_00000.png"
    assert "Traceback" not in v.stderr() and "frames written to" in (tmp_path / "stdout.txt").read_text()
