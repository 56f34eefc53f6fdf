"""The camera rig of [camera] on the host (NumPy, no Taichi): the view presets and the smoothed follow rule.
One rule for everything that frames the scene: the renderer (render/camera.py) and the USD export
(output/export.py) both use :func:`camera_of`.

The cameras, each under a name of its own: the scene's [camera] table is config/models.py ``CameraSettings``;
the rig that follows the vehicles is :class:`CameraRig` (here); one frame's view is render/camera.py ``View``,
the kernels' copy of it render/kernels.py ``CameraBasis``; GGUI's own ``ti.ui.Camera`` is set from the view
by the Renderer (``_ggui_camera``) and moved by the user in render/freecam.py ``FreeCamera``."""

import math

import numpy as np

from ..config.keys import choices

__all__ = ["VIEWS", "CHASE_OFFSET", "view_preset", "CameraRig", "camera_of"]

VIEWS = choices("camera.view")  # the presets, in the scene's order
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


def camera_of(scene, view=None):
    """The camera a scene asks for: (rig, index of the vehicle the eye rides with, index of the vehicle looked
    at). The chase view rides with ``camera.follow`` (default: bed.follow); side, low and orbit frame the
    ``camera.target`` (default: follow) and ride with it. ValueError naming the key if a name is unknown.
    ``view``: another preset than ``camera.view`` (its own eye and aim: the scene's offset and aim belong to
    its view), with the scene's vehicles, look-ahead, smoothing and orbit period."""
    settings = scene.camera
    own = view is None or view == settings.view
    view = settings.view if view is None else view
    names = [v.name for v in scene.vehicles]
    follow = settings.follow or getattr(scene.bed, "follow", None) or names[0]
    target = settings.target or follow
    for key, name in (("follow", follow), ("target", target)):
        if name not in names:
            raise ValueError(f"camera.{key}: no vehicle named {name!r} (vehicles: {', '.join(names)})")
    j = names.index(target)
    i = names.index(follow) if view == "chase" else j
    offset, aim = view_preset(view, scene.vehicles[i], scene.vehicles[j], settings.look_ahead)
    rig = CameraRig(offset if settings.offset is None or not own else settings.offset, settings.look_ahead,
                    settings.smoothing, aim=aim if settings.aim is None or not own else settings.aim,
                    orbit_period=settings.orbit_period if view == "orbit" else None)
    return rig, i, j
