"""Driving in the viewer (``taichi-rocks view SCENE --drive NAME [--record-drive FILE]``): the scene made ready
for it (:func:`drive_scene`), and the drive itself (:class:`DriveSession`): before each frame the simulation
advances to, the keys held move the keyboard's vehicle (motion/driver.py) and ``Simulation.drive`` takes its
pose; every pose given is kept, one row a frame, and written as a recorded drive (config/drivefile.py,
docs/drives.md) when the window closes.

Scrubbing: a frame already driven is driven again from the rows kept (the timeline replays frames from a saved
state: app/timeline.py), so going back shows what was driven; once the user has gone back, driving on from there
replaces the rows after that frame.
"""

from __future__ import annotations

import math
from pathlib import Path

from ..config.drivefile import drive_text
from ..config.scene import scene_with
from ..motion.driver import Driver
from ..motion.live import LivePath
from ..motion.paths import path_from_spec
from ..output.atomic import write_atomically

__all__ = ["DRIVE_KEYS", "drive_scene", "DriveSession"]

# the keys held to drive (GGUI's names, as the docs name them, what they do): docs/rendering.md's key table
DRIVE_KEYS = (
    (("w",), "W (with --drive)", "throttle: speed up to the top speed"),
    (("s",), "S (with --drive)", "brake, then reverse"),
    (("a", "d"), "A / D (with --drive)", "steer left / right (the free camera then only looks round)"),
)


def drive_scene(scene, name: str):
    """``scene`` made ready to drive vehicle ``name``: its path live (a scripted one from where and how fast its
    path starts), the camera's chase view following it. ValueError naming ``name`` if there is no such vehicle."""
    names = [v.name for v in scene.vehicles]
    if name not in names:
        raise ValueError(f"--drive: no vehicle named {name!r} (the vehicles: {', '.join(names)})")
    i = names.index(name)
    spec = scene.vehicles[i].path
    changes = {"camera.view": "chase", "camera.follow": name, "camera.target": name, "camera.shot": []}
    if spec.kind != "live":
        path = LivePath(spec.rows, live=False) if spec.kind == "recorded" else path_from_spec(
            spec.kind, **{k: v for k, v in spec.model_dump().items() if k != "kind"})
        p = path.pose(0.0)
        changes[f"vehicle[{i}].path"] = {"kind": "live", "start": [float(p.position[0]), float(p.position[1])],
                                         "heading": math.degrees(p.heading), "speed": float(p.speed)}
    return scene_with(scene, changes)


class DriveSession:
    """The drive of vehicle ``name`` in ``sim`` at ``fps`` frames a second (module docstring). ``rows``: the
    poses given, one per frame from frame 0 (the start): t, x, y, heading, speed, yaw_rate, wheel_spin."""

    def __init__(self, sim, name: str, fps: float):
        self.name, self.fps = name, float(fps)
        i = sim.fleet.names.index(name)
        spec, path = sim.scene.vehicles[i], sim.scene.vehicles[i].path
        self.rows = [tuple(float(v) for v in sim.drive_track(name)[0])]
        _, x, y, h, v, _, _ = self.rows[0]
        self.driver = Driver(x, y, h, v, float(spec.wheelbase), math.radians(path.steer_limit),
                             float(path.acceleration), float(path.top_speed))
        self.pedal = self.steering = 0

    @property
    def speed(self) -> float:
        return self.driver.speed

    def keys(self, held) -> None:
        """The keys held now (``held(key) -> bool``: the window's is_pressed) for the frames to come."""
        self.pedal = int(held("w")) - int(held("s"))
        self.steering = int(held("a")) - int(held("d"))

    def before_frame(self, sim, frame: int) -> None:
        """Frame ``frame`` is about to be simulated: drive the vehicle to its pose then (kept, or the keys')."""
        if frame < len(self.rows):  # driven before: the same pose again (a replay after going back)
            _, x, y, h, v, w, spin = self.rows[frame]
            sim.drive(self.name, (x, y), h, v, w, None if math.isnan(spin) else spin)
            return
        (x, y), h, v, w = self.driver.step(1.0 / self.fps, self.pedal, self.steering)
        sim.drive(self.name, (x, y), h, v, w)
        self.rows.append((frame / self.fps, x, y, h, v, w, math.nan))  # frames come one at a time

    def rewind(self, frame: int) -> bool:
        """The view went back to frame ``frame``: the rows after it go (the user drives on from there) and the
        keyboard's vehicle is where it was then. True if rows went."""
        if frame + 1 >= len(self.rows):
            return False
        del self.rows[frame + 1:]
        _, x, y, h, v, w, _ = self.rows[frame]
        d = self.driver
        d.x, d.y, d.heading, d.speed, d.yaw_rate, d.steer = x, y, h, v, w, 0.0
        return True

    def write(self, path, scene_name: str) -> None:
        """The drive so far as a recorded drive file (atomically)."""
        text = drive_text(self.rows, [f"vehicle {self.name} of scene {scene_name}, {len(self.rows)} poses at "
                                      f"{self.fps:g} a second (taichi-rocks view --drive)"]).encode()
        write_atomically(Path(path), lambda f: f.write(text))
