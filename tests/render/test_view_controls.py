"""``taichi-rocks view``'s controls in a real window (Xvfb, xdotool; view_util.py): the Up/Down speed keys, ``f``
and the free camera (W/A/S/D/E/Q), the camera buttons, the overlay check boxes, the time slider and the
recompile buttons of the panel; and ``--quit-after`` with ``--record DIR --overwrite`` and ``--seed``.

One viewer process (480x720: the whole "tune" panel fits) serves the control tests, in this order (the recompile
buttons last: they change the simulation). Widgets are found in a screenshot, not at fixed pixels: Dear ImGui
draws every slider, button and check box on a blue frame, so the rows of blue in the panel's column are its
widgets, in render/panel.py's order. Every wait is on the viewer's status file."""

import json
import subprocess
import sys

import numpy as np
import pytest

from view_util import ROOT, TIMEOUT, View, _env, xdisplay  # noqa: F401  (xdisplay: the display fixture)

W, H = 480, 720


# ---------------------------------------------------------------------------------------------- a process of its own
def test_quit_after_ends_the_window_and_record_overwrite_replaces_old_frames(xdisplay, tmp_path):
    """--quit-after: the viewer closes by itself that long after its first frame (exit 0, a summary line);
    --record DIR --overwrite: DIR's old frames are gone, every frame shown is written, other files stay;
    --seed: the window's simulation has that seed. Runs before the shared viewer starts (not beside it)."""
    import imageio.v3 as iio

    rec = tmp_path / "rec"
    rec.mkdir()
    for k in range(300):  # more than 1.5 s can show (at most 30 frames a second)
        (rec / f"frame_{k:05d}.png").write_bytes(b"old")
    (rec / "notes.txt").write_text("mine")
    status_file = tmp_path / "status.json"
    r = subprocess.run([sys.executable, "-m", "taichi_rocks", "view", str(ROOT / "scenes" / "minimal.toml"),
                        "--resolution", "320x180", "--seed", "5", "--quit-after", "1.5", "--record", str(rec),
                        "--overwrite"], cwd=tmp_path, env=_env(xdisplay, TAICHI_ROCKS_VIEW_STATUS=str(status_file)),
                       capture_output=True, text=True, timeout=300 + TIMEOUT)
    assert r.returncode == 0, r.stderr
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


# ---------------------------------------------------------------------------------------------- the shared viewer
@pytest.fixture(scope="module")
def view(xdisplay, tmp_path_factory):
    v = View(xdisplay, tmp_path_factory.mktemp("controls"), "--seed", "3", resolution=(W, H))
    yield v
    if v.proc.poll() is None:
        v.proc.kill()
    v.finish()


def _blue_rows(img, x0, x1, y0, y1, min_pixels=8):
    """(first row, last row) of each run of rows in img[y0:y1, x0:x1] holding at least ``min_pixels`` blue
    pixels (Dear ImGui's frames, grabs, buttons and active title bars)."""
    rgb = img[y0:y1, x0:x1, :3].astype(int)
    blue = (rgb[..., 2] - rgb[..., 0] > 30) & (rgb[..., 2] > 60)
    rows = np.append(blue.sum(axis=1) >= min_pixels, False)
    runs, start = [], None
    for y, on in enumerate(rows):
        if on and start is None:
            start = y
        elif not on and start is not None:
            runs.append((y0 + start, y0 + y - 1))
            start = None
    return runs, blue


def layout(img) -> dict:
    """Where the widgets are, from a screenshot: "tune" (the panel's widgets in order: sliders, recompile buttons,
    camera buttons, overlay check boxes; each (row, x to click)) and "time" (the HUD's time slider: row, bar
    start and end)."""
    from taichi_rocks.app.view import VIEW_SWITCHES
    from taichi_rocks.motion.camera import VIEWS
    from taichi_rocks.render.panel import HUD_PX, OVERLAYS, SLIDERS, panel_width

    left = int(round(W * (1.0 - panel_width(W))))
    runs, _ = _blue_rows(img, left + 4, W - 4, 0, H)
    rows = [(a + b) // 2 for a, b in runs if a > 2 and b - a >= 12]  # not the title bar, not the border
    n = {"sliders": len(SLIDERS) + 1, "switches": len(VIEW_SWITCHES), "cameras": len(VIEWS) + 1,
         "overlays": len(OVERLAYS)}  # release_angle: two sliders; the cameras and "free"
    assert len(rows) == sum(n.values()), rows
    tune, k = {}, 0
    for group, count in n.items():
        tune[group] = [(y, left + 16) for y in rows[k:k + count]]  # 16 px in: inside every button and box
        k += count
    top = int(round(H * (1.0 - min(0.5, HUD_PX / float(H)))))
    runs, blue = _blue_rows(img, 4, left - 4, top, H)
    runs = [(a, b) for a, b in runs if a > top + 2 and b - a >= 12]
    assert runs, "no time slider in the HUD"
    a, b = runs[-1]
    cols = np.flatnonzero(blue[(a + b) // 2 - top])
    tune["time"] = ((a + b) // 2, 4 + int(cols[0]), 4 + int(cols[-1]))
    return tune


def click(view, x, y, done, what):
    """Move the mouse to (x, y) in the window, press and release the left button (a frame apart each: ImGui
    sees the hover first), wait until ``done(status)``; again if the viewer opened a new window meanwhile."""
    for _ in range(3):
        before = view.status()["window_refreshes"]
        view.xdo("mousemove", "--window", view.wid, str(x), str(y))
        view.frames_later(2)
        view.xdo("mousedown", "1")
        view.frames_later(2)
        view.xdo("mouseup", "1")
        s = view.wait(lambda s: done(s) or s["window_refreshes"] != before, what)
        view.xdo("mousemove", "--window", view.wid, "5", "5")  # off the panel (the sky)
        if done(s):
            return view.frames_later(2)
    raise AssertionError(f"the click never took effect: {what}")


@pytest.fixture(scope="module")
def widgets(view):
    """The layout, from a screenshot taken once the HUD shows its notice line (a screenshot sets one, "saved
    ...", and it stays: the time slider sits one line lower from then on)."""
    view.still(panel=True)
    view.screenshot()
    view.frames_later(2)
    return layout(view.screenshot())


def test_the_window_runs_the_seed_given(view):
    s = view.wait(lambda s: s["shown"] >= 2)
    assert s["seed"] == 3 and s["camera"] == "chase" and s["eye"] is not None
    geometry = view.xdo("getwindowgeometry", view.wid).stdout
    assert f"{W}x{H}" in geometry, geometry
    x, y = (int(v) for v in geometry.split("Position: ")[1].split()[0].split(","))
    screen = view.xdo("getdisplaygeometry").stdout.split()
    assert x + W <= int(screen[0]) and y + H <= int(screen[1]), (geometry, screen)  # every pixel in reach


def test_up_and_down_double_and_halve_the_speed_within_a_quarter_and_four(view):
    view.still(panel=True)
    assert view.status()["speed"] == 1.0
    for key, want in (("Up", 2.0), ("Up", 4.0), ("Up", 4.0), ("Down", 2.0), ("Down", 1.0), ("Down", 0.5),
                      ("Down", 0.25), ("Down", 0.25), ("Up", 0.5), ("Up", 1.0)):
        before = view.status()["speed"]
        view.key(key)
        if want == before:  # at a limit: nothing changes
            s = view.frames_later(3)
        else:
            s = view.wait(lambda s: s["speed"] != before, f"the speed after {key}")
        assert s["speed"] == want and s["paused"], (key, s["speed"])


def _moved(view, key, frames=8):
    """Hold ``key`` for ``frames`` frames; (eye displacement, forward, right) in world metres. Again if the
    viewer opened a new window meanwhile (a key held across two windows is lost)."""
    for _ in range(3):
        s0 = view.status()
        view.xdo("keydown", "--window", view.wid, key)
        view.frames_later(frames)
        view.xdo("keyup", "--window", view.wid, key)
        s1 = view.frames_later(3)
        if s1["window_refreshes"] == s0["window_refreshes"]:
            return np.subtract(s1["eye"], s0["eye"]), np.array(s0["forward"]), np.array(s0["right"])
    raise AssertionError(f"the viewer kept opening new windows while {key} was held")


def test_f_starts_the_free_camera_and_w_a_s_d_e_q_move_it(view):
    """Paused, so that only the camera moves. The free camera starts where the preset's eye is; W/S move it
    along the view, D/A to the right and left, E/Q up and down (world +Z, the simulation's up); f again
    goes back to the preset, where it was."""
    s = view.still(panel=False)
    preset_eye = np.array(view.frames_later(2)["eye"])
    view.key("f")
    s = view.wait(lambda s: s["camera"] == "free", "the free camera")
    np.testing.assert_allclose(s["eye"], preset_eye, atol=1e-3)
    up = np.array([0.0, 0.0, 1.0])
    for key, sign, axis in (("w", 1, "forward"), ("s", -1, "forward"), ("d", 1, "right"), ("a", -1, "right"),
                            ("e", 1, "up"), ("q", -1, "up")):
        d, fwd, right = _moved(view, key)
        direction = {"forward": fwd, "right": right, "up": up}[axis] * sign
        along = float(d @ direction)
        assert along > 0.3, (key, d, direction)  # ~7 m/s held for 8+ frames
        assert np.linalg.norm(d - along * direction) < 0.35 * along, (key, d, direction)  # and only that way
    assert view.status()["camera"] == "free" and view.status()["paused"]
    view.key("f")
    s = view.wait(lambda s: s["camera"] == "chase", "back to the chase camera")
    np.testing.assert_allclose(view.frames_later(2)["eye"], preset_eye, atol=1e-3)


def test_camera_buttons_pick_the_preset(view, widgets):
    from taichi_rocks.motion.camera import VIEWS

    view.still(panel=True)
    start = np.array(view.status()["eye"])
    names = VIEWS + ("free",)
    eyes = {}
    for name in [n for n in names if n != "chase"] + ["chase"]:
        y, x = widgets["cameras"][names.index(name)]
        s = click(view, x, y, lambda s, name=name: s["camera"] == name, f"the {name} camera")
        eyes[name] = np.array(s["eye"])
    for name in ("side", "low", "orbit", "driver", "bonnet"):  # each its own place (orbit: the side view turned
        assert np.linalg.norm(eyes[name] - start) > 1.0, name  # by the time)
    assert np.linalg.norm(eyes["side"] - eyes["low"]) > 1.0 and np.linalg.norm(eyes["driver"] - eyes["bonnet"]) > 1.0
    np.testing.assert_allclose(eyes["free"], eyes[VIEWS[-1]], atol=1e-3)  # free starts where the camera was
    np.testing.assert_allclose(eyes["chase"], start, atol=1e-3)  # back behind the car (it drives straight)


def _picture(view):
    """The 3D picture of a screenshot (left of the panel, above the HUD), as int16."""
    from taichi_rocks.render.panel import HUD_PX, panel_width

    y_hud = int(round(H * (1.0 - min(0.5, HUD_PX / float(H)))))
    x_panel = int(round(W * (1.0 - panel_width(W))))
    return view.screenshot()[:y_hud - 4, :x_panel - 4, :3].astype(np.int16)


def test_overlay_check_boxes_switch_the_overlays_on_and_off(view, widgets):
    """Each check box turns its overlay on (its lines appear in its colour; the vehicles turn to wireframes for
    the three under them) and off again (the picture of before). The hash cells overlay draws the cells the
    tire rays visited, and with detection = "patch" (this scene) no rays trace cells: only the wireframe shows."""
    from taichi_rocks.render import looks
    from taichi_rocks.render.panel import OVERLAYS

    colour = {"bed_edge": looks.BED_EDGE_COLOR, "tire_rays": looks.RAY_COLOR, "hash_cells": looks.CELL_COLOR,
              "tread_patch": looks.PATCH_COLOR}
    view.still(panel=True)
    off = {flag: False for flag, _ in OVERLAYS}
    assert view.status()["overlays"] == off and set(colour) == set(off)
    before = _picture(view)

    def coloured(img, flag):
        return np.abs(img - 255.0 * np.array(colour[flag])).max(axis=2) < 40

    for k, (flag, label) in enumerate(OVERLAYS):
        y, x = widgets["overlays"][k]
        s = click(view, x, y, lambda s, flag=flag: s["overlays"][flag], f"the {label} overlay on")
        assert s["overlays"] == {**off, flag: True}, s["overlays"]
        on = _picture(view)
        lines = (coloured(on, flag) & ~coloured(before, flag)).sum()
        changed = (np.abs(on - before).max(axis=2) > 40).sum()
        if flag == "hash_cells":
            assert changed > 1000, changed  # the vehicle as a wireframe
        else:
            assert lines >= 4, (flag, lines)  # its own lines (paused: nothing else moved)
        if flag != "bed_edge":
            assert changed > 1000, (flag, changed)
        click(view, x, y, lambda s, flag=flag: not s["overlays"][flag], f"the {label} overlay off")
    assert view.status()["overlays"] == off
    assert np.abs(_picture(view) - before).max() <= 2  # all off: the picture of before


def test_time_slider_jumps_to_the_frame_clicked(view, widgets):
    view.still(panel=True)
    y, x0, x1 = widgets["time"]
    assert x1 - x0 > 100, widgets["time"]
    frames = view.status()["frames"]
    for share in (0.75, 0.25):
        before = view.status()["frame"]
        x = int(round(x0 + share * (x1 - x0)))
        s = click(view, x, y, lambda s: s["frame"] != before, f"the time slider at {share:.0%}")
        assert abs(s["frame"] - share * (frames - 1)) <= 0.08 * frames, (share, s["frame"])
        assert s["paused"] and s["time"] == pytest.approx(s["frame"] / 30.0)
        later = view.frames_later(5)
        assert later["frame"] == s["frame"]  # paused: it stays there


def test_recompile_buttons_step_each_switch_and_keep_the_state(view, widgets):
    """Each button sets its switch to the next choice; the simulation is rebuilt (one rebuild each, every
    one into a World of the same layout from the pool) and continues from the same state: the same frame and launches."""
    from taichi_rocks.app.view import VIEW_SWITCHES

    s = view.still(panel=True)
    keys = list(VIEW_SWITCHES)  # the panel's buttons, in order
    assert keys == list(s["switches"])
    for k, key in enumerate(keys):
        s = view.status()
        choices = VIEW_SWITCHES[key]
        want = choices[(choices.index(s["switches"][key]) + 1) % len(choices)]
        rebuilds, frame, launches = s["rebuilds"], s["frame"], s["launches"]
        y, x = widgets["switches"][k]
        s = click(view, x, y, lambda s: s["rebuilds"] > rebuilds and not s["recompiling"], f"the {key} button")
        assert s["rebuilds"] == rebuilds + 1 and s["switches"][key] == want, (key, s["switches"])
        assert (s["frame"], s["launches"], s["paused"]) == (frame, launches, True), key
        assert s["notice"] == ""
    assert {key: view.status()["switches"][key] for key in keys} == {
        "sim.integrator": "heun", "effects.drag": "none", "effects.ground": "none", "effects.gravity": False,
        "effects.fenders": False, "effects.impacts": True}
    view.toggle_until("space", lambda s: not s["paused"], "playing")  # the rebuilt simulation runs
    f0 = view.status()["frame"]
    view.wait(lambda s: s["frame"] != f0, "time to move in the rebuilt simulation")
