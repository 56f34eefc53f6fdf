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

__all__ = ["GL_UP", "NEAR", "VIEWS", "CHASE_OFFSET", "to_gl", "view_preset", "CameraRig", "camera_of", "View",
           "Lens", "look", "sun_vector", "sun_direction"]

GL_UP = (0.0, 0.0, 1.0)  # GGUI camera up: the simulation's +Z (no axis swap anywhere)
NEAR = 0.05  # near plane, m (GGUI's and the rock culling's)


def to_gl(p_world, origin) -> np.ndarray:
    """World (Z up, float64) -> what GGUI gets: local coordinates (``p - origin``) as f32, axes unchanged.

    Together with ``camera.up = GL_UP`` this is the whole Z-up/Y-up conversion.
    """
    return (np.asarray(p_world, np.float64) - np.asarray(origin, np.float64)).astype(np.float32)


VIEWS = ("chase", "side", "low", "orbit")
CHASE_OFFSET = (-9.0, 0.0, 3.5)  # m: the chase view's eye, in the followed vehicle's frame


def _body(spec):
    """The sizes a view is framed by: length, body top, rear axle x, tire radius, track (m)."""
    R = float(spec.tire_radius)
    return float(spec.length), 0.8 * R + float(spec.height), -0.5 * float(spec.wheelbase), R, float(spec.track)


def view_preset(view: str, follow_spec, target_spec, look_ahead: float):
    """The default eye (in the frame of the vehicle it rides with, ``follow_spec``) and aim point (in the
    target's frame) of a view, m. Side, low and orbit ride with the target (see :func:`camera_of`).

    * chase: behind and above the followed vehicle, looking ``look_ahead`` metres ahead of the target;
    * side: on the vehicle's left (the side the default sun lights), level with a point a quarter
      of its length behind its rear axle, at 1.4 m, looking across at the target's rear tires and the spray
      behind them; far enough (4 m + half the length) to frame the rear half of the body and the spray;
    * low: at 1.2 m, 5.5 m behind the vehicle's rear axle and 3.5 m outside its left tires, looking along
      the spray at a point a quarter of the target's length behind its rear axle (the rear tires on the
      left of the frame, the spray on the right);
    * orbit: the side view's eye turned about the vehicle's centre (:class:`CameraRig`).
    """
    if view not in VIEWS:
        raise ValueError(f"camera.view must be one of {', '.join(VIEWS)}, got {view!r}")
    L, top, xr, R, track = _body(follow_spec)
    tL, ttop, txr, tR, _ = _body(target_spec)
    if view == "chase":
        return np.array(CHASE_OFFSET), np.array([float(look_ahead), 0.0, 0.0])
    if view in ("side", "orbit"):
        return (np.array([xr - 0.25 * L, 4.0 + 0.5 * L, 1.4]),
                np.array([txr - 0.25 * tL, 0.0, max(0.4 * ttop, tR)]))
    return np.array([xr - 5.5, 0.5 * track + 3.5, 1.2]), np.array([txr - 0.25 * tL, 0.0, 0.35 * ttop])


class CameraRig:
    """The camera: eye at ``offset`` in the followed vehicle's frame, looking at ``aim`` in the target's frame
    (default: ``look_ahead`` metres ahead, on the ground: the chase camera).

    The followed vehicle's heading is smoothed exponentially with time constant ``smoothing`` seconds (a
    first-order low-pass, frame-rate independent: alpha = 1 - exp(-dt / smoothing)); positions are not lagged,
    so the vehicle stays framed at any speed, and the camera swings round late in turns. The first update
    snaps. The aim point turns with the smoothed heading too when the target is the followed vehicle, with
    the target's own heading otherwise. ``orbit_period`` (s): the eye turns about the followed vehicle's
    centre once in that time (counter-clockwise seen from above), a pure function of the time (so it needs
    no state to resume); None: no orbit.
    """

    def __init__(self, offset, look_ahead: float, smoothing: float, *, aim=None, orbit_period=None):
        self.offset = np.asarray(offset, np.float64)
        self.look_ahead = float(look_ahead)
        self.aim = np.array([self.look_ahead, 0.0, 0.0]) if aim is None else np.asarray(aim, np.float64)
        self.orbit_period = None if orbit_period is None else float(orbit_period)
        self.smoothing = float(smoothing)
        self.heading = None  # smoothed heading, rad
        self.t = None

    def update(self, position, heading: float, t: float, target=None):
        """Return (eye, target point, smoothed heading), world float64. ``target``: (position, heading) of
        the vehicle looked at, if it is not the followed one."""
        if self.heading is None or self.smoothing <= 0.0:
            self.heading = float(heading)
        else:
            dt = max(0.0, float(t) - self.t)
            alpha = 1.0 - math.exp(-dt / self.smoothing)
            dh = math.remainder(float(heading) - self.heading, 2.0 * math.pi)
            self.heading += alpha * dh
        self.t = float(t)
        p = np.asarray(position, np.float64)
        offset = self.offset
        if self.orbit_period is not None:
            offset = _yaw(2.0 * math.pi * float(t) / self.orbit_period) @ offset
        rot = _yaw(self.heading)
        eye = p + rot @ offset
        if target is None:
            look_at = p + rot @ self.aim
        else:
            look_at = np.asarray(target[0], np.float64) + _yaw(float(target[1])) @ self.aim
        if np.linalg.norm(look_at - eye) < 1e-6:  # degenerate set-up: look forward
            look_at = eye + rot @ np.array([1.0, 0.0, 0.0])
        return eye, look_at, self.heading


def _yaw(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def camera_of(scene):
    """The camera a scene asks for: (rig, index of the vehicle the eye rides with, index of the vehicle looked
    at). The chase view rides with ``camera.follow`` (default: bed.follow); side, low and orbit frame the
    ``camera.target`` (default: follow) and ride with it. ValueError naming the key if a name is unknown."""
    cam = scene.camera
    names = [v.name for v in scene.vehicles]
    follow = cam.follow or getattr(scene.bed, "follow", None) or names[0]
    target = cam.target or follow
    for key, name in (("follow", follow), ("target", target)):
        if name not in names:
            raise ValueError(f"camera.{key}: no vehicle named {name!r} (vehicles: {', '.join(names)})")
    j = names.index(target)
    i = names.index(follow) if cam.view == "chase" else j
    offset, aim = view_preset(cam.view, scene.vehicles[i], scene.vehicles[j], cam.look_ahead)
    rig = CameraRig(offset if cam.offset is None else cam.offset, cam.look_ahead, cam.smoothing,
                    aim=aim if cam.aim is None else cam.aim,
                    orbit_period=cam.orbit_period if cam.view == "orbit" else None)
    return rig, i, j


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
    eye, target = to_gl(eye_w, origin), to_gl(target_w, origin)
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
