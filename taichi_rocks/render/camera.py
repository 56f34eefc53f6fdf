"""The chase camera and the view it gives, host side (NumPy, no Taichi).

Coordinate convention (the one place it is decided): we draw in the simulation's *local* frame
(world = ``sim.origin`` + local, Z up) without any axis swap, and set the GGUI camera's ``up`` to +Z
(:data:`GL_UP`). :func:`to_gl` is therefore the identity on the axes and only subtracts the floating origin;
every host-side world position goes through it, so GGUI's f32 stays precise far from (0, 0, 0).
"""

import math
from typing import NamedTuple

import numpy as np

from .looks import SUN_DIR_CAMERA

__all__ = ["GL_UP", "NEAR", "to_gl", "CameraRig", "View", "Lens", "look", "sun_direction"]

GL_UP = (0.0, 0.0, 1.0)  # GGUI camera up: the simulation's +Z (no axis swap anywhere)
NEAR = 0.05  # near plane, m (GGUI's and the rock culling's)


def to_gl(p_world, origin) -> np.ndarray:
    """World (Z up, float64) -> what GGUI gets: local coordinates (``p - origin``) as f32, axes unchanged.

    Together with ``camera.up = GL_UP`` this is the whole Z-up/Y-up conversion.
    """
    return (np.asarray(p_world, np.float64) - np.asarray(origin, np.float64)).astype(np.float32)


class CameraRig:
    """Chase camera: eye at ``offset`` in the followed vehicle's frame, looking ``look_ahead`` metres ahead.

    The frame's heading is smoothed exponentially with time constant ``smoothing`` seconds (a first-order
    low-pass, frame-rate independent: alpha = 1 - exp(-dt / smoothing)); positions are not lagged, so the
    vehicle stays framed at any speed, and the camera swings round late in turns. The first update snaps.
    """

    def __init__(self, offset, look_ahead: float, smoothing: float):
        self.offset = np.asarray(offset, np.float64)
        self.look_ahead = float(look_ahead)
        self.smoothing = float(smoothing)
        self.heading = None  # smoothed heading, rad
        self.t = None

    def update(self, position, heading: float, t: float):
        """Return (eye, target, smoothed heading), world float64."""
        if self.heading is None or self.smoothing <= 0.0:
            self.heading = float(heading)
        else:
            dt = max(0.0, float(t) - self.t)
            alpha = 1.0 - math.exp(-dt / self.smoothing)
            dh = math.remainder(float(heading) - self.heading, 2.0 * math.pi)
            self.heading += alpha * dh
        self.t = float(t)
        c, s = math.cos(self.heading), math.sin(self.heading)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        p = np.asarray(position, np.float64)
        eye = p + rot @ self.offset
        target = p + rot @ np.array([self.look_ahead, 0.0, 0.0])
        if np.linalg.norm(target - eye) < 1e-6:  # degenerate set-up: look forward
            target = eye + rot @ np.array([1.0, 0.0, 0.0])
        return eye, target, self.heading


class View(NamedTuple):
    """One frame's camera in local f32 coordinates: eye and target points, the unit basis (forward, right,
    up; right horizontal: the camera has no roll) and the smoothed heading (rad)."""

    eye: np.ndarray
    target: np.ndarray
    fwd: np.ndarray
    right: np.ndarray
    up: np.ndarray
    heading: float


def look(rig: CameraRig, position, heading: float, t: float, origin) -> View:
    """Advance ``rig`` to time ``t`` following a vehicle at ``position`` (world) with ``heading``; the view."""
    eye_w, target_w, heading = rig.update(position, heading, t)
    origin = np.asarray(origin, np.float64)
    eye, target = to_gl(eye_w, origin), to_gl(target_w, origin)
    fwd = (target - eye).astype(np.float64)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, GL_UP)
    if np.linalg.norm(right) < 1e-6:  # looking straight down or up
        right = np.array([math.sin(heading), -math.cos(heading), 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    return View(eye, target, fwd.astype(np.float32), right.astype(np.float32), up.astype(np.float32), heading)


def sun_direction(heading: float) -> np.ndarray:
    """Unit vector towards the sun: fixed in the camera's heading frame (behind, left, high), so the lit
    side of every rock faces the camera whatever the direction of travel."""
    c, s = math.cos(heading), math.sin(heading)
    sd = np.array(SUN_DIR_CAMERA, np.float64)
    sd = np.array([c * sd[0] - s * sd[1], s * sd[0] + c * sd[1], sd[2]])
    return sd / np.linalg.norm(sd)


class Lens(NamedTuple):
    """The projection of a ``fov`` (vertical, degrees) camera onto ``width`` x ``height`` pixels: half-extents
    of the image plane at 1 m depth (``tan_x``, ``tan_y``) and pixels per metre at 1 m depth."""

    tan_x: float
    tan_y: float
    px_per_rad: float

    @classmethod
    def of(cls, fov: float, width: int, height: int) -> "Lens":
        tan_y = math.tan(math.radians(fov) / 2)
        return cls(tan_y * width / height, tan_y, (height / 2) / tan_y)
