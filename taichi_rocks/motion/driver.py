"""A vehicle the keyboard drives (``taichi-rocks view --drive NAME``): the kinematic bicycle model (Rajamani,
*Vehicle Dynamics and Control*, 2nd ed., 2012, section 2.2, with the reference point at the body centre taken as
moving along the heading), stepped once a frame. Host side, plain floats.

State: position p (world XY, m), heading h (rad), speed v (m/s along the heading, negative reversing) and the
front wheels' steering angle delta. A frame of length dt with the pedal u (W: +1, S: -1, none: 0) and the
steering input s (A: +1 left, D: -1 right, none: 0):

  speed      W speeds up at a (the scene's ``acceleration``) to the top speed v_max, S brakes at 2 a and, once
             stopped, reverses at a to -v_max / 4; W while reversing brakes at 2 a; no pedal rolls down at
             ROLL_DECEL to a stop
  steering   delta moves towards s delta_lim(v) at delta_max / STEER_TIME rad/s (back to 0 when released), where
             delta_lim(v) = delta_max / (1 + (v / GRIP_SPEED)^2) keeps the lateral acceleration v^2 tan(delta) / L
             within what tires hold at speed (delta_max: the scene's ``steer_limit``; L: the wheelbase)
  yaw rate   omega = v tan(delta) / L
  pose       h' = h + omega dt, p' = p + v dt (cos h_m, sin h_m) with h_m = h + omega dt / 2 (the chord of the arc)

The pose handed to ``Simulation.drive`` each frame is (p', h', v', omega): every value given, nothing derived,
so a recorded drive replays it to the bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Driver", "ROLL_DECEL", "STEER_TIME", "GRIP_SPEED"]

ROLL_DECEL = 1.0  # m/s^2: how fast a vehicle with no pedal pressed slows down (rolling resistance, engine braking)
STEER_TIME = 0.3  # s: from straight ahead to the steering limit (and back)
GRIP_SPEED = 12.0  # m/s: above it the steering limit shrinks as 1 / (1 + (v / GRIP_SPEED)^2)


@dataclass
class Driver:
    """The keyboard's vehicle (module docstring): its state (``x``, ``y``, ``heading``, ``speed``, ``steer``) and
    limits (``wheelbase`` m, ``steer_limit`` rad, ``acceleration`` m/s^2, ``top_speed`` m/s)."""

    x: float
    y: float
    heading: float
    speed: float
    wheelbase: float
    steer_limit: float
    acceleration: float
    top_speed: float
    steer: float = 0.0
    yaw_rate: float = 0.0

    def step(self, dt: float, pedal: int, steering: int) -> tuple:
        """One frame of ``dt`` s with the pedal (+1 throttle, -1 brake / reverse, 0) and the steering input (+1
        left, -1 right, 0); returns the pose at its end: ((x, y), heading, speed, yaw_rate)."""
        self.speed = self._speed(dt, pedal)
        lim = self.steer_limit / (1.0 + (self.speed / GRIP_SPEED) ** 2)
        want = steering * lim
        rate = self.steer_limit / STEER_TIME * dt
        self.steer = min(max(want, self.steer - rate), self.steer + rate)
        self.yaw_rate = self.speed * math.tan(self.steer) / self.wheelbase
        mid = self.heading + 0.5 * self.yaw_rate * dt
        self.x += self.speed * dt * math.cos(mid)
        self.y += self.speed * dt * math.sin(mid)
        self.heading = math.remainder(self.heading + self.yaw_rate * dt, 2.0 * math.pi)
        return (self.x, self.y), self.heading, self.speed, self.yaw_rate

    def _speed(self, dt: float, pedal: int) -> float:
        v, a = self.speed, self.acceleration
        if pedal == 0:
            return math.copysign(max(abs(v) - ROLL_DECEL * dt, 0.0), v)
        if pedal * v < 0.0:  # against the motion: the brakes, stopping at 0
            stopped = abs(v) <= 2.0 * a * dt
            return 0.0 if stopped else v + pedal * 2.0 * a * dt
        top = self.top_speed if pedal > 0 else 0.25 * self.top_speed
        return pedal * min(abs(v) + a * dt, top)
