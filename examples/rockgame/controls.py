"""What drives the player's car each frame: the keyboard through the game's car model (car.py), or a recorded
drive (docs/drives.md; config/drivefile.py reads it, motion/live.py gives its pose at any time), the offscreen
mode's scripted input. Either gives a :class:`Command`: the pose the car has at the frame's end, which goes to
``Simulation.drive`` and to the car drawn.

Keys: W / Up throttle, S / Down brake then reverse, A / Left and D / Right steer, Space the handbrake's opposite
(a burnout: the rear wheels spin at three times their rolling rate and throw harder), R back behind the truck,
C the camera, Escape quits.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from panda3d.core import KeyboardButton

from taichi_rocks.config.drivefile import read_drive
from taichi_rocks.motion.live import LivePath

from .car import Car

BURNOUT = 3.0  # the rear wheels' spin with Space, in multiples of rolling


class Command(NamedTuple):
    """The car's pose at the frame's end: world (x, y) m, heading rad, speed m/s, yaw rate rad/s, the front wheels'
    steering angle rad (drawn only) and the rear wheels' spin rad/s (None: rolling)."""

    position: tuple
    heading: float
    speed: float
    yaw_rate: float
    steer: float
    wheel_spin: float | None


class Keyboard:
    """The keyboard through the car model. ``watcher``: Panda3D's mouse watcher (it knows the keys held);
    ``car``: the model; ``tire_radius`` m (for the burnout's spin)."""

    KEYS = {"up": ("w", KeyboardButton.up()), "down": ("s", KeyboardButton.down()),
            "left": ("a", KeyboardButton.left()), "right": ("d", KeyboardButton.right()),
            "burnout": (KeyboardButton.space(),)}

    def __init__(self, watcher, car: Car, tire_radius: float):
        self.watcher, self.car, self.tire_radius = watcher, car, tire_radius

    def held(self, name: str) -> bool:
        if self.watcher is None:
            return False
        return any(self.watcher.isButtonDown(KeyboardButton.asciiKey(k) if isinstance(k, str) else k)
                   for k in self.KEYS[name])

    def command(self, t: float, dt: float) -> Command:
        pedal = int(self.held("up")) - int(self.held("down"))
        steering = int(self.held("left")) - int(self.held("right"))
        (x, y), h, v, w = self.car.step(dt, pedal, steering)
        spin = BURNOUT * v / self.tire_radius if self.held("burnout") and v > 0.5 else None
        return Command((x, y), h, v, w, self.car.steer, spin)


class Replay:
    """A recorded drive: the pose at time t of the drive file ``path``."""

    def __init__(self, path, wheelbase: float):
        self.track = LivePath(read_drive(path), live=False)
        self.wheelbase = wheelbase

    def command(self, t: float, dt: float) -> Command:
        p = self.track.pose(t)
        steer = math.atan(p.yaw_rate * self.wheelbase / p.speed) if abs(p.speed) > 0.5 else 0.0
        spin = None if math.isnan(p.wheel_spin) else float(p.wheel_spin)
        return Command((float(p.position[0]), float(p.position[1])), float(p.heading), float(p.speed),
                       float(p.yaw_rate), steer, spin)
