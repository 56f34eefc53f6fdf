"""The view a camera rig gives (the rig itself: motion/camera.py), host side (NumPy, no Taichi).

Coordinate convention (the one place it is decided): we draw in the simulation's *local* frame
(world = ``sim.origin`` + local, Z up) without any axis swap, and set the GGUI camera's ``up`` to +Z
(:data:`GL_UP`). :func:`to_gl` is therefore the identity on the axes and only subtracts the floating origin;
every host-side world position goes through it, so GGUI's f32 stays precise far from (0, 0, 0).
"""

import math
from typing import NamedTuple

import numpy as np

from ..motion.camera import (CHASE_OFFSET, VIEWS, CameraRig, SceneCamera, camera_of,  # noqa: F401
                             scene_camera, view_preset)
from .looks import SUN_DIR_CAMERA

__all__ = ["GL_UP", "NEAR", "VIEWS", "CHASE_OFFSET", "to_gl", "view_preset", "CameraRig", "camera_of",
           "SceneCamera", "scene_camera", "View", "Lens", "look", "look_at_time", "frame_of", "sun_vector",
           "sun_direction"]

GL_UP = (0.0, 0.0, 1.0)  # GGUI camera up: the simulation's +Z (no axis swap anywhere)
NEAR = 0.05  # near plane, m (GGUI's and the rock culling's)


def to_gl(p_world, origin) -> np.ndarray:
    """World (Z up, float64) -> what GGUI gets: local coordinates (``p - origin``) as f32, axes unchanged.

    Together with ``camera.up = GL_UP`` this is the whole Z-up/Y-up conversion.
    """
    return (np.asarray(p_world, np.float64) - np.asarray(origin, np.float64)).astype(np.float32)


class View(NamedTuple):
    """One frame's camera in local f32 coordinates: eye and target points, the unit basis (forward, right,
    up; right horizontal: the camera has no roll) and the smoothed heading (rad)."""

    eye: np.ndarray
    target: np.ndarray
    fwd: np.ndarray
    right: np.ndarray
    up: np.ndarray
    heading: float


def look(rig: CameraRig, position, heading: float, t: float, origin, target=None) -> View:
    """Advance ``rig`` to time ``t`` following a vehicle at ``position`` (world) with ``heading`` (and looking
    at ``target`` = (position, heading), if given: see :meth:`CameraRig.update`); the view."""
    eye_w, target_w, heading = rig.update(position, heading, t, target)
    origin = np.asarray(origin, np.float64)
    return frame_of(to_gl(eye_w, origin), to_gl(target_w, origin), heading)


def look_at_time(camera: SceneCamera, poses, t: float, origin) -> View:
    """Advance the scene's ``camera`` to time ``t`` with the vehicles at ``poses`` (motion/vehicles.py
    VehiclePose, world); the view (local f32 coordinates)."""
    positions = np.array([p.position for p in poses], np.float64)
    eye_w, target_w, heading = camera.update(positions, [p.heading for p in poses], t)
    origin = np.asarray(origin, np.float64)
    return frame_of(to_gl(eye_w, origin), to_gl(target_w, origin), heading)


def frame_of(eye, target, heading: float) -> View:
    """The view from ``eye`` looking at ``target`` (local f32 points): the camera's unit basis, no roll
    (``heading``, rad: the right vector's direction when looking straight down or up)."""
    fwd = (target - eye).astype(np.float64)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, GL_UP)
    if np.linalg.norm(right) < 1e-6:  # looking straight down or up
        right = np.array([math.sin(heading), -math.cos(heading), 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    return View(eye, target, fwd.astype(np.float32), right.astype(np.float32), up.astype(np.float32), heading)


def sun_vector(sun) -> np.ndarray:
    """[render] sun as a unit vector: from [x, y, z] or from a table with azimuth and elevation (degrees)."""
    if hasattr(sun, "azimuth"):
        az, el = math.radians(float(sun.azimuth)), math.radians(float(sun.elevation))
        return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    v = np.asarray(sun, np.float64)
    return v / np.linalg.norm(v)


def sun_direction(heading: float, sun=SUN_DIR_CAMERA, frame: str = "vehicle") -> np.ndarray:
    """Unit vector towards the sun (``sun``: see :func:`sun_vector`). ``frame`` "vehicle": ``sun`` is given in
    the camera rig's heading frame (that of the vehicle the camera rides with, smoothed: x forward, y left),
    so the default (behind, left, high) lights the side of every rock the chase camera sees whatever the
    direction of travel; "world": in the world's."""
    sd = sun_vector(sun)
    if frame == "world":
        return sd
    c, s = math.cos(heading), math.sin(heading)
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
