"""The camera of [camera] on the host (NumPy, no Taichi): the view presets, the smoothed follow rule and the
shots. One rule for everything that frames the scene: the renderer (render/camera.py, for ``render`` and
``view``) and the USD export (output/export.py) both ask :func:`scene_camera` for the scene's camera and step
it with :meth:`SceneCamera.update` at every frame time.

The cameras, each under a name of its own: the scene's [camera] table is config/models.py ``CameraSettings``
(its [[camera.shot]] tables ``Shot``); the camera that plays them is :class:`SceneCamera` (here), each shot's
follow rule a :class:`CameraRig`; one frame's view is render/camera.py ``View``, the kernels' copy of it
render/kernels.py ``CameraBasis``; GGUI's own ``ti.ui.Camera`` is set from the view by the Renderer
(``_ggui_camera``) and moved by the user in render/freecam.py ``FreeCamera``.

Views. The presets are one table, :data:`VIEW_TABLE`: a row per view (:class:`CameraView`) names it, says
whether it is mounted on the body, which vehicle it rides with, whether it looks out of a cabin, and gives its
pose (eye and aim) and whether it orbits. A view is one row (and its name among the scene's choices,
config/models.py CAMERA_VIEWS: the module refuses to load when the two lists differ); a name without a row is
refused (ValueError), never taken for another view.

Shots. The [camera] table's view plays from t = 0 until the first [[camera.shot]] (from its ``at``, s), each
shot until the next. A shot's keys left out come from the [camera] table (follow, target; look_ahead,
smoothing and orbit_period always do), its offset and aim from its view. Where a shot starts, the camera cuts:
the rig snaps to the new shot instead of smoothing into it. The camera's state is the rig's smoothed heading
and clock (``heading``, ``t``): the shot in effect follows from the clock, so a render resumed from a saved
state, or a viewer scrubbed back to one, frames every later frame as an uninterrupted run does, across cuts
too.
"""

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..config.keys import choices
from .cabin import cabin_of

__all__ = ["VIEWS", "CameraView", "VIEW_TABLE", "view_of", "CHASE_OFFSET", "view_preset", "CameraRig", "camera_of",
           "Shot", "shots_of", "SceneCamera", "scene_camera"]

VIEWS = choices("camera.view")  # the presets, in the scene's order (config/models.py CAMERA_VIEWS)
CHASE_OFFSET = (-9.0, 0.0, 3.5)  # m: the chase view's eye, in the followed vehicle's frame
MOUNTED_REACH = 30.0  # m: the driver and bonnet views look at a point this far ahead
MOUNTED_PITCH = 2.5  # deg: ... this far below the eye's height (the road ahead, the vehicle in front)
AT_TOLERANCE = 1e-9  # s: a shot starts at a frame time that rounds to within this of its at


def _body(spec):
    """The sizes a view is framed by: length, body top, rear axle x, tire radius, track (m)."""
    R = float(spec.tire_radius)
    return float(spec.length), 0.8 * R + float(spec.height), -0.5 * float(spec.wheelbase), R, float(spec.track)


def _mounted(eye) -> tuple:
    """The eye and aim of a camera fixed to the body at ``eye`` (motion/cabin.py): looking straight ahead,
    MOUNTED_PITCH below the horizontal."""
    eye = np.array(eye)
    drop = MOUNTED_REACH * math.tan(math.radians(MOUNTED_PITCH))
    return eye, eye + np.array([MOUNTED_REACH, 0.0, -drop])


def _chase_pose(follow_spec, target_spec, look_ahead: float) -> tuple:
    """Behind and above the followed vehicle, looking ``look_ahead`` metres ahead of the target."""
    return np.array(CHASE_OFFSET), np.array([float(look_ahead), 0.0, 0.0])


def _side_pose(follow_spec, target_spec, look_ahead: float) -> tuple:
    """On the vehicle's left (the side the default sun lights), level with a point a quarter of its length
    behind its rear axle, at 1.4 m, looking across at the target's rear tires and the spray behind them; far
    enough (4 m + half the length) to frame the rear half of the body and the spray."""
    L, top, xr, R, track = _body(follow_spec)
    tL, ttop, txr, tR, _ = _body(target_spec)
    return (np.array([xr - 0.25 * L, 4.0 + 0.5 * L, 1.4]),
            np.array([txr - 0.25 * tL, 0.0, max(0.4 * ttop, tR)]))


def _low_pose(follow_spec, target_spec, look_ahead: float) -> tuple:
    """At 1.2 m, 5.5 m behind the vehicle's rear axle and 3.5 m outside its left tires, looking along the spray
    at a point a quarter of the target's length behind its rear axle (the rear tires on the left of the frame,
    the spray on the right)."""
    L, top, xr, R, track = _body(follow_spec)
    tL, ttop, txr, tR, _ = _body(target_spec)
    return np.array([xr - 5.5, 0.5 * track + 3.5, 1.2]), np.array([txr - 0.25 * tL, 0.0, 0.35 * ttop])


def _driver_pose(follow_spec, target_spec, look_ahead: float) -> tuple:
    """The driver's eye behind the windscreen of the vehicle ridden with (motion/cabin.py), looking straight
    ahead and a little down (MOUNTED_PITCH): its bonnet and the windscreen's frame in the lower and outer part
    of the image, the road and the vehicle in front in the middle."""
    return _mounted(cabin_of(follow_spec).eye)


def _bonnet_pose(follow_spec, target_spec, look_ahead: float) -> tuple:
    """A camera on the bonnet of the vehicle ridden with, looking ahead as the driver does."""
    return _mounted(cabin_of(follow_spec).bonnet_eye)


@dataclass(frozen=True)
class CameraView:
    """One view preset, a row of :data:`VIEW_TABLE`. ``mounted``: the eye is fixed to the body of the vehicle it
    rides with (it turns with the body; the aim is in that vehicle's frame); ``rides``: the vehicle it rides
    with, "follow" (camera.follow) or "target" (camera.target); ``inside``: it looks out of that vehicle's
    cabin (the renderer draws the windscreen's frame, render/interior.py, and the marks on the glass's inner
    side); ``pose``: (follow spec, target spec, look_ahead) -> its default eye (in the frame of the vehicle it
    rides with) and aim point (in the target's frame; mounted: in the frame of the vehicle ridden with), m;
    ``orbits``: the eye turns about the vehicle once per camera.orbit_period."""

    name: str
    mounted: bool
    rides: str
    inside: bool
    pose: Callable
    orbits: bool = False


#: The view presets, one row each; the names are the scene's (config/models.py CAMERA_VIEWS), in its order.
VIEW_TABLE = {v.name: v for v in (
    CameraView("chase", mounted=False, rides="follow", inside=False, pose=_chase_pose),
    CameraView("side", mounted=False, rides="target", inside=False, pose=_side_pose),
    CameraView("low", mounted=False, rides="target", inside=False, pose=_low_pose),
    CameraView("orbit", mounted=False, rides="target", inside=False, pose=_side_pose, orbits=True),
    CameraView("driver", mounted=True, rides="follow", inside=True, pose=_driver_pose),
    CameraView("bonnet", mounted=True, rides="follow", inside=False, pose=_bonnet_pose),
)}
if tuple(VIEW_TABLE) != VIEWS:  # a view of the scene's list without its row (or the other way round)
    raise ImportError(f"motion/camera.py VIEW_TABLE {tuple(VIEW_TABLE)} differs from camera.view's choices {VIEWS}")


def view_of(view: str) -> CameraView:
    """The row of view preset ``view``; ValueError naming the key if there is none."""
    try:
        return VIEW_TABLE[view]
    except (KeyError, TypeError):
        raise ValueError(f"camera.view must be one of {', '.join(VIEWS)}, got {view!r}") from None


def view_preset(view: str, follow_spec, target_spec, look_ahead: float):
    """The default eye (in the frame of the vehicle it rides with, ``follow_spec``) and aim point (in the
    target's frame; mounted views: in the frame of the vehicle ridden with) of a view, m: its row's ``pose``
    (:data:`VIEW_TABLE`; the orbit view is the side view's eye turned about the vehicle's centre,
    :class:`CameraRig`). ValueError for a name without a row."""
    return view_of(view).pose(follow_spec, target_spec, look_ahead)


class CameraRig:
    """The camera: eye at ``offset`` in the followed vehicle's frame, looking at ``aim`` in the target's frame
    (default: ``look_ahead`` metres ahead, on the ground: the chase camera).

    The followed vehicle's heading is smoothed exponentially with time constant ``smoothing`` seconds (a
    first-order low-pass, frame-rate independent: alpha = 1 - exp(-dt / smoothing)); positions are not lagged,
    so the vehicle stays framed at any speed, and the camera swings round late in turns. The first update
    snaps. The aim point turns with the smoothed heading too when the target is the followed vehicle, with
    the target's own heading otherwise. ``orbit_period`` (s): the eye turns about the followed vehicle's
    centre once in that time (counter-clockwise seen from above), a pure function of the time (so it needs
    no state to resume); None: no orbit. ``mounted``: the eye is fixed to the body (it turns with the vehicle's
    own heading, so it stays in its seat in a turn) and looks along ``aim - offset`` turned by the smoothed
    heading (the driver's gaze follows the turn smoothly).
    """

    def __init__(self, offset, look_ahead: float, smoothing: float, *, aim=None, orbit_period=None,
                 mounted: bool = False):
        self.offset = np.asarray(offset, np.float64)
        self.look_ahead = float(look_ahead)
        self.aim = np.array([self.look_ahead, 0.0, 0.0]) if aim is None else np.asarray(aim, np.float64)
        self.orbit_period = None if orbit_period is None else float(orbit_period)
        self.smoothing = float(smoothing)
        self.mounted = bool(mounted)
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
        if self.mounted:
            eye = p + _yaw(float(heading)) @ offset
            look_at = eye + rot @ (self.aim - offset)
        else:
            eye = p + rot @ offset
            look_at = p + rot @ self.aim
        if target is not None:
            look_at = np.asarray(target[0], np.float64) + _yaw(float(target[1])) @ self.aim
        if np.linalg.norm(look_at - eye) < 1e-6:  # degenerate set-up: look forward
            look_at = eye + rot @ np.array([1.0, 0.0, 0.0])
        return eye, look_at, self.heading


def _yaw(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Shot:
    """One shot as the camera plays it: from ``at`` (s), ``view`` riding with vehicle ``rides`` (an index into
    the scene's vehicles) and looking at vehicle ``target``, eye ``offset`` and ``aim`` point (m, body frames:
    see :func:`view_preset`)."""

    at: float
    view: str
    rides: int
    target: int
    offset: tuple
    aim: tuple


def _shot(scene, at: float, view: str, follow, target, offset, aim) -> Shot:
    """A shot of ``view`` with the vehicles named (None: the [camera] table's; ValueError naming the key if a
    name is unknown) and the view's own offset and aim where None."""
    settings = scene.camera
    names = [v.name for v in scene.vehicles]
    follow = follow or settings.follow or getattr(scene.bed, "follow", None) or names[0]
    target = target or settings.target or follow
    for key, name in (("follow", follow), ("target", target)):
        if name not in names:
            raise ValueError(f"camera.{key}: no vehicle named {name!r} (vehicles: {', '.join(names)})")
    row = view_of(view)
    j = names.index(target)
    i = names.index(follow) if row.rides == "follow" else j
    if row.mounted:
        j = i  # the aim is in the frame of the vehicle ridden with
    eye, look = view_preset(view, scene.vehicles[i], scene.vehicles[j], settings.look_ahead)
    return Shot(float(at), view, i, j, tuple(map(float, eye if offset is None else offset)),
                tuple(map(float, look if aim is None else aim)))


def shots_of(scene, view=None) -> tuple:
    """The scene's camera as shots (:class:`Shot`), in time order: the [camera] table's own view from t = 0,
    then each [[camera.shot]] (one that starts at 0 replaces the table's). ``view``: another preset for the
    whole scene instead (the viewer's camera buttons; its own eye and aim, except that the [camera] table's
    own view keeps its offset and aim), with the table's vehicles."""
    settings = scene.camera
    if view is not None:
        own = view == settings.view
        return (_shot(scene, 0.0, view, None, None, settings.offset if own else None,
                      settings.aim if own else None),)
    out = [_shot(scene, 0.0, settings.view, None, None, settings.offset, settings.aim)]
    for s in settings.shots:
        if s.at <= AT_TOLERANCE:
            out.clear()
        out.append(_shot(scene, s.at, s.view, s.follow, s.target, s.offset, s.aim))
    return tuple(out)


class SceneCamera:
    """The scene's camera over time: the shot in effect at each time (:func:`shots_of`), each framed by its
    :class:`CameraRig`; a cut (a shot starting, or the first update) snaps. ``heading`` and ``t`` are its whole
    state (the smoothed heading of the vehicle ridden with, rad, and the time of the last update, s): saved
    and set again, they make the camera frame every later time as it would have."""

    def __init__(self, shots, look_ahead: float, smoothing: float, orbit_period: float):
        if not shots:
            raise ValueError("a camera needs at least one shot")
        self.shots = tuple(shots)
        self._rigs = [_rig(s, look_ahead, smoothing, orbit_period) for s in self.shots]
        self.heading = None
        self.t = None

    def index_at(self, t: float) -> int:
        """The shot in effect at time ``t`` (s): the last one whose ``at`` is not after it."""
        k = 0
        for i, s in enumerate(self.shots):
            if s.at <= float(t) + AT_TOLERANCE:
                k = i
        return k

    def shot_at(self, t: float) -> Shot:
        return self.shots[self.index_at(t)]

    @property
    def shot(self) -> Shot:
        """The shot of the last update (the first shot before any)."""
        return self.shots[0 if self.t is None else self.index_at(self.t)]

    def update(self, positions, headings, t: float):
        """Advance to time ``t`` with the vehicles at ``positions`` (V, 3) and ``headings`` (V,) (world); return
        (eye, target point, smoothed heading), world float64."""
        k = self.index_at(t)
        shot, rig = self.shots[k], self._rigs[k]
        cut = self.t is None or self.index_at(self.t) != k
        rig.heading, rig.t = (None, None) if cut else (self.heading, self.t)
        i, j = shot.rides, shot.target
        looked_at = None if j == i else (positions[j], float(headings[j]))
        eye, look_at, heading = rig.update(positions[i], float(headings[i]), t, looked_at)
        self.heading, self.t = rig.heading, rig.t
        return eye, look_at, heading


def scene_camera(scene, view=None) -> SceneCamera:
    """The camera a scene asks for (its [camera] table and shots; ``view``: one preset instead, see
    :func:`shots_of`). ValueError naming the key if a vehicle name is unknown."""
    c = scene.camera
    return SceneCamera(shots_of(scene, view), c.look_ahead, c.smoothing, c.orbit_period)


def camera_of(scene, view=None):
    """The [camera] table's own view (shots aside; ``view``: another preset, see :func:`shots_of`): (rig,
    index of the vehicle the eye rides with, index of the vehicle looked at). The chase, driver and bonnet
    views ride with ``camera.follow`` (default: bed.follow); side, low and orbit frame the ``camera.target``
    (default: follow) and ride with it. ValueError naming the key if a name is unknown."""
    s = shots_of(scene, scene.camera.view if view is None else view)[0]
    c = scene.camera
    return _rig(s, c.look_ahead, c.smoothing, c.orbit_period), s.rides, s.target


def _rig(shot: Shot, look_ahead: float, smoothing: float, orbit_period: float) -> CameraRig:
    """The rig of ``shot``: its eye and aim, mounted and orbiting as its view's row says."""
    row = view_of(shot.view)
    return CameraRig(shot.offset, look_ahead, smoothing, aim=shot.aim, mounted=row.mounted,
                     orbit_period=orbit_period if row.orbits else None)
