"""What an exported frame shows of the rocks and vehicles beyond the simulated state: instance ids that change
when a rock is recycled, a tumble, and the vehicles' wheel spin.

Ids. A rock recycled to the bed's leading edge jumps across the bed; a tool that matches instances by id
would interpolate (and motion-blur) it along that jump. So each recycle gives the rock a new id: id = rock
index + N x generation (int64, unique in every frame), the generation counted per rock from the start of the
export. The engine counts recycles (``recycles_total``) but does not say which rocks; of the rocks that
moved farther since the previous frame than their speed allows (|dp| > (max(|v0|, |v1|) + g dt) dt + 1 mm)
the exporter takes, per frame, as many as the counter went up, farthest beyond the bound first.

Tumble. The engine has no angular velocity. A rock's orientation is derived, deterministically, from its id
and the time it has spent moving: a fixed random orientation q0(id) (uniform over rotations), turned about a
random axis a(id) at a rate w(id) in [3, 15] rad/s for as long as the rock flies or slides, i.e.
q = rot(a, w tau) q0 with tau the moving time. A resting rock keeps its orientation (q0 for one that has not
moved since it was placed); a recycled rock starts again from the q0 of its new id.

Wheels. Each wheel turns by the distance the vehicle travelled along its heading over the tire radius,
times (1 + slip) for the rear wheels (the engine's tread speed of the splashing tires).
"""

from __future__ import annotations

import math

import numpy as np

from ..config.streams import EXPORT_ORIENTATION, EXPORT_PROTOTYPE, EXPORT_SPIN_AXIS, EXPORT_SPIN_RATE
from .shapes import axis_angle, quat_mul, random_quaternions, uniforms

__all__ = ["RockTracker", "VehicleTracker", "PROTOTYPES", "SPIN_RANGE"]

PROTOTYPES = 3  # rock shapes, chosen per id
SPIN_RANGE = (3.0, 15.0)  # rad/s, tumble rate of a moving rock


class RockTracker:
    """Per-rock export state across frames: generations (ids), moving time; see the module docstring."""

    def __init__(self, n: int, gravity: float, fps: float):
        self.n = int(n)
        self.g, self.dt = float(gravity), 1.0 / float(fps)
        self.generation = np.zeros(self.n, np.int64)
        self.moving_time = np.zeros(self.n)
        self.prev = None  # positions, velocities, recycles_total of the previous frame

    def update(self, st: dict) -> dict:
        """Advance to the frame ``st`` (Simulation.state()); per rock (N,): ids, active (in the air or sliding,
        or moved since the previous frame), proto, orientations (x, y, z, w), angular velocities (rad/s),
        and ``recycled`` (given a new id in this frame)."""
        pos = st["positions"]
        vel = np.asarray(st["velocities"], np.float64)
        moving = (vel != 0.0).any(axis=1)
        recycled = np.zeros(self.n, bool)
        active = moving.copy()
        if self.prev is not None:
            p0, v0, r0 = self.prev
            active |= (pos != p0).any(axis=1)
            recycled = self._recycled(pos, vel, p0, v0, int(st["recycles_total"]) - r0)
            self.generation[recycled] += 1
            self.moving_time[recycled] = 0.0
            self.moving_time[active & ~recycled] += self.dt
        self.prev = (pos.copy(), vel, int(st["recycles_total"]))
        ids = np.arange(self.n, dtype=np.int64) + self.n * self.generation
        axis, rate = self._spin(ids)
        q = quat_mul(axis_angle(axis, rate * self.moving_time), random_quaternions(ids, EXPORT_ORIENTATION.first))
        omega = axis * (rate * (moving & ~recycled))[:, None]
        proto = np.minimum((uniforms(ids, EXPORT_PROTOTYPE.first) * PROTOTYPES).astype(np.int32), PROTOTYPES - 1)
        return {"ids": ids, "active": active, "proto": proto, "orientations": q, "angular_velocities": omega,
                "recycled": recycled}

    def _recycled(self, pos, vel, p0, v0, count: int) -> np.ndarray:
        """The ``count`` rocks that jumped farthest beyond what their speed allows (see the module docstring)."""
        out = np.zeros(self.n, bool)
        if count <= 0:
            return out
        speed = np.maximum(np.linalg.norm(v0, axis=1), np.linalg.norm(vel, axis=1))
        excess = np.linalg.norm(pos - p0, axis=1) - ((speed + self.g * self.dt) * self.dt + 1e-3)
        candidates = np.flatnonzero(excess > 0.0)
        order = candidates[np.argsort(-excess[candidates], kind="stable")]
        out[order[:count]] = True
        return out

    @staticmethod
    def _spin(ids):
        z = 2.0 * uniforms(ids, EXPORT_SPIN_AXIS.first) - 1.0
        phi = 2.0 * np.pi * uniforms(ids, EXPORT_SPIN_AXIS.first + 1)
        s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        axis = np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)
        lo, hi = SPIN_RANGE
        return axis, lo + (hi - lo) * uniforms(ids, EXPORT_SPIN_RATE.first)


class VehicleTracker:
    """Vehicle headings unwrapped across frames (so that interpolating between two frames never turns a
    vehicle the long way round) and wheel angles (rad, front and rear) from the distance travelled."""

    def __init__(self, vehicles):
        self.radius = np.array([float(v.tire_radius) for v in vehicles])
        self.slip = np.array([float(v.slip) for v in vehicles])
        self.prev = None
        self.heading = None
        self.distance = np.zeros(len(self.radius))

    def update(self, positions, headings) -> dict:
        positions = np.asarray(positions, np.float64)
        headings = np.asarray(headings, np.float64)
        if self.prev is None:
            self.heading = headings.copy()
        else:
            p0, h0 = self.prev
            fwd = np.stack([np.cos(h0), np.sin(h0)], axis=1)
            self.distance += np.sum((positions[:, :2] - p0[:, :2]) * fwd, axis=1)
            self.heading = self.heading + np.array([math.remainder(a - b, 2.0 * math.pi)
                                                    for a, b in zip(headings, h0)])
        self.prev = (positions.copy(), headings.copy())
        front = self.distance / self.radius
        return {"positions": positions, "headings": self.heading.copy(), "front": front,
                "rear": front * (1.0 + self.slip)}
