"""Driving ``taichi-rocks view`` in a real window under a virtual X display (Xvfb) with xdotool, for
tests/render/test_view.py and tests/render/test_view_controls.py: the display (a module fixture), a running viewer
(:class:`View`: its status file, its window, keys). Every wait is on what the viewer reports: its status file
(TAICHI_ROCKS_VIEW_STATUS, written after every frame shown). Xvfb, xdotool and xdpyinfo are required
(tools/setup.sh installs them): without them these tests fail.
"""

import json
import os
import select
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
TIMEOUT = 120.0  # s: the machine may be slow and loaded


@pytest.fixture(scope="module")
def xdisplay():
    """A virtual display of 1280x1024 (windows open at (100, 100) without a window manager: a 680-pixel-tall one
    must fit below that, or its bottom rows are out of the pointer's reach)."""
    missing = [t for t in ("Xvfb", "xdotool", "xdpyinfo") if shutil.which(t) is None]
    if missing:
        pytest.fail(f"{', '.join(missing)} not installed: run tools/setup.sh (apt-get install xvfb xdotool "
                    f"x11-utils)")
    # Xvfb picks a free display itself and reports it on a pipe once it listens (-displayfd): two test processes
    # choosing "the first free number" at the same moment could both get one server, and its one pointer
    proc, display = _start_xvfb()
    try:
        deadline = time.time() + 60
        while proc.poll() is None and time.time() < deadline:
            if subprocess.run(["xdpyinfo", "-display", display], capture_output=True).returncode == 0:
                yield display
                return
            time.sleep(0.1)
        pytest.fail(f"Xvfb {display} never answered")
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def _start_xvfb():
    read_end, write_end = os.pipe()
    proc = subprocess.Popen(["Xvfb", "-displayfd", str(write_end), "-screen", "0", "1280x1024x24", "-nolisten",
                             "tcp"], pass_fds=(write_end,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    number = b""
    try:
        deadline = time.time() + 60
        while not number.endswith(b"\n") and time.time() < deadline:
            if select.select([read_end], [], [], 1.0)[0]:
                chunk = os.read(read_end, 16)
                if not chunk:  # Xvfb ended
                    break
                number += chunk
    finally:
        os.close(read_end)
    if not number.strip().isdigit():
        proc.kill()
        proc.wait(timeout=30)
        pytest.fail(f"could not start Xvfb (status {proc.returncode})")
    return proc, f":{int(number)}"


def _env(display, **extra):
    env = dict(os.environ, PYTHONPATH=str(ROOT), **extra)
    if display is None:
        env.pop("DISPLAY", None)
    else:
        env["DISPLAY"] = display
    return env


class View:
    """A running viewer of ``scene`` (default scenes/minimal.toml; its window is titled with the file's stem, the
    scene's name): its status, its window (xdotool), its outputs in ``cwd``. ``ready=False``: return as soon as
    the process is started (the caller does other work while it starts up, then calls :meth:`ready`)."""

    def __init__(self, display, cwd: Path, *args, resolution=(480, 320), scene=None, ready=True):
        self.display, self.cwd = display, cwd
        self.scene = Path(scene) if scene is not None else ROOT / "scenes" / "minimal.toml"
        self.status_file = cwd / "status.json"
        self.out, self.err = open(cwd / "stdout.txt", "w+"), open(cwd / "stderr.txt", "w+")  # never a full pipe
        w, h = resolution
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "taichi_rocks", "view", str(self.scene), "--resolution",
             f"{w}x{h}", *map(str, args)], cwd=cwd, env=_env(display, TAICHI_ROCKS_VIEW_STATUS=str(self.status_file)),
            stdout=self.out, stderr=self.err, text=True)
        if ready:
            self.ready()

    def ready(self):
        """Wait for the first frame shown and the window."""
        self.wait(lambda s: s["shown"] >= 1, "the first frame")
        self._window()

    def stderr(self) -> str:
        return (self.cwd / "stderr.txt").read_text()

    def finish(self) -> int:
        code = self.proc.wait(timeout=TIMEOUT)
        self.out.close()
        self.err.close()
        return code

    def status(self):
        try:
            return json.loads(self.status_file.read_text())
        except (OSError, ValueError):
            return None

    def wait(self, cond, what="the viewer's status"):
        deadline = time.time() + TIMEOUT
        while True:
            s = self.status()
            if s is not None and cond(s):
                return s
            if self.proc.poll() is not None:
                raise AssertionError(f"viewer ended (status {self.proc.returncode}) waiting for {what}:\n"
                                     f"{self.stderr()}")
            if time.time() > deadline:
                raise AssertionError(f"timed out waiting for {what}; last status: {s}")
            time.sleep(0.05)

    def frames_later(self, n=3):
        """Wait until ``n`` more frames were shown."""
        shown = self.status()["shown"]
        return self.wait(lambda s: s["shown"] >= shown + n, f"{n} more frames")

    @property
    def wid(self) -> str:
        """The viewer's window now (it opens a new one now and then to free GGUI's memory: app/view.py)."""
        return self._window()

    def _window(self) -> str:
        deadline = time.time() + TIMEOUT
        while time.time() < deadline:
            r = self.xdo("search", "--pid", str(self.proc.pid), "--name", f"taichi-rocks view: {self.scene.stem}",
                         check=False)
            if r.returncode == 0 and r.stdout.split():
                return r.stdout.split()[0]
            time.sleep(0.1)
        raise AssertionError("no viewer window found")

    def xdo(self, *args, check=True):
        r = subprocess.run(["xdotool", *args], env=_env(self.display), capture_output=True, text=True, timeout=60)
        if check:
            assert r.returncode == 0, r.stderr
        return r

    def key(self, name):
        for _ in range(3):  # the window may be replaced between the search and the key
            if self.xdo("key", "--window", self.wid, name, check=False).returncode == 0:
                return
        raise AssertionError(f"could not press {name}")

    def press(self, key, done, what):
        """Press ``key`` and wait until ``done(status)``. A key sent while the viewer replaces its window (it
        opens a new one now and then: app/view.py) is lost: if the window was replaced and the press showed no
        effect a few frames into the new one, it is pressed again (only then: a second press of a toggle that
        did land would undo it)."""
        for _ in range(3):
            before = self.status()["window_refreshes"]
            self.key(key)
            s = self.wait(lambda s: done(s) or s["window_refreshes"] != before, what)
            if not done(s):
                s = self.frames_later(3)
            if done(s):
                return s
        raise AssertionError(f"{key} had no effect while the viewer kept opening new windows: {what}")

    def toggle_until(self, key, cond, what):
        """Press ``key`` unless ``cond(status)`` holds already; wait for it."""
        if cond(self.status()):
            return self.status()
        return self.press(key, cond, what)

    def step_to(self, k, forward=False):
        """Step one frame at a time until frame ``k`` is shown: Left while past it, else Right (``forward``:
        Right only, round the loop past the last frame)."""
        while self.status()["frame"] != k:
            f = self.status()["frame"]
            self.press("Left" if f > k and not forward else "Right", lambda x: x["frame"] != f, "a frame step")

    def still(self, panel=False):
        """Paused, panel shown or not."""
        self.toggle_until("space", lambda s: s["paused"], "paused")
        return self.toggle_until("h", lambda s: s["panel"] == panel, f"panel {panel}")

    def screenshot(self) -> np.ndarray:
        import imageio.v3 as iio

        n = len(self.status()["screenshots"])
        s = self.press("p", lambda s: len(s["screenshots"]) > n, "a screenshot")
        return iio.imread(s["screenshots"][-1])
