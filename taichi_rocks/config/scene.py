"""Scene files: the TOML format of docs/scene-format.md, as frozen pydantic models.

One set of models is both the validator and the source of the JSON Schema (:func:`scene_json_schema`).
Every problem in a file is reported at once, as a :class:`SceneError` whose lines read
``FILE: key.path: what was expected, got X``. This module knows nothing of Taichi.

The parts: config/values.py (value types), config/models.py (the tables), config/messages.py (problems in
words); this module loads, checks across tables, derives (:func:`scene_with`) and is the face the other rooms
import from: ``from taichi_rocks.config.scene import Scene, load_scene, ...``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Union

from pydantic import ValidationError

from .messages import _key_path, _line, _messages, _unknown
from .models import (CAMERA_VIEWS, PATH_KINDS, Bed, CameraSettings, CirclePath, Effects, Environment, Hash, Launch,
                     Render, Scene, Shot, Sim, SunAngles, Vehicle, WaypointPath)
from .presets import PRESETS
from .summary import summarise
from .tomltext import read_toml
from .values import _is_list, _show, dumped

__all__ = ["SceneError", "Scene", "load_scene", "parse_scene", "scene_with", "scene_to_dict", "shipped_scene",
           "scene_json_schema", "summarise", "Environment", "Bed", "Launch", "Effects", "Hash",
           "Sim", "WaypointPath", "CirclePath", "PATH_KINDS", "Vehicle", "CAMERA_VIEWS", "CameraSettings", "Shot",
           "SunAngles", "Render", "PRESETS"]


class SceneError(ValueError):
    """A scene that cannot be used; ``problems`` holds one ``FILE: key.path: message`` line per problem. A
    ValueError: what the Python API raises for a bad argument, here the scene (each line names its key)."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


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
        for loc, follow in _vehicle_keys(data):
            if isinstance(follow, str) and follow not in seen:
                problems.append((loc, _unknown("vehicle", follow, list(seen))))
    return problems


def _vehicle_keys(data: dict) -> list[tuple[tuple, object]]:
    """(location, value) of every key the user wrote that names a vehicle: bed.follow, camera.follow and
    camera.target, and each camera shot's follow and target."""
    found = []
    for table, key in (("bed", "follow"), ("camera", "follow"), ("camera", "target")):
        if isinstance(data.get(table), dict) and key in data[table]:
            found.append(((table, key), data[table][key]))
    shots = data["camera"].get("shot") if isinstance(data.get("camera"), dict) else None
    for i, shot in enumerate(shots if _is_list(shots) else ()):
        for key in ("follow", "target"):
            if isinstance(shot, dict) and key in shot:
                found.append((("camera", "shot", i, key), shot[key]))
    return found


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
    if problems:
        raise SceneError([_line(source, loc, msg) for loc, msg in problems])
    scene._source = source
    return scene


def load_scene(path: Union[str, os.PathLike]) -> Scene:
    """Read and validate a scene file (docs/scene-format.md).

    Args:
        path: the scene file (TOML, UTF-8; a leading byte-order mark is ignored).

    Returns:
        The validated, frozen Scene; its name defaults to the file stem.

    Raises:
        SceneError: the file cannot be read, is not TOML, or holds bad keys or values (one line per problem,
            naming the file and the key).
    """
    source = str(path)
    data = read_toml(path, "scene", SceneError)
    return parse_scene(data, source, Path(path).stem)


SCENES = Path(__file__).resolve().parents[2] / "scenes"  # the shipped scenes, beside the package in its repository


def shipped_scene(name: str) -> Path:
    """The file of a scene that ships with taichi_rocks (its repository's scenes/ folder), wherever the caller
    runs: ``load_scene(shipped_scene("convoy"))`` reads scenes/convoy.toml from any folder.

    Args:
        name: the scene's name, the file's stem ("convoy", "minimal", ...).

    Returns:
        The scene file's absolute path.

    Raises:
        ValueError: no shipped scene of that name (the message lists them).
    """
    path = SCENES / f"{name}.toml"
    if not isinstance(name, str) or "/" in name or not path.is_file():
        known = sorted(p.stem for p in SCENES.glob("*.toml"))
        raise ValueError(f"name: no shipped scene {name!r} in {SCENES}" +
                         (f"; the shipped scenes: {', '.join(known)}" if known else ""))
    return path


# ---------------------------------------------------------------------------------------------- derived
def scene_to_dict(scene: Scene) -> dict:
    """The scene as a TOML-like dict with every key filled in (lists, file key names); parse_scene reads it back."""
    return dumped(scene, mode="json", by_alias=True)  # an interrupt inside pydantic's dump is not lost


_PART = re.compile(r"([A-Za-z_][\w-]*)((?:\[\d+\])*)")


def scene_with(scene: Scene, overrides: dict) -> Scene:
    """A re-validated copy of ``scene`` with dotted-key overrides (file key names).

    E.g. ``scene_with(s, {"sim.dt": 0.01, "vehicle[0].path.speed": 5.0})``; raises SceneError (one line) on a
    key that is not a key path, an index past a list's end ("no such item"), a key below a value that is not a
    table ("not inside a table") and on invalid values.
    Keys that default from others (bed.follow, camera.follow) keep their resolved values. An override of
    ``sim.accuracy`` with a preset's name applies that preset's keys, as the file key does (keys given in the
    same overrides win): ``scene_with(s, {"sim.accuracy": "game"})`` steps once per 60 Hz frame.

    Args:
        scene: the Scene to start from (it is not changed).
        overrides: {dotted key: value}, file key names ("vehicle[0].path.speed", "sim.accuracy").

    Returns:
        A new, validated Scene.

    Raises:
        TypeError: ``overrides`` is not a dict, or a key of it is not a string.
        SceneError: a bad key path or value (one line per problem).
    """
    if not isinstance(overrides, Mapping):
        raise TypeError(f"overrides must be a dict of dotted keys and values, like {{\"sim.dt\": 0.01}}, got "
                        f"{type(overrides).__name__}")
    for key in overrides:
        if not isinstance(key, str):
            raise TypeError(f"overrides: each key must be a dotted key path (a string) like \"sim.dt\", got {key!r}")
    overrides = {key: _plain(value) for key, value in overrides.items()}
    data = scene_to_dict(scene)
    preset = overrides.get("sim.accuracy")
    if isinstance(preset, str) and preset in PRESETS:
        data["sim"] = {**data.get("sim", {}), **PRESETS[preset]}
    for key, value in overrides.items():
        steps: list = []
        for part in key.split("."):
            m = _PART.fullmatch(part)
            if not m:
                raise SceneError([f"{scene.source}: {key}: not a key path like sim.dt or vehicle[0].path.speed"])
            steps += [m[1]] + [int(i) for i in re.findall(r"\d+", m[2])]
        node = data
        for i, step in enumerate(steps):
            # every step is checked, the last too: a key below a number or a list is refused, not a TypeError
            if isinstance(step, int) and not (_is_list(node) and step < len(node)):
                raise SceneError([f"{scene.source}: {_key_path(tuple(steps[:i + 1]))}: no such item"])
            if not isinstance(step, int) and not isinstance(node, dict):
                raise SceneError([f"{scene.source}: {_key_path(tuple(steps[:i + 1]))}: not inside a table"])
            if i == len(steps) - 1:
                node[step] = value
            else:
                node = node[step] if isinstance(step, int) else node.setdefault(step, {})
    return parse_scene(data, scene.source, scene.name)


def _plain(value):
    """``value`` with NumPy's numbers and arrays as the Python numbers and lists a TOML file gives (a scene's
    integer key takes ``np.int64(100)`` as it takes 100; no NumPy import here: they are known by ``tolist``)."""
    if type(value).__module__ == "numpy" and callable(getattr(value, "tolist", None)):
        value = value.tolist()
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def scene_json_schema() -> dict:
    """JSON Schema (draft 2020-12) of a scene file, with defaults, ranges and enums."""
    schema = _defs_by_title(Scene.model_json_schema(by_alias=True))
    schema.pop("title", None)
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": "taichi-rocks scene", **schema}


def _defs_by_title(schema: dict) -> dict:
    """Definitions named by their table's title, not the Python class (the [world] table's model is Environment,
    its definition "World"), in alphabetical order, the references following."""
    rename = {k: d.get("title", k) for k, d in schema.get("$defs", {}).items()}
    prefix = "#/$defs/"

    def walk(node):
        if isinstance(node, dict):
            return {k: (prefix + rename[v[len(prefix):]] if k == "$ref" and isinstance(v, str) and
                        v.startswith(prefix) else walk(v)) for k, v in node.items()}
        if isinstance(node, list):
            return [walk(v) for v in node]
        return node

    out = walk({k: v for k, v in schema.items() if k != "$defs"})
    if "$defs" in schema:
        defs = {rename[k]: walk(v) for k, v in schema["$defs"].items()}
        out = {"$defs": dict(sorted(defs.items())), **out}
    return out
