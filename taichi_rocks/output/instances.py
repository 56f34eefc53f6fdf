"""What an exported frame shows of the rocks and vehicles beyond the simulated state: instance ids that change
when a rock is recycled, the prototype each instance draws, and the vehicles' wheel spin.

Ids. A rock recycled to the bed's leading edge jumps across the bed; a tool that matches instances by id
would interpolate (and motion-blur) it along that jump. So each recycle gives the rock a new id: id = rock
index + N x generation (int64, unique in every frame), the generation counted per rock from the start of the
export. The engine counts recycles (``recycles_total``) but does not say which rocks; of the rocks that
moved farther since the previous frame than their speed allows (|dp| > (max(|v0|, |v1|) + g dt) dt + 1 mm)
the exporter takes, per frame, as many as the counter went up, farthest beyond the bound first.

Orientations and angular velocities are the engine's (engine/tumble.py: a Simulation built with tumbling,
whose ``state()`` has "orientations", unit quaternions (x, y, z, w) from the rock's frame to the world's, and
"angular_velocities", rad/s in world axes): set at launch by the tread, constant in the air, changed by the
ground's impulses, kept at rest. A recycled rock keeps its orientation under its new id.

Wheels. Each wheel turns by the distance the vehicle travelled along its heading over the tire radius,
times (1 + slip) for the rear wheels (the engine's tread speed of the splashing tires).
"""

from __future__ import annotations

import math

import numpy as np

from ..config.streams import EXPORT_PROTOTYPE
from .shapes import uniforms

__all__ = ["RockTracker", "VehicleTracker", "PROTOTYPES"]

PROTOTYPES = 3  # rock shapes, chosen per id


class RockTracker:
    """Per-rock export state across frames: generations (ids); see the module docstring."""

    def __init__(self, n: int, gravity: float, fps: float):
        self.n = int(n)
        self.g, self.dt = float(gravity), 1.0 / float(fps)
        self.generation = np.zeros(self.n, np.int64)
        self.prev = None  # positions, velocities, recycles_total of the previous frame

    def update(self, st: dict) -> dict:
        """Advance to the frame ``st`` (Simulation.state() of a simulation with tumbling); per rock (N,): ids,
        active (in the air or sliding, or moved since the previous frame), proto, orientations (x, y, z, w) and
        angular velocities (rad/s) as the engine has them, and ``recycled`` (given a new id in this frame)."""
        if "orientations" not in st:
            raise ValueError("the export needs the rocks' orientations: a Simulation built with tumble=True")
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
        self.prev = (pos.copy(), vel, int(st["recycles_total"]))
        ids = np.arange(self.n, dtype=np.int64) + self.n * self.generation
        proto = np.minimum((uniforms(ids, EXPORT_PROTOTYPE.first) * PROTOTYPES).astype(np.int32), PROTOTYPES - 1)
        return {"ids": ids, "active": active, "proto": proto, "orientations": np.asarray(st["orientations"]),
                "angular_velocities": np.asarray(st["angular_velocities"]), "recycled": recycled}

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
