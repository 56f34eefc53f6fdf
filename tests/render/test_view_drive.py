"""``taichi-rocks view --drive NAME --record-drive FILE`` in a real window (Xvfb, xdotool; view_util.py): keys held
drive the vehicle (A turns it left, W speeds it up, S brakes it and then reverses it), the bed follows it off its
road, the chase camera follows it and the status reports its speed; going back shows the frames driven and
driving on from there replaces the rest; Escape writes the drive, which ``check`` accepts and a scene's recorded
path replays to the bit; the refusals (an unknown vehicle, --record-drive alone, an existing file) exit 2 before a
window opens.

One viewer process of scenes/minimal.toml (one car, scripted along +x at 10 m/s: --drive makes it live where its
path starts) serves the driving tests, in this order. Every wait is on the viewer's status file
(TAICHI_ROCKS_VIEW_STATUS, written after every frame shown), never on a sleep."""

import math
import subprocess
import sys

import numpy as np
import pytest

from cli_util import cli
from view_util import ROOT, TIMEOUT, View, _env, xdisplay  # noqa: F401  (xdisplay: the display fixture)

SCENE = ROOT / "scenes" / "minimal.toml"


@pytest.fixture(scope="module")
def view(xdisplay, tmp_path_factory):
    cwd = tmp_path_factory.mktemp("drive")
    v = View(xdisplay, cwd, "--drive", "car", "--record-drive", cwd / "out" / "car.drive", resolution=(480, 320))
    v.drive_file = cwd / "out" / "car.drive"
    try:
        yield v
    finally:
        if v.proc.poll() is None:
            v.proc.kill()
        v.finish()


def _hold(v, key, done, what):
    """Hold ``key`` down until ``done(status)``; held again if the viewer replaced its window meanwhile (a key
    held in the old window is let go there)."""
    for _ in range(3):
        before = v.status()["window_refreshes"]
        v.xdo("keydown", "--window", v.wid, key)
        try:
            s = v.wait(lambda s: done(s) or s["window_refreshes"] != before, what)
        finally:
            v.xdo("keyup", "--window", v.wid, key, check=False)
        if done(s):
            return s
    raise AssertionError(f"{key} held had no effect while the viewer kept opening new windows: {what}")


def test_the_keys_drive_the_car_off_its_road_and_the_bed_and_the_camera_follow(view):
    s = view.wait(lambda s: s["shown"] >= 2 and not s["paused"], "playing")
    d = s["drive"]
    assert d["vehicle"] == "car" and d["speed"] == pytest.approx(10.0, abs=0.5) and s["camera"] == "chase"
    s = _hold(view, "a", lambda s: s["drive"]["heading"] > 0.6, "a left turn")
    assert s["drive"]["steering"] == 1 and s["drive"]["position"][1] > 0.5  # off the road along +x, to the left
    s = _hold(view, "w", lambda s: s["drive"]["speed"] > 14.0, "speeding up")
    assert s["drive"]["pedal"] == 1
    s = view.frames_later(3)
    p = np.array(s["drive"]["position"])
    assert np.array_equal(np.array(s["bed_center"]), p)  # the bed is where the car is
    eye, fwd = np.array(s["eye"]), np.array(s["forward"])
    heading = np.array([math.cos(s["drive"]["heading"]), math.sin(s["drive"]["heading"])])
    assert 5.0 < np.hypot(*(eye - p)[:2]) < 15.0 and fwd[:2] @ heading > 0.8  # behind it, looking its way
    s = _hold(view, "s", lambda s: s["drive"]["speed"] < -0.5, "braking, then reversing")
    assert s["drive"]["pedal"] == -1


def test_going_back_shows_the_frames_driven_and_driving_on_replaces_the_rest(view):
    s = view.still(panel=True)
    f = s["frame"]
    assert s["drive"]["rows"] == f + 1
    s = view.press("Left", lambda x: x["frame"] == f - 1, "a frame back")
    assert s["drive"]["rows"] == f  # the frames after it are no longer the drive
    view.back = (f - 1, s["drive"]["position"])
    view.toggle_until("space", lambda s: not s["paused"], "playing")
    view.wait(lambda s: s["frame"] >= f + 5, "driving on")


def test_escape_writes_the_drive_and_a_scene_replays_it_to_the_bit(view, tmp_path):
    from taichi_rocks.config.scene import load_scene, parse_scene, scene_to_dict
    from taichi_rocks.motion.vehicles import Fleet

    last = view.frames_later(2)
    view.key("Escape")
    assert view.finish() == 0 and "Traceback" not in view.stderr()
    final = view.status()
    out = (view.cwd / "stdout.txt").read_text()
    rows = final["drive"]["rows"]
    assert f"{rows} poses of car written to {view.drive_file}" in out and rows >= last["drive"]["rows"]
    r = cli("check", view.drive_file)
    assert r.returncode == 0 and f"{rows} poses" in r.stdout, r.stderr
    data = scene_to_dict(load_scene(SCENE))
    data["vehicle"][0]["path"] = {"kind": "recorded", "file": str(view.drive_file)}
    fleet = Fleet(parse_scene(data))
    fps = load_scene(SCENE).render.fps
    t = final["frame"] / fps
    assert list(fleet.poses(t)[0].position) == final["drive"]["position"]  # the last frame, to the bit
    k, where = view.back
    assert list(fleet.poses(k / fps)[0].position) == where  # the frame gone back to stayed in the drive


@pytest.mark.parametrize("args, words", [
    (("--drive", "truck"), "--drive: no vehicle named 'truck' (the vehicles: car)"),
    (("--record-drive", "x.drive"), "--record-drive needs --drive NAME"),
    (("--drive", "car", "--record-drive", "old.drive"), "old.drive exists (pass --overwrite to replace it)")])
def test_drive_refusals_exit_2_before_a_window_opens(xdisplay, tmp_path, args, words):
    (tmp_path / "old.drive").write_text("mine")
    r = subprocess.run([sys.executable, "-m", "taichi_rocks", "view", str(SCENE), *args], cwd=tmp_path,
                       env=_env(xdisplay), capture_output=True, text=True, timeout=TIMEOUT)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and words in lines[0], r.stderr
    assert "Starting on arch" not in r.stdout + r.stderr and (tmp_path / "old.drive").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.drive"]
