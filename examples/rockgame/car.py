"""The player's car as the game models it: a kinematic bicycle (Rajamani, *Vehicle Dynamics and Control*, 2nd ed.,
2012, section 2.2, reference point at the body centre) with an arcade longitudinal model, stepped once a frame.
The game owns it; the rock system only hears the pose it gives (``Simulation.drive``).

State: position p (world XY, m), heading h (rad), speed v (m/s along the heading, negative reversing), steering
angle delta. A frame of length dt with the pedal u in [-1, 1] (the keys: W +1, S -1) and the steering input s in
[-1, 1] (A: +1 left, D: -1 right):

    speed     throttle (u > 0): v += (u ENGINE - DRAG v^2) dt up to TOP; brake (u < 0 while v > 0): v -= |u| BRAKE dt
              down to 0, then reverse at |u| REVERSE up to -TOP_REVERSE; no pedal: v -= sign(v) (ROLL + DRAG v^2) dt
              to a stop
    steering  delta -> s delta_max / (1 + (v / GRIP)^2) at delta_max / STEER_TIME rad/s
    yaw rate  omega = v tan(delta) / wheelbase
    pose      h += omega dt;  p += v dt (cos h_m, sin h_m),  h_m = h - omega dt / 2 (the chord of the arc)

The drag term makes the throttle's top speed ~ sqrt(ENGINE / DRAG) = 33 m/s, above the truck's 16 m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

ENGINE = 5.0  # m/s^2 at full throttle, standing
DRAG = 0.0045  # 1/m: aerodynamic drag over mass
BRAKE = 9.0  # m/s^2
REVERSE = 3.0  # m/s^2
ROLL = 0.6  # m/s^2: rolling resistance and engine braking with no pedal
TOP, TOP_REVERSE = 40.0, 6.0  # m/s
STEER_MAX = math.radians(32.0)
STEER_TIME = 0.25  # s from straight ahead to full lock
GRIP = 11.0  # m/s: above it the steering limit shrinks as 1 / (1 + (v / GRIP)^2)


@dataclass
class Car:
    """The model's state (module docstring); ``wheelbase`` m."""

    x: float
    y: float
    heading: float
    speed: float
    wheelbase: float = 2.7
    steer: float = 0.0
    yaw_rate: float = 0.0

    def step(self, dt: float, pedal: float, steering: float) -> tuple:
        """One frame; returns the pose at its end: ((x, y), heading, speed, yaw_rate)."""
        self.speed = self._speed(dt, pedal)
        lim = STEER_MAX / (1.0 + (self.speed / GRIP) ** 2)
        rate = STEER_MAX / STEER_TIME * dt
        self.steer = min(max(steering * lim, self.steer - rate), self.steer + rate)
        self.yaw_rate = self.speed * math.tan(self.steer) / self.wheelbase
        self.heading = math.remainder(self.heading + self.yaw_rate * dt, 2.0 * math.pi)
        mid = self.heading - 0.5 * self.yaw_rate * dt
        self.x += self.speed * dt * math.cos(mid)
        self.y += self.speed * dt * math.sin(mid)
        return (self.x, self.y), self.heading, self.speed, self.yaw_rate

    def _speed(self, dt: float, pedal: float) -> float:
        v = self.speed
        if pedal > 0 and v >= 0.0:
            return min(v + (pedal * ENGINE - DRAG * v * v) * dt, TOP)
        if pedal > 0:  # forward while reversing: brake
            return min(v + pedal * BRAKE * dt, 0.0)
        if pedal < 0 and v > 0.0:
            return max(v + pedal * BRAKE * dt, 0.0)
        if pedal < 0:
            return max(v + pedal * REVERSE * dt, -TOP_REVERSE)
        slow = (ROLL + DRAG * v * v) * dt
        return math.copysign(max(abs(v) - slow, 0.0), v)

    def place(self, x: float, y: float, heading: float, speed: float) -> None:
        """Put the car somewhere (a respawn), wheels straight."""
        self.x, self.y, self.heading, self.speed, self.steer, self.yaw_rate = x, y, heading, speed, 0.0, 0.0
