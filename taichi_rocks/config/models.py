"""The scene models: one frozen pydantic model per table of docs/scene-format.md. They are both the validator
and the source of the JSON Schema (config/scene.py). No Taichi."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationInfo, create_model, field_validator, model_validator

from .values import (Bool, CellSize, Color, Float, Int, Name, Pixels, Range, Speed, TableSize, Vec2, Vec3, _either,
                     _f, _follow, _is_list, _raise_problems, _show, _Table, SEED_MAX)
from .drivefile import DriveFileError, read_drive
from .resolution import MIN_SIDE
from .impacts import Impacts
from .limits import MAX_STEPS, steps_estimate
from .effects import EFFECTS
from .presets import PRESETS


# ---------------------------------------------------------------------------------------------- the models
class Environment(_Table):
    """Physical constants of the world (Z up)."""
    model_config = ConfigDict(title="World")  # the [world] table; the engine's fields are engine/world.py's World
    gravity: Float = _f(9.81, "m/s^2 along -Z", ge=0)
    ground_z: Float = _f(0.0, "m, height of the ground plane")
    air_density: Float = _f(1.2, "kg/m^3, for quadratic drag", ge=0)
    air_viscosity: Float = _f(1.81e-5, "Pa s, for linear (Stokes) drag", ge=0)
    restitution: Float = _f(0.35, "ground bounce coefficient, in [0, 1]", ge=0, le=1)
    ground_friction: Float = _f(0.6, "Coulomb friction rock-ground (bounce and sliding)", ge=0)
    rest_speed: Float = _f(0.05, "m/s: a rock touching the ground slower than this comes to rest", gt=0)
    wetness: Float = _f(0.0, "ground wetness in [0, 1]: 1 = a soaked film that makes stones stick to the tread",
                        ge=0, le=1)


class Bed(_Table):
    """The disc of rocks that follows a vehicle."""
    follow: Optional[Name] = _follow("name of the vehicle the bed follows; default: the first vehicle")
    radius: Float = _f(30.0, "m, radius of the bed", gt=0)
    rocks: Int = _f(100000, "number of rocks", ge=0)
    rock_radius: Range(gt=0) = _f((0.015, 0.05), "m, [min, max] rock radius, 0 < min <= max")
    density: Float = _f(2600.0, "kg/m^3, rock density", gt=0)
    static_friction: Range(ge=0) = _f((0.4, 0.9), "[min, max] rock static friction, 0 <= min <= max")
    drag_coefficient: Float = _f(0.47, "sphere drag coefficient C_d", ge=0)


class Launch(_Table):
    """How the rear tires throw rocks (docs/physics.md, "The throw")."""
    model: Literal["tread", "uniform"] = _f("tread", "tread: capture and force balance; uniform: release "
                                                     "angle uniform in release_angle")
    groove: Float = _f(0.012, "m, stone radius the tread's grooves hold (tread)", gt=0)
    grip: Float = _f(2.0e5, "Pa, clamp stress of the tread on a carried stone (tread)", ge=0)
    grip_relax: Float = _f(12.0, "deg, angle over which the clamp relaxes after the contact patch (tread)", gt=0)
    grip_spread: Float = _f(0.3, "log-spread of the clamp from stone to stone (tread)", ge=0)
    adhesion: Float = _f(3.0e4, "Pa, adhesion stress of a soaked film at wetness 1 (tread)", ge=0)
    transfer: Float = _f(1.0, "launch velocity factor k = min(1, transfer * friction) (tread)", ge=0)
    release_angle: Range(ge=0, le=90) = _f((10.0, 35.0), "deg, [min, max] angle up the back of the tire, "
                                                         "0 <= min <= max <= 90")
    spread: Float = _f(8.0, "deg, lateral scatter half-angle, in [0, 90]", ge=0, le=90)
    spin_spread: Float = _f(0.5, "scatter of a launched stone's spin about its rolling spin off the tread, as a "
                                 "share of that spin (uniform in a ball), in [0, 2]", ge=0, le=2)


class _Effects(_Table):
    """Physical effects switched on or off."""
    splash: Bool = _f(True, "rear tires launch rocks")
    recycle: Bool = _f(True, "rocks left behind by the bed are moved back in front of it")
    gravity: Bool = _f(True, "gravity acts on flying rocks")
    drag: Literal["none", "linear", "quadratic"] = _f("quadratic", "air drag model")
    ground: Literal["none", "stop", "bounce"] = _f("bounce", "what flying rocks do when they reach the ground")
    fenders: Bool = _f(True, "fenders (and mud flaps) stop stones thrown into them (tread model)")
    impacts: Bool = _f(False, "flying stones hit the bodies of the other vehicles and are recorded ([impacts])")
    tumble: Literal["auto", "always"] = _f("auto", "each rock's spin and orientation: auto tracks them for the "
                                                   "commands that draw or export them (render, view, export), "
                                                   "always also for simulate and the Python API")


# the optional effects' switches, from their declarations (config/effects/): [effects] <name>, default off
Effects = create_model("Effects", __base__=_Effects, __doc__=_Effects.__doc__,
                       **{n: (Bool, _f(False, m.SWITCH)) for n, m in EFFECTS.items()})


class Hash(_Table):
    """Spatial hash used to find the rocks under the tires."""
    insert: Literal["aabb", "center"] = _f("center", "insert each rock in every cell its box overlaps, "
                                                     "or only in its centre's cell")
    cell_size: CellSize = _f("auto", '"auto", "min_radius", "max_diameter" or a number of metres > 0')
    table_size: TableSize = _f("auto", '"auto" or the number of table slots (int >= 1)')
    reorder_every: Int = _f(64, "steps between re-sorting rocks by cell (0 = never; scope \"all\" only)", ge=0)
    scope: Literal["tires", "all"] = _f("tires", "hash only the rocks near a tire's query (same hits, less "
                                                 "work) or every rock (the full table)")


class Sim(_Table):
    """Time stepping and numerics."""
    accuracy: Literal[("custom", *PRESETS)] = _f(
        "custom", "preset of dt, integrator, detection and precision (keys set in the file win)")
    dt: Float = _f(0.002, "s, time step, in (0, 0.1]", gt=0, le=0.1)
    integrator: Literal["symplectic_euler", "heun", "rk4"] = _f("symplectic_euler", "integrator of flying rocks")
    detection: Literal["ray", "swept", "patch"] = _f("ray", "how tires find the rocks they touch (patch: the "
                                                            "tread's swept footprint)")
    substeps: Int = _f(1, "tire-ray evaluations per step (ray detection)", ge=1)
    precision: Literal["f32", "f64"] = _f("f32", "floating-point precision of the simulation")
    origin: Literal["floating", "world"] = _f("floating", "floating keeps kernel coordinates near the bed")
    stepping: Literal["active", "full"] = _f("active", "active: a step visits only the rocks something happens "
                                                       "to (resting rocks wait in ground tiles); full: every rock, "
                                                       "every step (the reference; same results)")
    hash: Hash = _f(Hash(), "spatial hash settings")


class WaypointPath(_Table):
    """A path through waypoints [x, y]."""
    kind: Literal["waypoints"] = _f("waypoints", "path kind")
    points: tuple[Vec2, ...] = _f(((0.0, 0.0), (300.0, 0.0)), "m, >= 2 points [x, y], no two consecutive equal",
                                  min_length=2)
    speed: _either(tuple[Speed, ...], Speed, _is_list) = _f(
        25.0, "m/s >= 0, or one value per point (constant acceleration between points)")
    loop: Bool = _f(False, "closed loop through the points")
    smooth: Bool = _f(True, "C2 spline through the points (false: straight segments)")
    reverse: Bool = _f(False, "drive backwards along the path")

    @model_validator(mode="after")
    def _check(self) -> WaypointPath:
        pts, n = self.points, len(self.points)
        problems = [(("points", i), f"repeats the previous point, got {_show(pts[i])}")
                    for i in range(1, n) if pts[i] == pts[i - 1]]
        if self.loop and n > 2 and pts[0] == pts[-1]:
            problems.append((("points", n - 1), "repeats the first point (a loop closes by itself)"))
        if isinstance(self.speed, tuple) and len(self.speed) != n:
            problems.append((("speed",), f"expected one speed per point ({n}), got {len(self.speed)}"))
        _raise_problems(problems)
        return self


class CirclePath(_Table):
    """A circle or circular arc."""
    kind: Literal["circle"] = _f(..., "path kind")
    center: Vec2 = _f((0.0, 0.0), "m, centre [x, y]")
    radius: Float = _f(20.0, "m, radius, at least 0.5 (tighter than any vehicle turns; the turn rate speed / radius "
                             "overflowed for radii near 1e-300)", ge=0.5)
    speed: Speed = _f(10.0, "m/s")
    clockwise: Bool = _f(False, "drive clockwise")
    start_angle: Float = _f(0.0, "deg, where the vehicle starts, counter-clockwise from +x")
    sweep: Float = _f(360.0, "deg, angle covered; < 360 is an arc", gt=0, le=360)
    loop: Bool = _f(True, "keep going round")
    reverse: Bool = _f(False, "drive backwards along the path")


MAX_LIVE_SPEED = 150.0  # m/s: a start speed or top speed above it is a unit mistake (km/h for m/s)


class LivePath(_Table):
    """A vehicle driven at run time: by the game (``Simulation.drive``) or by the keyboard (``taichi-rocks view
    --drive NAME``). Without a drive it keeps its start heading at its start speed."""
    kind: Literal["live"] = _f(..., "path kind")
    start: Vec2 = _f((0.0, 0.0), "m, where the body centre is at t = 0 [x, y]")
    heading: Float = _f(0.0, "deg, the heading at t = 0, counter-clockwise from +x")
    speed: Float = _f(0.0, "m/s, the speed at t = 0 along the heading (negative: reversing), in [-150, 150]",
                      ge=-MAX_LIVE_SPEED, le=MAX_LIVE_SPEED)
    steer_limit: Float = _f(35.0, "deg, the front wheels' steering limit when the keyboard drives (view --drive), "
                                  "in (0, 60]", gt=0, le=60)
    acceleration: Float = _f(4.0, "m/s^2, full throttle when the keyboard drives (braking: twice this), in (0, 30]",
                             gt=0, le=30)
    top_speed: Float = _f(30.0, "m/s, the top speed when the keyboard drives (reversing: a quarter of it), in "
                                "(0, 150]", gt=0, le=MAX_LIVE_SPEED)


class RecordedPath(_Table):
    """A recorded drive replayed as a scripted path (``view --record-drive`` writes one; the format:
    docs/drives.md): ``render`` and ``export`` reproduce the drive frame for frame."""
    kind: Literal["recorded"] = _f(..., "path kind")
    file: Name = _f(..., "the drive file (docs/drives.md), relative to the scene file's folder")
    _rows: tuple = PrivateAttr(())

    @property
    def rows(self) -> tuple:
        """The drive's poses: (t, x, y, heading, speed, yaw_rate, wheel_spin) tuples (NaN wheel spin: rolling)."""
        return self._rows

    @model_validator(mode="after")
    def _read(self, info: ValidationInfo) -> RecordedPath:
        base = Path((info.context or {}).get("base", "."))
        where = base / self.file
        try:
            self._rows = read_drive(where, shown=self.file if base == Path(".") else str(where))
        except DriveFileError as e:
            _raise_problems([(("file",), str(e))])
        return self


Path_ = Union[WaypointPath, CirclePath, LivePath, RecordedPath]
PATH_KINDS = {"waypoints": WaypointPath, "circle": CirclePath, "live": LivePath, "recorded": RecordedPath}


# Vehicle keys that must fit in keys before them: (that key, its share, why). A key that failed its own check
# is absent from the data a validator sees, so a bad length is reported once, not again at the wheelbase.
_FITS = {"wheelbase": [("length", 1, "")], "track": [("width", 1, "")],
         "tire_radius": [("height", 2, "the tire fits in the vehicle's height"),
                         ("wheelbase", 2, "the front and rear tires do not overlap")],
         "tire_width": [("track", 1, "the left and right tires do not overlap")],
         "contact_length": [("tire_radius", 0.5, "")]}
# Bounds above the largest wheeled vehicles (haul trucks ~8 m tall, ~10 m wide, tires ~4 m across): wrong units
MAX_BODY, MAX_TIRE_RADIUS = 100.0, 3.0
_FIT = dict(gt=0, validate_default=True)   # a size that must fit in others: its default is checked too


class Vehicle(_Table):
    """One vehicle ([[vehicle]] table)."""
    name: Name = Field(description="unique name of the vehicle")
    length: Float = _f(4.5, "m, in (0, 100]", gt=0, le=MAX_BODY)
    width: Float = _f(1.8, "m, in (0, 100]", gt=0, le=MAX_BODY)
    height: Float = _f(1.4, "m, in (0, 100]", gt=0, le=MAX_BODY)
    wheelbase: Float = _f(2.7, "m, > 0, <= length: front to rear axle", le=MAX_BODY, **_FIT)
    track: Float = _f(1.6, "m, > 0, <= width: left to right tire centre", le=MAX_BODY, **_FIT)
    tire_radius: Float = _f(0.33, "m, in (0, 3]; the diameter is <= height and <= wheelbase", le=MAX_TIRE_RADIUS,
                            **_FIT)
    tire_width: Float = _f(0.22, "m, > 0, <= track", le=MAX_BODY, **_FIT)
    contact_length: Float = _f(0.12, "m, > 0, <= 2 tire_radius: length of the contact patch", **_FIT)
    fender_angle: Float = _f(50.0, "deg up the back of the tire above which stones hit the fender", ge=0, le=180)
    mud_flaps: Bool = _f(False, "mud flaps 1.1 tire_radius behind the rear axles")
    mud_flap_clearance: Float = _f(0.10, "m, height of the mud flaps' lower edge", ge=0)
    color: Color = _f((0.8, 0.2, 0.1), 'RGB in [0, 1], or "#rrggbb"')
    kind: Literal["auto", "car", "van", "truck"] = _f("auto", "body drawn in videos; auto: from the proportions")
    splash: Bool = _f(True, "its rear tires launch rocks")
    hit: Bool = _f(True, "stones thrown by the other vehicles hit its body ([effects] impacts)")
    slip: Float = _f(0.15, "wheel spin = speed / tire_radius * (1 + slip)", ge=0)
    path: Path_ = Field(WaypointPath(), discriminator="kind", description="path of the body centre")

    @field_validator("path", mode="before")
    @classmethod
    def _default_kind(cls, v: Any) -> Any:
        return {"kind": "waypoints", **v} if isinstance(v, dict) and "kind" not in v else v

    @field_validator(*_FITS)
    @classmethod
    def _fits(cls, value: float, info: ValidationInfo) -> float:
        for limit, share, why in _FITS[info.field_name]:
            if limit in info.data and value > info.data[limit] / share:
                scale = f" / {share:g}" if share > 1 else (f" * {1 / share:g}" if share < 1 else "")
                bound = limit + scale + f" ({info.data[limit] / share:g})"
                default = " (the default)" if value == cls.model_fields[info.field_name].default else ""
                raise ValueError(f"must be <= {bound}" + (f" so that {why}" if why else "") + f", got {value:g}"
                                 + default)
        return value


CAMERA_VIEWS = ("chase", "side", "low", "orbit", "driver", "bonnet")
_VIEW_WORDS = ("chase: behind and above the followed vehicle; driver (its driver's eye behind the windscreen), "
               "bonnet (a camera on its bonnet): ride with follow; side (beside the target, at its rear tires), "
               "low (low, behind and to the left of its rear tires), orbit (circling it): ride with the target")


class Shot(_Table):
    """One shot of the camera ([[camera.shot]]): from ``at`` until the next shot, the camera is this view (a cut:
    the camera does not glide from the shot before)."""
    at: Float = _f(..., "s, >= 0, when the shot starts; each shot's at is larger than the one before", ge=0)
    view: Literal[CAMERA_VIEWS] = _f(..., _VIEW_WORDS)
    follow: Optional[Name] = _f(None, "vehicle the chase, driver and bonnet views ride with; default: "
                                      "camera.follow")
    target: Optional[Name] = _f(None, "vehicle the camera looks at (side, low, orbit: and rides with); default: "
                                      "camera.target, else follow")
    offset: Optional[Vec3] = _f(None, "m, the eye in the frame of the vehicle the camera rides with (x forward, "
                                      "y left, z up); default: the view's")
    aim: Optional[Vec3] = _f(None, "m, the point looked at, in the target's frame (chase, driver, bonnet: in the "
                                   "frame of the vehicle ridden with); default: the view's")


class CameraSettings(_Table):
    """The camera of rendered videos: a view preset, the vehicles it rides with and looks at, and the shots."""
    model_config = ConfigDict(title="Camera")  # the [camera] table; its rig: motion/camera.py CameraRig
    view: Literal[CAMERA_VIEWS] = _f("chase", _VIEW_WORDS + "; before the first shot")
    follow: Optional[Name] = _follow("vehicle the chase, driver and bonnet views ride with; default: bed.follow")
    target: Optional[Name] = _f(None, "vehicle the camera looks at (side, low, orbit: and rides with); "
                                      "default: follow")
    offset: Optional[Vec3] = _f(None, "m, the eye in the frame of the vehicle the camera rides with (x forward, "
                                      "y left, z up); default: the view's")
    aim: Optional[Vec3] = _f(None, "m, the point looked at, in the target's frame (chase, driver, bonnet: in the "
                                   "frame of the vehicle ridden with); default: the view's (chase: look_ahead "
                                   "metres ahead)")
    look_ahead: Float = _f(6.0, "m ahead of the vehicle the chase camera looks at")
    orbit_period: Float = _f(20.0, "s, one turn of the orbit view", gt=0)
    fov: Float = _f(50.0, "deg, field of view, in (0, 180)", gt=0, lt=180)
    smoothing: Float = _f(0.3, "s, time constant of the camera's follow", ge=0)
    shots: tuple[Shot, ...] = Field((), alias="shot", description="cuts within one video ([[camera.shot]] tables, "
                                                                  "in increasing at); before the first, the view "
                                                                  "above")

    @model_validator(mode="after")
    def _shots_in_order(self) -> CameraSettings:
        _raise_problems([(("shot", i, "at"), f"must be > the previous shot's at ({self.shots[i - 1].at:g}), "
                                             f"got {self.shots[i].at:g}")
                         for i in range(1, len(self.shots)) if not self.shots[i].at > self.shots[i - 1].at])
        return self


class SunAngles(_Table):
    """A direction towards the sun by its angles."""
    azimuth: Float = _f(129.3, "deg, counter-clockwise from +x (the sun's frame, see sun_frame)")
    elevation: Float = _f(54.6, "deg above the horizon, in (0, 90]", gt=0, le=90)


class Render(_Table):
    """Video output."""
    resolution: tuple[Pixels, Pixels] = _f((1280, 720), f"[width, height], even ints >= {MIN_SIDE}")
    fps: Float = _f(30.0, "frames per second of simulated time", gt=0)
    quality: Int = _f(27, "H.264 constant rate factor of the MP4 (x264 superfast), 0 (lossless) to 51 "
                          "(smallest): +6 about halves the size; 27: ~0.9 MB/s at 720p", ge=0, le=51)
    background: Color = _f((0.62, 0.76, 0.92), 'sky RGB in [0, 1], or "#rrggbb"')
    draw_distance: Float = _f(80.0, "m", gt=0)
    ground_tile: Float = _f(2.0, "m, checker size of the ground", gt=0)
    sun: _either(Vec3, SunAngles, _is_list) = _f(
        (-0.45, 0.55, 1.0), "direction towards the sun: [x, y, z] (z > 0) or {azimuth, elevation} in degrees")
    sun_frame: Literal["vehicle", "world"] = _f(
        "vehicle", "frame of sun: the heading frame of the vehicle the camera rides with (x forward, y left; "
                   "smoothed like the camera, so the light keeps its side in turns) or the world's")
    shadows: Bool = _f(True, "flying rocks and vehicles cast shadows on the ground; resting rocks darken it")
    bed_edge: Bool = _f(False, "debug overlay: the bed's edge circle")
    tire_rays: Bool = _f(False, "debug overlay: the tire rays")
    hash_cells: Bool = _f(False, "debug overlay: hash cells queried this frame")

    @field_validator("sun")
    @classmethod
    def _sun_up(cls, v: Any) -> Any:
        if isinstance(v, tuple) and not v[2] > 0:
            raise ValueError(f"must point up (z > 0), got {_show(v)}")
        return v


class _Scene(_Table):
    """A taichi-rocks scene: a bed of rocks following a vehicle, and vehicles whose rear tires throw rocks.
    SI units, world Z up, angles in degrees."""
    name: Name = _f("scene", "scene name; defaults to the file stem")
    duration: Float = _f(10.0, "s of simulated time", gt=0)
    seed: Int = _f(1, "random seed", ge=0, le=SEED_MAX)
    world: Environment = _f(Environment(), Environment.__doc__)
    bed: Bed = _f(Bed(), Bed.__doc__)
    launch: Launch = _f(Launch(), Launch.__doc__)
    effects: Effects = _f(Effects(), Effects.__doc__)
    impacts: Impacts = _f(Impacts(), Impacts.__doc__)
    sim: Sim = _f(Sim(), Sim.__doc__)
    vehicles: tuple[Vehicle, ...] = Field(alias="vehicle", min_length=1,
                                          description="the vehicles ([[vehicle]] tables), at least one")
    camera: CameraSettings = _f(CameraSettings(), CameraSettings.__doc__)
    render: Render = _f(Render(), Render.__doc__)
    _source: str = PrivateAttr("<scene>")

    @property
    def source(self) -> str:
        """The file the scene came from, or "<scene>"."""
        return self._source

    @model_validator(mode="after")
    def _shots_in_the_scene(self) -> Scene:
        _raise_problems([(("camera", "shot", i, "at"), f"must be < duration ({self.duration:g}): a shot that starts "
                                                       f"after the end is never seen, got {shot.at:g}")
                         for i, shot in enumerate(self.camera.shots) if not shot.at < self.duration])
        return self

    @model_validator(mode="after")
    def _steps_in_reach(self) -> Scene:
        """At most MAX_STEPS steps (config/limits.py): ``duration`` is to blame when even the default dt takes
        too many, else ``sim.dt``."""
        if self.duration / self.sim.dt > MAX_STEPS:
            blame_duration = self.duration / Sim().dt > MAX_STEPS
            got = f"{self.duration:g}" if blame_duration else f"{self.sim.dt:g}"
            _raise_problems([(("duration",) if blame_duration else ("sim", "dt"),
                              f"{self.duration:g} s of simulated time are {steps_estimate(self.duration, self.sim.dt)}"
                              f", got {got}")])
        return self

    def vehicle_index(self, name: str) -> int:
        for i, v in enumerate(self.vehicles):
            if v.name == name:
                return i
        raise KeyError(f"no vehicle named {name!r} in scene {self.name!r}")

    def vehicle(self, name: str) -> Vehicle:
        return self.vehicles[self.vehicle_index(name)]


# the optional effects' tables, from their declarations (config/effects/): [<name>]
Scene = create_model("Scene", __base__=_Scene, __doc__=_Scene.__doc__,
                     **{n: (m.Table, _f(m.Table(), m.Table.__doc__)) for n, m in EFFECTS.items()})


# tables by the key that holds them (or the path kind), to list the keys allowed where an unknown one is found
_TABLES: dict[str, type[BaseModel]] = {
    "world": Environment, "bed": Bed, "launch": Launch, "effects": Effects, "impacts": Impacts, "sim": Sim, "hash": Hash,
    "vehicle": Vehicle, "camera": CameraSettings, "shot": Shot, "render": Render, "sun": SunAngles, **PATH_KINDS,
    **{n: m.Table for n, m in EFFECTS.items()}}
_TAGS = {"@a", "@b", *PATH_KINDS}   # union-member labels pydantic puts in error locations

