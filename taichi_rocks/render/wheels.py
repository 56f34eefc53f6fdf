"""How far each vehicle has driven, and so how far its wheels have turned, host side (NumPy, no Taichi).

A wheel rolling without slip turns by distance / tire radius; the rear wheels spin ``1 + slip`` times faster
(the tread speed of motion/vehicles.py: omega R = v (1 + slip)). The distance is the integral of the path's
signed speed (negative when reversing) by the trapezoidal rule on a fixed grid of ``STEP`` seconds anchored at
t = 0 (exact for the paths' piecewise-constant accelerations except in the cells holding a knot), so the
angle at a time is a function of that time alone: a resumed render turns its wheels as an uninterrupted one.
"""

import math

import numpy as np

__all__ = ["STEP", "Odometer", "wheel_angles"]

STEP = 1.0 / 240.0  # s: the integration grid


class Odometer:
    """Signed distance driven since t = 0 along each of ``paths`` (objects whose ``pose(t).speed`` is the
    signed speed: the simulation's vehicle paths, ``sim.fleet.paths``), :meth:`at` any time t >= 0.

    Integrates forwards from the last grid point reached (so a render advancing frame by frame costs a few
    path evaluations per frame) and starts again from 0 when asked for an earlier time."""

    def __init__(self, paths):
        self.paths = list(paths)
        self._k = 0  # grid points integrated: the distance is known at t = k * STEP
        self._dist = np.zeros(len(self.paths))
        self._speed = self._speeds(0.0)

    def _speeds(self, t: float) -> np.ndarray:
        return np.array([p.pose(t).speed for p in self.paths], np.float64)

    def at(self, t: float) -> np.ndarray:
        """Distance (m) per vehicle at time ``t``."""
        t = max(float(t), 0.0)
        k = int(math.floor(t / STEP))
        if k < self._k:
            self._k, self._dist, self._speed = 0, np.zeros(len(self.paths)), self._speeds(0.0)
        while self._k < k:
            nxt = self._speeds((self._k + 1) * STEP)
            self._dist = self._dist + 0.5 * STEP * (self._speed + nxt)
            self._speed = nxt
            self._k += 1
        tau = t - k * STEP
        if tau <= 0.0:
            return self._dist.copy()
        return self._dist + 0.5 * tau * (self._speed + self._speeds(t))


def wheel_angles(spec, distance: float, rear) -> np.ndarray:
    """Angles (rad) of a vehicle's wheels after driving ``distance``: distance / tire radius, times
    (1 + slip) for the ``rear`` ones."""
    rear = np.asarray(rear, bool)
    return float(distance) / float(spec.tire_radius) * np.where(rear, 1.0 + float(spec.slip), 1.0)
