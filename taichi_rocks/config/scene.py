"""Scene files: the TOML format of docs/scene-format.md, as frozen pydantic models.

One set of models is both the validator and the source of the JSON Schema (:func:`scene_json_schema`).
Every problem in a file is reported at once, as a :class:`SceneError` whose lines read
``FILE: key.path: what was expected, got X``. This module knows nothing of Taichi.
"""

from __future__ import annotations

import difflib
import json
import os
import re
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import (AfterValidator, BaseModel, ConfigDict, Discriminator, Field, PrivateAttr, Strict, Tag,
                      ValidationError, ValidationInfo, field_validator, model_validator)
from pydantic_core import PydanticCustomError

from .impacts import Impacts
from .presets import PRESETS
from .resolution import MIN_SIDE, SIDE_MULTIPLE
from .summary import estimate_memory, physical_memory, summarise
from .tomltext import TomlTextError, loads as toml_loads

__all__ = ["SceneError", "Scene", "load_scene", "parse_scene", "scene_with", "scene_to_dict",
           "scene_json_schema", "estimate_memory", "summarise"]


class SceneError(Exception):
    """A scene that cannot be used; ``problems`` holds one ``FILE: key.path: message`` line per problem."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


# ---------------------------------------------------------------------------------------------- value types
# Strict leaves: no bool-as-number, no number-as-string; ints are still accepted where floats are expected.
Float = Annotated[float, Strict()]
Int = Annotated[int, Strict()]
Bool = Annotated[bool, Strict()]
Name = Annotated[str, Strict(), Field(min_length=1)]
Vec2 = tuple[Float, Float]
Vec3 = tuple[Float, Float, Float]


def _f(default: Any, description: str, **constraints) -> Any:
    return Field(default, description=description, **constraints)


def _ordered(pair: tuple[float, float]) -> tuple[float, float]:
    if pair[0] > pair[1]:
        raise ValueError(f"min must be <= max, got {_show(pair)}")
    return pair


def Range(**bounds) -> Any:
    """A [min, max] pair: each value within ``bounds`` (ge/gt/le), and min <= max."""
    item = Annotated[float, Strict(), Field(**bounds)]
    return Annotated[tuple[item, item], AfterValidator(_ordered)]


def _either(a: Any, b: Any, pick_a) -> Any:
    """A union that picks its member by the input's type, so a bad value gets one error, not one per member."""
    return Annotated[Union[Annotated[a, Tag("@a")], Annotated[b, Tag("@b")]],
                     Discriminator(lambda v: "@a" if pick_a(v) else "@b")]


def _is_str(v: Any) -> bool:
    return isinstance(v, str)


def _is_list(v: Any) -> bool:
    return isinstance(v, (list, tuple))


HEX_COLOR = r"^#[0-9a-fA-F]{6}$"
Unit = Annotated[float, Strict(), Field(ge=0, le=1)]
HexColor = Annotated[str, Strict(), Field(pattern=HEX_COLOR),
                     AfterValidator(lambda s: tuple(int(s[i:i + 2], 16) / 255 for i in (1, 3, 5)))]
Color = _either(HexColor, tuple[Unit, Unit, Unit], _is_str)   # always a tuple of 3 floats once validated
Speed = Annotated[float, Strict(), Field(ge=0)]
CellSize = _either(Literal["auto", "min_radius", "max_diameter"], Annotated[float, Strict(), Field(gt=0)], _is_str)
TableSize = _either(Literal["auto"], Annotated[int, Strict(), Field(ge=1)], _is_str)
Pixels = Annotated[int, Strict(), Field(ge=MIN_SIDE, multiple_of=SIDE_MULTIPLE)]


def _vehicle_name_schema(schema: dict) -> None:
    schema.pop("default", None)
    schema.pop("anyOf", None)
    schema.update(type="string", minLength=1)


def _follow(description: str) -> Any:
    return Field(None, description=description, json_schema_extra=_vehicle_name_schema)


def _raise_problems(problems: list[tuple[tuple, str]]) -> None:
    """Report several cross-field problems of one table at once; locations are relative to the table."""
    if problems:
        raise PydanticCustomError("scene_checks", "{problems}", {"problems": problems})


# ---------------------------------------------------------------------------------------------- the models
class _Table(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class World(_Table):
    """Physical constants of the world (Z up)."""
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
    """How the rear tires throw rocks (README, "The throw")."""
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


class Effects(_Table):
    """Physical effects switched on or off."""
    splash: Bool = _f(True, "rear tires launch rocks")
    recycle: Bool = _f(True, "rocks left behind by the bed are moved back in front of it")
    gravity: Bool = _f(True, "gravity acts on flying rocks")
    drag: Literal["none", "linear", "quadratic"] = _f("quadratic", "air drag model")
    ground: Literal["none", "stop", "bounce"] = _f("bounce", "what flying rocks do when they reach the ground")
    fenders: Bool = _f(True, "fenders (and mud flaps) stop stones thrown into them (tread model)")
    impacts: Bool = _f(False, "flying stones hit the bodies of the other vehicles and are recorded ([impacts])")


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
    accuracy: Literal["custom", "draft", "balanced", "reference"] = _f(
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
    radius: Float = _f(20.0, "m, radius", gt=0)
    speed: Speed = _f(10.0, "m/s")
    clockwise: Bool = _f(False, "drive clockwise")
    start_angle: Float = _f(0.0, "deg, where the vehicle starts, counter-clockwise from +x")
    sweep: Float = _f(360.0, "deg, angle covered; < 360 is an arc", gt=0, le=360)
    loop: Bool = _f(True, "keep going round")
    reverse: Bool = _f(False, "drive backwards along the path")


Path_ = Union[WaypointPath, CirclePath]
PATH_KINDS = {"waypoints": WaypointPath, "circle": CirclePath}


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


CAMERA_VIEWS = ("chase", "side", "low", "orbit")


class Camera(_Table):
    """The camera of rendered videos: a view preset, the vehicles it rides with and looks at."""
    view: Literal[CAMERA_VIEWS] = _f("chase", "chase: behind and above the followed vehicle; side (beside the "
                                              "target, at its rear tires), low (low, behind and to the left of "
                                              "its rear tires), orbit (circling it): ride with the target")
    follow: Optional[Name] = _follow("vehicle the chase camera rides with; default: bed.follow")
    target: Optional[Name] = _f(None, "vehicle the camera looks at (side, low, orbit: and rides with); "
                                      "default: follow")
    offset: Optional[Vec3] = _f(None, "m, the eye in the frame of the vehicle the camera rides with (x forward, "
                                      "y left, z up); default: the view's")
    aim: Optional[Vec3] = _f(None, "m, the point looked at, in the target's frame; default: the view's "
                                   "(chase: look_ahead metres ahead)")
    look_ahead: Float = _f(6.0, "m ahead of the vehicle the chase camera looks at")
    orbit_period: Float = _f(20.0, "s, one turn of the orbit view", gt=0)
    fov: Float = _f(50.0, "deg, field of view, in (0, 180)", gt=0, lt=180)
    smoothing: Float = _f(0.3, "s, time constant of the camera's follow", ge=0)


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


class Scene(_Table):
    """A taichi-rocks scene: a bed of rocks following a vehicle, and vehicles whose rear tires throw rocks.
    SI units, world Z up, angles in degrees."""
    name: Name = _f("scene", "scene name; defaults to the file stem")
    duration: Float = _f(10.0, "s of simulated time", gt=0)
    seed: Int = _f(1, "random seed", ge=0)
    world: World = _f(World(), World.__doc__)
    bed: Bed = _f(Bed(), Bed.__doc__)
    launch: Launch = _f(Launch(), Launch.__doc__)
    effects: Effects = _f(Effects(), Effects.__doc__)
    impacts: Impacts = _f(Impacts(), Impacts.__doc__)
    sim: Sim = _f(Sim(), Sim.__doc__)
    vehicles: tuple[Vehicle, ...] = Field(alias="vehicle", min_length=1,
                                          description="the vehicles ([[vehicle]] tables), at least one")
    camera: Camera = _f(Camera(), Camera.__doc__)
    render: Render = _f(Render(), Render.__doc__)
    _source: str = PrivateAttr("<scene>")

    @property
    def source(self) -> str:
        """The file the scene came from, or "<scene>"."""
        return self._source

    def vehicle_index(self, name: str) -> int:
        for i, v in enumerate(self.vehicles):
            if v.name == name:
                return i
        raise KeyError(f"no vehicle named {name!r} in scene {self.name!r}")

    def vehicle(self, name: str) -> Vehicle:
        return self.vehicles[self.vehicle_index(name)]


# tables by the key that holds them (or the path kind), to list the keys allowed where an unknown one is found
_TABLES: dict[str, type[BaseModel]] = {
    "world": World, "bed": Bed, "launch": Launch, "effects": Effects, "impacts": Impacts, "sim": Sim, "hash": Hash,
    "vehicle": Vehicle, "camera": Camera, "render": Render, "sun": SunAngles, **PATH_KINDS}
_TAGS = {"@a", "@b", *PATH_KINDS}   # union-member labels pydantic puts in error locations


# ---------------------------------------------------------------------------------------------- messages
def _show(v: Any, room: int = 60) -> str:
    """A value as the user wrote it (TOML-ish); a list is cut to ``room`` characters, looking only at what fits."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, (list, tuple)):
        text = "["
        for i, x in enumerate(v):
            if len(text) > room:
                break
            text += (", " if i else "") + _show(x, room - len(text) - 2 * bool(i))
        text += "]"
        return text if len(text) <= room else text[:max(room - 4, 0)] + " ...]"
    return "nothing" if v is None else str(v)


def _num(x: Any) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _unknown(what: str, value: Any, choices: list[str], list_all: bool = True) -> str:
    msg = f"unknown {what} {_show(value)}"
    close = difflib.get_close_matches(value, choices, n=1) if isinstance(value, str) else []
    if close:
        msg += f', did you mean "{close[0]}"?'
    if list_all or not close:
        msg += " (expected one of " + ", ".join(f'"{c}"' for c in choices) + ")"
    return msg


def _choices(expected: str) -> list[str]:
    return re.findall(r"'([^']*)'", expected)


_SIMPLE = {   # pydantic error type -> what was expected
    "float_type": "expected a number", "float_parsing": "expected a number",
    "int_type": "expected an integer", "int_parsing": "expected an integer", "int_from_float": "expected an integer",
    "bool_type": "expected true or false", "bool_parsing": "expected true or false",
    "string_type": "expected a string", "string_too_short": "must not be empty",
    "model_type": "expected a table", "model_attributes_type": "expected a table", "dict_type": "expected a table",
    "tuple_type": "expected a list", "list_type": "expected a list",
    "finite_number": "must be finite",
    "greater_than": "must be > {gt}", "greater_than_equal": "must be >= {ge}",
    "less_than": "must be < {lt}", "less_than_equal": "must be <= {le}",
    "multiple_of": "must be a multiple of {multiple_of}",
    "too_short": "expected at least {min_length} items", "too_long": "expected at most {max_length} items",
    "string_pattern_mismatch": 'expected a "#rrggbb" colour',
}


def _messages(err: dict) -> list[tuple[tuple, str]]:
    """One pydantic error as (location, human message) pairs; [] for errors that only echo another one."""
    kind, loc, ctx, value = err["type"], tuple(err["loc"]), err.get("ctx") or {}, err.get("input")
    got = f", got {_show(value)}"
    if kind == "scene_checks":
        return [(loc + tuple(sub), msg) for sub, msg in ctx["problems"]]
    if kind == "too_short" and _is_list(value) and len(value) >= ctx["min_length"]:
        return []   # pydantic adds this after an item failed; the item's own error says what is wrong
    if loc == ("vehicle",) and kind in ("missing", "too_short", "tuple_type"):
        return [(loc, "at least one [[vehicle]] table is required" + (got if kind == "tuple_type" else ""))]
    if kind == "extra_forbidden":
        parent = next((x for x in reversed(loc[:-1]) if x in _TABLES), None)
        model = _TABLES.get(parent, Scene)
        keys = [f.alias or k for k, f in model.model_fields.items()]
        return [(loc, _unknown("key", loc[-1], keys, list_all=False))]
    if kind == "missing":
        if isinstance(loc[-1], int):
            return [(loc[:-1], f"too few items{got}")]
        return [(loc, "required key is missing")]
    if kind == "literal_error":
        choices = _choices(ctx["expected"])
        if isinstance(value, str):
            return [(loc, _unknown("value", value, choices))]
        return [(loc, "expected one of " + ", ".join(f'"{c}"' for c in choices) + got)]
    if kind == "union_tag_invalid":
        key = ctx["discriminator"].strip("'")
        return [(loc + (key,), _unknown("value", ctx["tag"], _choices(ctx["expected_tags"])))]
    if kind == "multiple_of" and ctx.get("multiple_of") == SIDE_MULTIPLE:
        return [(loc, "must be even" + got)]
    if kind in _SIMPLE:
        return [(loc, _SIMPLE[kind].format(**{k: _num(v) for k, v in ctx.items()}) + got)]
    if kind == "value_error":   # raised by our own validators, already in the house style
        return [(loc, err["msg"].removeprefix("Value error, "))]
    return [(loc, err["msg"][:1].lower() + err["msg"][1:] + got)]


def _key_path(loc: tuple) -> str:
    out = ""
    for item in loc:
        if isinstance(item, int):
            out += f"[{item}]"
        elif item not in _TAGS:
            out += ("." if out else "") + str(item)
    return out


def _line(source: str, loc: tuple, msg: str) -> str:
    path = _key_path(loc)
    return f"{source}: {path}: {msg}" if path else f"{source}: {msg}"


# ---------------------------------------------------------------------------------------------- loading
def _with_defaults(data: dict, default_name: str) -> dict:
    """Fill in the defaults that depend on other keys: name, bed.follow, camera.follow, accuracy presets."""
    data = {"name": default_name, **data}
    sim = data.get("sim")
    if isinstance(sim, dict) and sim.get("accuracy") in PRESETS:
        data["sim"] = {**PRESETS[sim["accuracy"]], **sim}
    vehicles = data.get("vehicle")
    first = vehicles[0] if _is_list(vehicles) and vehicles else None
    follow = first.get("name") if isinstance(first, dict) else None
    for table in ("bed", "camera"):
        given = data.get(table, {})
        if not isinstance(given, dict):
            break
        if "follow" not in given and isinstance(follow, str):
            data[table] = {**given, "follow": follow}
        follow = data.get(table, {}).get("follow")
    return data


def _name_problems(data: dict) -> list[tuple[tuple, str]]:
    """Vehicle names: unique, and the follow keys the user wrote name one of them."""
    vehicles = data.get("vehicle")
    names = [v.get("name") if isinstance(v, dict) else None for v in vehicles] if _is_list(vehicles) else []
    problems, seen = [], {}
    for i, name in enumerate(names):
        if isinstance(name, str) and name in seen:
            problems.append((("vehicle", i, "name"), f"duplicate vehicle name {_show(name)} "
                                                     f"(already used by vehicle[{seen[name]}])"))
        elif isinstance(name, str):
            seen[name] = i
    if names and all(isinstance(n, str) for n in names):
        for table, key in (("bed", "follow"), ("camera", "follow"), ("camera", "target")):
            follow = data[table].get(key) if isinstance(data.get(table), dict) else None
            if isinstance(follow, str) and follow not in seen:
                problems.append(((table, key), _unknown("vehicle", follow, list(seen))))
    return problems


def parse_scene(data: dict, source: str = "<scene>", default_name: str = "scene") -> Scene:
    """Validate a scene given as the dict of a parsed TOML file; raise SceneError listing every problem."""
    if not isinstance(data, dict):
        raise SceneError([f"{source}: expected a table, got {_show(data)}"])
    problems = _name_problems(data)
    scene = None
    try:
        try:
            scene = Scene.model_validate(_with_defaults(data, default_name))
        except ValidationError as e:
            problems = [p for err in e.errors() for p in _messages(err)] + problems
    except RecursionError:   # not seen: validating goes as deep as the models, _show as deep as it prints
        raise SceneError([f"{source}: lists and tables nested too deeply to check"]) from None
    if scene is not None:
        need, have = estimate_memory(scene), physical_memory()
        if have and need > have:
            problems.append((("bed", "rocks"), f"needs about {need / 1e9:.1f} GB of memory, more than this machine "
                                               f"has ({have / 1e9:.1f} GB), got {scene.bed.rocks}"))
    if problems:
        raise SceneError([_line(source, loc, msg) for loc, msg in problems])
    scene._source = source
    return scene


def load_scene(path: Union[str, os.PathLike]) -> Scene:
    """Read and validate a scene file; its name defaults to the file stem."""
    source = str(path)
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except OSError as e:
        raise SceneError([f"{source}: cannot read scene: {e.strerror or e}"]) from None
    except UnicodeDecodeError as e:
        raise SceneError([f"{source}: cannot read scene: not UTF-8 text ({e.reason} at byte {e.start})"]) from None
    try:
        data = toml_loads(text)
    except TomlTextError as e:
        raise SceneError([f"{source}: {e}"]) from None
    return parse_scene(data, source, Path(path).stem)


# ---------------------------------------------------------------------------------------------- derived
def scene_to_dict(scene: Scene) -> dict:
    """The scene as a TOML-like dict with every key filled in (lists, file key names); parse_scene reads it back."""
    return scene.model_dump(mode="json", by_alias=True)


_PART = re.compile(r"([A-Za-z_][\w-]*)((?:\[\d+\])*)")


def scene_with(scene: Scene, overrides: dict) -> Scene:
    """A re-validated copy of ``scene`` with dotted-key overrides (file key names).

    E.g. ``scene_with(s, {"sim.dt": 0.01, "vehicle[0].path.speed": 5.0})``; raises SceneError on invalid values.
    Keys that default from others (bed.follow, camera.follow) keep their resolved values.
    """
    data = scene_to_dict(scene)
    for key, value in overrides.items():
        steps: list = []
        for part in key.split("."):
            m = _PART.fullmatch(part)
            if not m:
                raise SceneError([f"{scene.source}: {key}: not a key path like sim.dt or vehicle[0].path.speed"])
            steps += [m[1]] + [int(i) for i in re.findall(r"\d+", m[2])]
        node = data
        for i, step in enumerate(steps[:-1]):
            if isinstance(step, int):
                if not (_is_list(node) and step < len(node)):
                    raise SceneError([f"{scene.source}: {_key_path(tuple(steps[:i + 1]))}: no such item"])
                node = node[step]
            elif isinstance(node, dict):
                node = node.setdefault(step, {})
            else:
                raise SceneError([f"{scene.source}: {_key_path(tuple(steps[:i + 1]))}: not inside a table"])
        if isinstance(steps[-1], int) and not (_is_list(node) and steps[-1] < len(node)):
            raise SceneError([f"{scene.source}: {key}: no such item"])
        node[steps[-1]] = value
    return parse_scene(data, scene.source, scene.name)


def scene_json_schema() -> dict:
    """JSON Schema (draft 2020-12) of a scene file, with defaults, ranges and enums."""
    schema = Scene.model_json_schema(by_alias=True)
    schema.pop("title", None)
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": "taichi-rocks scene", **schema}
