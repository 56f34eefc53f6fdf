"""``taichi-rocks view``: the simulation in a window, drawn by the same Renderer as ``render``.

Each frame shown: the keys, the clock (:mod:`.timeline`: play, step, scrub; the simulation only stands at
frame times, so frame k here is ``render``'s frame k), the camera (the rig's presets or render/freecam.py), the
Renderer declaring the background image and the 3D scene in the shown window (render/window.py
``ShownWindow``), the panel (render/panel.py), then ``window.show()``. Runtime parameters go to the engine through
engine/tuning.py ``set_runtime``; a switch is applied one frame after its "recompiling" notice was shown, by
a new Simulation restored from a checkpoint (``rebuilder``).

Keys (GGUI 1.7.4 reports letters, arrows, space, Tab and Escape, not digits or punctuation): space play/pause,
Right/Left one frame forward/back, Up/Down speed x2 / x1/2 (x1/4 .. x4), c next camera (the scene's shots, if
it has [[camera.shot]] tables, then the presets; the shots play on the first), f free camera
(W/A/S/D/E/Q, right mouse button to look), h hide/show the panel, p screenshot, Escape quit.

Driving (``--drive NAME``, app/driving.py): W/S/A/D held drive the vehicle NAME (the free camera then only looks
round), the camera's chase view follows it and the HUD shows its speed; the timeline has no end; going back in
time shows what was driven and driving on from there replaces the rest; ``--record-drive FILE`` writes the poses
driven as a recorded drive when the window closes.

Automation: ``TAICHI_ROCKS_VIEW_STATUS=PATH`` writes a JSON status (:meth:`Viewer.status`) atomically after
every frame shown; "view: ready" goes to stderr once the first frame is on the screen.

Memory: GGUI 1.7.4 keeps ~0.1-0.3 MB of every 3D renderable it draws (measured here on lavapipe, CPU and
Vulkan arch alike, for particles, meshes and lines; ``malloc_trim`` and a new Scene object do not give it
back; destroying the window does). So once the process has grown by REFRESH_MB since its window opened, the
window is destroyed and opened again between two frames (a blink; the HUD says so, the panel keeps its
values, the simulation and the camera are not touched), and frames are shown at most MAX_FPS times a second (each one drawn costs memory until then).
RSS over a long session: docs/rendering.md, "Memory".
"""

import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import taichi as ti

from ..config.keys import choices
from ..config.scene import SceneError
from ..engine.probes import rocks_in_air
from ..engine.simulation import Simulation
from ..engine.tuning import RUNTIME_KEYS, SWITCH_KEYS, rebuilder, runtime_values, scene_value, set_runtime
from ..motion.camera import VIEWS
from ..output.atomic import check_place, new_folders, write_atomically
from ..output.video import frame_name, png_bytes
from ..render.freecam import FreeCamera
from ..render.panel import draw_panel
from ..render.renderer import SHOTS, Renderer
from ..render.window import ShownWindow, trim_heap
from .driving import DRIVE_KEYS, DriveSession, drive_scene
from .timeline import Timeline

__all__ = ["Viewer", "view_scene", "STATUS_ENV", "READY_LINE", "VIEW_SWITCHES", "KEYS", "DRIVE_KEYS",
           "check_record_dir", "check_drive_file", "drive_scene", "screenshot_path"]

STATUS_ENV = "TAICHI_ROCKS_VIEW_STATUS"
READY_LINE = "view: ready"
TRIM_EVERY = 100  # frames shown between giving freed heap memory back to the OS
REFRESH_MB = 300.0  # growth of the resident set since the window opened that makes it open anew
MAX_FPS = 30.0  # more would only feed GGUI's memory (the scene's fps is 30)
# the panel's recompile buttons: the engine's switches and whether stones hit the vehicles' bodies
VIEW_SWITCHES = {**SWITCH_KEYS, "effects.impacts": choices("effects.impacts")}
# the keys :meth:`Viewer._keys` answers: (GGUI's names of them, as the docs name them, what they do); docs/rendering.md
# is generated from it (tools/gen_docs.py) and tests/test_gen_docs.py checks that _keys answers exactly these
KEYS = (
    ((ti.ui.SPACE,), "space", "play / pause"),
    ((ti.ui.RIGHT, ti.ui.LEFT), "Right / Left", "one frame forward / back (pauses)"),
    ((ti.ui.UP, ti.ui.DOWN), "Up / Down", "speed x2 / x1/2, from x1/4 to x4"),
    (("c",), "c", "next camera: the scene's shots (\"shots\", first, if it has `[[camera.shot]]` tables; they play on "
                  "it), then the presets chase, side, low, orbit, driver, bonnet (the panel has a button for each)"),
    (("f",), "f", "free camera: W/A/S/D forward, left, back, right, E/Q up and down, the mouse with the right button "
                  "held to look round; f again goes back to the preset"),
    (("h",), "h", "hide / show the panel and HUD"),
    (("p",), "p", "screenshot of what the window shows: `<scene>_t<time>.png` in the current folder (e.g. "
                  "`convoy_t003.25.png`; never overwritten: `_2`, `_3` ...)"),
    ((ti.ui.ESCAPE,), "Escape", "quit (exit status 0; closing the window does the same)"),
)


def check_record_dir(path, overwrite: bool) -> None:
    """FileExistsError if ``path`` holds files and ``overwrite`` is off; with it, old frames go."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise FileExistsError(f"{path}: exists and is not a folder")
    if path.is_dir() and any(path.iterdir()):
        if not overwrite:
            raise FileExistsError(f"{path} is not empty (pass --overwrite to replace its frames)")
        for old in path.glob("frame_*.png"):
            old.unlink()


def screenshot_path(folder, scene_name: str, t: float) -> Path:
    """``<scene>_t<time>.png`` in ``folder`` (e.g. convoy_t003.25.png), with _2, _3 ... if taken."""
    base = f"{scene_name}_t{t:06.2f}"
    path = Path(folder) / f"{base}.png"
    k = 2
    while path.exists():
        path = Path(folder) / f"{base}_{k}.png"
        k += 1
    return path


class Viewer:
    """A window on a live simulation of ``scene``. See the module docstring."""

    def __init__(self, scene, arch="cpu", resolution=None, record=None, status_path=None, drive=None):
        # the flying rocks are drawn turned; drawn from the device (engine/drawing.py), no changes() mirror
        self.sim = Simulation(scene, arch=arch, tumble=True, track_changes=False)
        res = tuple(resolution) if resolution is not None else tuple(int(x) for x in scene.render.resolution)
        self.win = ShownWindow(res, title=f"taichi-rocks view: {scene.name}")
        self.renderer = Renderer(self.sim, resolution=res, target=self.win)
        self.resolution = self.renderer.resolution
        fps = self.renderer.fps
        self.timeline = Timeline(fps, max(1, int(round(scene.duration * fps))))
        self.renderer.view()
        self.timeline.save(self.sim, self.renderer.rig)
        self.free = FreeCamera()
        self.free_on = False
        self.shown_view = None  # the camera of the last frame shown (render/camera.py View, local)
        self.camera_name = self.renderer.view_name
        self.cameras = ((SHOTS,) if scene.camera.shots else ()) + VIEWS  # what c and the panel's buttons pick
        self.runtime = {k: scene_value(scene, k) for k in RUNTIME_KEYS}
        self.switches = {k: scene_value(scene, k) for k in VIEW_SWITCHES}
        self.switch_choices = VIEW_SWITCHES
        self.notice, self.pending, self._notice_shown = "", None, False
        self.panel_on, self.quit, self._shot = True, False, False
        self.fps, self.shown, self.in_air, self.rebuilds = 0.0, 0, 0, 0
        self.screenshots, self.record, self.recorded = [], None if record is None else Path(record), 0
        self.status_path = Path(status_path) if status_path else None
        self._times = []
        self.refreshes, self._rss_base = 0, None  # measured once the kernels are compiled (frame TRIM_EVERY)
        self.driving = None  # with --drive: the drive (app/driving.py); the scene is drive_scene's
        if drive is not None:
            self.driving = DriveSession(self.sim, drive, fps)
            self.timeline.before_advance = lambda frame: self.driving.before_frame(self.sim, frame)
            self.timeline.endless = True

    # -------------------------------------------------------------------------------------------- loop
    def run(self, quit_after=None) -> dict:
        """Show frames until Escape, the window closing or ``quit_after`` seconds after the first frame."""
        last = time.perf_counter()
        start = None
        try:
            while self.win.running and not self.quit:
                now = time.perf_counter()
                wall_dt, last = now - last, now
                self._keys()
                if self.quit:
                    break
                if self.pending is not None and self._notice_shown:
                    self._rebuild()
                    last = time.perf_counter()  # the recompile is not playing time
                self._frame(wall_dt)
                if start is None:
                    start = time.perf_counter()
                    print(READY_LINE, file=sys.stderr, flush=True)
                if quit_after is not None and time.perf_counter() - start >= quit_after:
                    break
        finally:
            self.renderer.close()
        return {"frames_shown": self.shown, "frame": self.timeline.frame, "screenshots": list(map(str, self.screenshots)),
                "recorded": self.recorded, "seconds": 0.0 if start is None else time.perf_counter() - start,
                "driven": None if self.driving is None else len(self.driving.rows)}

    def _frame(self, wall_dt: float) -> None:
        tl, r = self.timeline, self.renderer
        if self.driving is not None:
            self.driving.keys(self.win.window.is_pressed)
        tl.tick(wall_dt, self.sim, r.rig, r.view)
        view = None
        if self.free_on:
            view = self.free.update(self.win.window, self.sim.origin, r.view().heading, move=self.driving is None)
        r.render_frame(view)
        self.shown_view = view if view is not None else r.view()  # the same time: the rig does not move again
        self.in_air = rocks_in_air(self.sim)
        changes = draw_panel(self.win.window.get_gui(), self) if self.panel_on else None
        if self._shot or self.record is not None:
            self._capture()
        self.win.window.show()
        self._notice_shown = bool(self.notice)
        self.shown += 1
        self._count_fps()
        if changes is not None:
            self._apply(changes)
        if self.shown % TRIM_EVERY == 0:
            trim_heap()
            if self._rss_base is None:
                self._rss_base = _rss_mb()
            elif _rss_mb() - self._rss_base > REFRESH_MB:
                self._refresh_window()
        pause = 1.0 / MAX_FPS - (time.perf_counter() - self._times[-1])
        if pause > 0:
            time.sleep(pause)
        if self.status_path is not None:
            data = json.dumps(self.status()).encode()
            write_atomically(self.status_path, lambda f: f.write(data))

    def _count_fps(self) -> None:
        now = time.perf_counter()
        self._times = [t for t in self._times if now - t < 2.0] + [now]
        span = now - self._times[0]
        self.fps = (len(self._times) - 1) / span if span > 0 else 0.0

    def _refresh_window(self) -> None:
        """Open the window anew: GGUI frees what it kept of the frames drawn (see the module docstring)."""
        self.win.close()
        trim_heap()
        self.win.open()
        self.refreshes += 1
        self._rss_base = None
        if self.free_on:  # the free camera's mouse state belonged to the old window
            self.free.forget_mouse()

    # -------------------------------------------------------------------------------------------- input
    def _keys(self) -> None:
        tl = self.timeline
        for e in self.win.window.get_events(ti.ui.PRESS):
            k = e.key
            if k == ti.ui.ESCAPE:
                self.quit = True
            elif k == ti.ui.SPACE:
                tl.playing = not tl.playing
            elif k in (ti.ui.RIGHT, ti.ui.LEFT):
                tl.playing = False
                self._step_frame(1 if k == ti.ui.RIGHT else -1)
            elif k in (ti.ui.UP, ti.ui.DOWN):
                tl.faster(k == ti.ui.UP)
            elif k == "c":
                i = self.cameras.index(self.camera_name) + 1 if self.camera_name in self.cameras else 0
                self.set_camera(self.cameras[i % len(self.cameras)])
            elif k == "f":
                self.set_camera(self.renderer.view_name if self.free_on else "free")
            elif k == "h":
                self.panel_on = not self.panel_on
            elif k == "p":
                self._shot = True

    def _step_frame(self, step: int) -> None:
        """One frame forward or back: round the loop, or with a drive, on past the end and not before 0."""
        tl = self.timeline
        if not tl.endless:
            self._seek((tl.frame + step) % tl.frames)
            return
        if tl.frame + step >= tl.frames:
            tl.frames = tl.frame + step + 1
        self._seek(max(tl.frame + step, 0))

    def _seek(self, frame: int) -> None:
        r = self.renderer
        self.timeline.seek(frame, self.sim, r.rig, r.view)
        if self.driving is not None and self.driving.rewind(self.timeline.frame):  # drive on from here
            self.timeline.forget_after(self.timeline.frame)

    def set_camera(self, name: str) -> None:
        """A preset of motion/camera.py VIEWS, the scene's own camera with its shots (``SHOTS``), or "free"
        (starting where the camera is now)."""
        if name == "free":
            if not self.free_on:
                self.free.start(self.renderer.view(), self.sim.origin)
            self.free_on = True
        else:
            self.free_on = False
            self.renderer.set_view(name)
            self.renderer.view()
        self.camera_name = name

    def _apply(self, ch) -> None:
        if ch.seek is not None:
            self._seek(ch.seek)
        if ch.runtime:
            try:
                scene = set_runtime(self.sim, ch.runtime)
            except (SceneError, ValueError) as e:
                self.notice = str(e).splitlines()[0][-80:]
            else:
                self.runtime = {k: scene_value(scene, k) for k in RUNTIME_KEYS}
                self._forget_future()
        if ch.switch is not None and self.pending is None:
            self.pending = ch.switch
            key, value = ch.switch
            self.notice = f"recompiling: {key} = {value} ..."
            self._notice_shown = False
        if ch.view is not None:
            self.set_camera(ch.view)
        for flag, on in ch.overlays.items():
            setattr(self.renderer.flags, flag, bool(on))

    def _rebuild(self) -> None:
        """Apply the pending switch: a new Simulation of the changed scene, continuing from this state."""
        key, value = self.pending
        try:
            make = rebuilder(self.sim, {key: value})
        except (SceneError, ValueError) as e:
            self.pending, self.notice, self._notice_shown = None, str(e).splitlines()[0][-80:], False
            return
        keep = rebuilder(self.sim, {})
        self.sim = self.renderer.sim = None  # the old World goes before the new one is built
        try:
            self.sim = self.renderer.sim = make()
        except (SceneError, ValueError) as e:  # refused by the engine (a body stones would hit, ...): as before
            self.sim = self.renderer.sim = keep()
            self.pending, self.notice, self._notice_shown = None, str(e).splitlines()[0][-80:], False
            return
        self.switches[key] = value
        self._forget_future()
        self.rebuilds += 1
        self.pending, self.notice, self._notice_shown = None, "", False

    def _forget_future(self) -> None:
        """The settings changed: the saved states and the hits after this frame are no longer this run's."""
        self.timeline.forget_after(self.timeline.frame)
        self.renderer.hits.hits.clear_after(self.timeline.time)

    # -------------------------------------------------------------------------------------------- output
    def _capture(self) -> None:
        """What the window shows (panel included) as PNG: the screenshot asked for, the recorded frame."""
        raw = self.win.window.get_image_buffer_as_numpy()  # (W, H, 4) float32, y up; this frame's pixels
        img = (np.clip(np.rot90(raw[:, :, :3]), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        data = png_bytes(img)
        if self._shot:
            path = screenshot_path(Path.cwd(), self.sim.scene.name, self.timeline.time)
            write_atomically(path, lambda f: f.write(data))
            self.screenshots.append(path)
            self.notice = f"saved {path.name}" if not self.pending else self.notice
            self._shot = False
        if self.record is not None:
            write_atomically(self.record / frame_name(self.recorded), lambda f: f.write(data))
            self.recorded += 1

    def status(self) -> dict:
        """What the window shows now, for programs that drive it (the tests): the clock, the scene's seed, the
        camera (its name; the eye in world metres, the forward and right unit vectors of the frame shown), the
        panel's values, notices, outputs."""
        tl, v = self.timeline, self.shown_view
        eye, fwd, right = (None,) * 3 if v is None else (
            (np.asarray(v.eye, np.float64) + self.sim.origin).tolist(), np.asarray(v.fwd).tolist(),
            np.asarray(v.right).tolist())
        return {"frame": tl.frame, "frames": tl.frames, "time": tl.time, "paused": not tl.playing, "speed": tl.speed,
                "seed": self.sim.scene.seed, "launches": self.sim.launches_total, "in_air": self.in_air,
                "camera": self.camera_name, "eye": eye, "forward": fwd, "right": right, "fps": self.fps,
                "shown": self.shown, "panel": self.panel_on, "params": runtime_values(self.sim),
                "switches": self.switches, "overlays": vars(self.renderer.flags).copy(), "notice": self.notice,
                "recompiling": self.pending is not None, "rebuilds": self.rebuilds, "replayed": tl.replayed,
                "hits": self.renderer.hits.counts(),
                "window_refreshes": self.refreshes,
                "screenshots": [str(p) for p in self.screenshots], "recorded": self.recorded,
                "rss_mb": _rss_mb(), "bed_center": self.sim.bed_center.tolist(), "drive": self._drive_status()}

    def _drive_status(self):
        """With --drive: the vehicle driven, its pose (world m, rad), speed (m/s) and the poses kept."""
        d = self.driving
        if d is None:
            return None
        i = self.sim.fleet.names.index(d.name)
        p = self.sim.vehicle_poses()[i]
        return {"vehicle": d.name, "position": p.position.tolist(), "heading": p.heading, "speed": p.speed,
                "pedal": d.pedal, "steering": d.steering, "rows": len(d.rows)}


def _rss_mb() -> float:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6
    except (OSError, ValueError, IndexError):
        return 0.0


def check_drive_file(path, overwrite: bool) -> None:
    """FileExistsError if the --record-drive ``path`` exists and ``overwrite`` is off; ValueError if it cannot
    be written there (output/atomic.py check_place)."""
    path = Path(path)
    if path.is_dir():
        raise FileExistsError(f"{path}: is a folder (--record-drive takes a file name)")
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists (pass --overwrite to replace it)")
    check_place(path)


def view_scene(scene, arch="cpu", resolution=None, record=None, overwrite=False, quit_after=None,
               status_path=None, drive=None, record_drive=None) -> dict:
    """Open the window on ``scene`` (a validated Scene) and run it until closed; see :class:`Viewer`.
    ``record``: a folder to write every frame shown into (FileExistsError if it holds files, unless
    ``overwrite``). ``drive``: the vehicle the keys drive (the scene is made ready with app/driving.py
    ``drive_scene``); ``record_drive``: the file its drive is written to when the window closes. Returns the
    summary of :meth:`Viewer.run` ("driven": the poses of the drive, written to ``record_drive``)."""
    if record is not None:
        check_record_dir(record, overwrite)
    if record_drive is not None:
        if drive is None:
            raise ValueError("--record-drive needs --drive NAME (the vehicle whose drive is recorded)")
        check_drive_file(record_drive, overwrite)
    if drive is not None:
        scene = drive_scene(scene, drive)
    status_path = status_path if status_path is not None else os.environ.get(STATUS_ENV)
    folders = tuple(f for f in (record, None if record_drive is None else Path(record_drive).parent)
                    if f is not None)
    with new_folders(*folders):
        viewer = Viewer(scene, arch=arch, resolution=resolution, record=record, status_path=status_path, drive=drive)
        try:
            return viewer.run(quit_after=quit_after)
        finally:
            if record_drive is not None:  # what was driven, also when the window failed on the way
                viewer.driving.write(record_drive, scene.name)
