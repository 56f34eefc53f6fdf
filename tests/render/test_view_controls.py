"""``taichi-rocks view``'s controls in a real window (Xvfb, xdotool; view_util.py): the window (its size, the
scene's frames, the seed given), space (pause), Right/Left (a frame step; scrubbing back shows the frame
``render`` draws), c (the next camera), h (the panel), p (a screenshot named after the scene and the time),
Up/Down (the speed), ``f`` and the free camera (W/A/S/D/E/Q); with the mouse, the panel's wetness slider, camera
buttons, overlay check boxes, the time slider and the recompile buttons.

One viewer process of scenes/minimal.toml (480x720: the whole "tune" panel fits) serves every test here, in this
order (the recompile buttons last: they change the simulation); each first puts it in the state it needs: paused
or playing, panel shown or hidden. The frame ``render`` draws, for the scrubbing test, is rendered in this
process while the viewer starts. Widgets are found in a screenshot, not at fixed pixels: Dear ImGui draws every
slider, button and check box on a blue frame, so the rows of blue in the panel's column are its widgets, in
render/panel.py's order. Every wait is on the viewer's status file (TAICHI_ROCKS_VIEW_STATUS, written after
every frame shown). How the viewer ends (Escape, --quit-after, --record) and its refusals: test_view.py.
"""

import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from cli_util import cli_here
from view_util import ROOT, View, xdisplay  # noqa: F401  (xdisplay: the display fixture)

W, H = 480, 720
SEED = 3
K = 10  # the frame scrubbed back to and compared with render's


def _render_frame_k(out: Path):
    """``render``'s frame K of the viewer's scene, seed and size: (the command's result, the image or None)."""
    import imageio.v3 as iio

    try:
        r = cli_here(None, "render", ROOT / "scenes" / "minimal.toml", "--seed", SEED, "--frames", K + 1,
                     "--resolution", f"{W}x{H}", "--format", "png", "--out", out)
    except Exception as e:  # the scrubbing test's failure, not an error of every test sharing the viewer
        return SimpleNamespace(returncode=None, stderr=repr(e)), None
    path = out / "frames" / f"frame_{K:05d}.png"
    return r, iio.imread(path).astype(np.int16) if r.returncode == 0 and path.exists() else None


@pytest.fixture(scope="module")
def view(xdisplay, tmp_path_factory, taichi_cpu):
    v = View(xdisplay, tmp_path_factory.mktemp("controls"), "--seed", SEED, resolution=(W, H), ready=False)
    try:
        # drawn here while the viewer process starts up, not while its window runs idle waiting for it
        v.offline = _render_frame_k(tmp_path_factory.mktemp("render"))
        v.ready()
        yield v
    finally:
        if v.proc.poll() is None:
            v.proc.kill()
        v.finish()


def test_window_opens_with_the_seed_given_in_reach_of_the_pointer(view):
    s = view.wait(lambda s: s["shown"] >= 3)
    assert s["seed"] == SEED and s["camera"] == "chase" and s["eye"] is not None
    assert s["panel"] is True and s["frames"] == 60  # 2 s at 30 fps
    assert "view: ready" in view.stderr().splitlines()
    geometry = view.xdo("getwindowgeometry", view.wid).stdout
    assert f"{W}x{H}" in geometry, geometry
    x, y = (int(v) for v in geometry.split("Position: ")[1].split()[0].split(","))
    screen = view.xdo("getdisplaygeometry").stdout.split()
    assert x + W <= int(screen[0]) and y + H <= int(screen[1]), (geometry, screen)  # every pixel in reach


def test_pause_stops_time(view):
    view.toggle_until("space", lambda s: not s["paused"], "playing")
    f0 = view.status()["frame"]
    view.wait(lambda s: s["frame"] != f0, "time to move while playing")
    s = view.toggle_until("space", lambda s: s["paused"], "paused")
    later = view.frames_later(10)
    assert later["frame"] == s["frame"] and later["time"] == s["time"]
    stepped = view.press("Right", lambda x: x["frame"] != s["frame"], "one frame step")  # one step while paused
    assert stepped["frame"] == (s["frame"] + 1) % s["frames"] and stepped["paused"]


def test_key_moves_camera(view):
    view.still(panel=False)
    assert view.status()["camera"] == "chase"  # the scene's view (each test that changes it goes back)
    view.frames_later()
    before = view.screenshot().astype(np.int16)
    s = view.press("c", lambda s: s["camera"] == "side", "the side camera")
    assert s["frame"] == view.status()["frame"]  # paused: only the camera moved
    view.frames_later()
    after = view.screenshot().astype(np.int16)
    diff = np.abs(after - before).max(axis=2)
    assert (diff > 30).mean() > 0.2, (diff > 30).mean()
    view.press("c", lambda s: s["camera"] == "low", "the low camera")
    while view.status()["camera"] != "chase":  # back to the scene's own view for the other tests
        cam = view.status()["camera"]
        view.press("c", lambda s: s["camera"] != cam, "the next camera")


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


def test_scrubbing_back_shows_the_frame_render_draws(view):
    render, offline = view.offline
    assert render.returncode == 0 and offline is not None, render.stderr
    s = view.still(panel=False)
    assert s["params"]["world.wetness"] == 0.0  # the scene's parameters, as render has them
    replayed = s["replayed"]
    # Each step back restores the newest saved state (frames 0, 30) and simulates forward from it, a step forward
    # simulates one frame: from further on than K + 3, forward round the loop to K + 1 first, then one step back.
    if not K < s["frame"] <= K + 3:
        view.step_to(K + 1, forward=True)
    view.step_to(K)
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


def _moved(view, key, frames=4):
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
    s = view.press("f", lambda s: s["camera"] == "free", "the free camera")
    np.testing.assert_allclose(s["eye"], preset_eye, atol=1e-3)
    up = np.array([0.0, 0.0, 1.0])
    for key, sign, axis in (("w", 1, "forward"), ("s", -1, "forward"), ("d", 1, "right"), ("a", -1, "right"),
                            ("e", 1, "up"), ("q", -1, "up")):
        d, fwd, right = _moved(view, key)
        direction = {"forward": fwd, "right": right, "up": up}[axis] * sign
        along = float(d @ direction)
        assert along > 0.3, (key, d, direction)  # ~7 m/s held for 4+ frames: >= 0.7 m at 30 frames/s
        assert np.linalg.norm(d - along * direction) < 0.35 * along, (key, d, direction)  # and only that way
    assert view.status()["camera"] == "free" and view.status()["paused"]
    s = view.press("f", lambda s: s["camera"] == "chase", "back to the chase camera")
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
