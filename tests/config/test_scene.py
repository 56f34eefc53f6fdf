"""Scene files: shipped scenes, defaults, round trip, JSON Schema and the error messages of bad files.

Each file in tests/bad_scenes/ starts with ``# expect: <key.path> | <phrase>``; adding a case is adding a file.
"""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from taichi_rocks.config.scene import (Scene, SceneError, load_scene, parse_scene, scene_json_schema,
                                scene_to_dict, scene_with, summarise)
from taichi_rocks.engine.layout import check_machine

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted((ROOT / "scenes").glob("*.toml"))
BAD = sorted((ROOT / "tests" / "bad_scenes").glob("*.toml"))
CAR = {"name": "car"}


def problems_of(fn, *args) -> list[str]:
    with pytest.raises(SceneError) as info:
        fn(*args)
    assert str(info.value) == "\n".join(info.value.problems)
    return info.value.problems


def test_scene_module_does_not_import_taichi():
    code = "import sys, taichi_rocks.config.scene; assert 'taichi' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_shipped_scenes():
    assert {p.stem for p in SCENES} >= {"convoy", "slalom", "circle", "minimal"}
    for path in SCENES:
        scene = load_scene(path)
        assert scene.name == path.stem and scene.source == str(path)
        assert scene.bed.follow == scene.camera.follow == scene.vehicles[0].name
        assert "rocks" in summarise(scene)
    convoy = load_scene(ROOT / "scenes/convoy.toml")
    assert convoy.bed.rocks == 200000 and len(convoy.vehicles) == 4
    assert all(v.path.speed == 20.0 and v.path.points[-1][0] - v.path.points[0][0] >= 20.0 * convoy.duration
               for v in convoy.vehicles)
    minimal = load_scene(ROOT / "scenes/minimal.toml")
    assert (minimal.bed.rocks, minimal.bed.radius, minimal.duration, minimal.sim.dt) == (2000, 8.0, 2.0, 0.004)


def test_defaults_filled_in():
    scene = parse_scene({"vehicle": [{"name": "a", "color": "#ff8000"}, {"name": "b"}]})
    assert isinstance(scene, Scene) and scene.source == "<scene>" and scene.name == "scene"
    assert (scene.bed.follow, scene.camera.follow) == ("a", "a")
    assert parse_scene({"bed": {"follow": "b"}, "vehicle": [CAR, {"name": "b"}]}).camera.follow == "b"
    assert scene.world.gravity == 9.81 and scene.sim.hash.insert == "center" and scene.sim.hash.cell_size == "auto"
    assert scene.bed.rock_radius == (0.015, 0.05) and scene.render.resolution == (1280, 720)
    assert scene.vehicles[0].color == (1.0, 128 / 255, 0.0) and scene.vehicles[1].color == (0.8, 0.2, 0.1)
    assert scene.vehicles[0].path.kind == "waypoints" and scene.vehicles[0].path.speed == 25.0
    assert scene.vehicle("b") is scene.vehicles[1] and scene.vehicle_index("b") == 1
    with pytest.raises(KeyError):
        scene.vehicle("nobody")
    with pytest.raises(Exception):
        scene.duration = 3.0  # frozen


def test_types_are_strict_but_ints_are_numbers():
    scene = parse_scene({"duration": 3, "vehicle": [{"name": "c", "color": [1, 0, 0],
                                                     "path": {"points": [[0, 0], [5, 0]], "speed": [1, 2]}}]})
    assert scene.duration == 3.0 and isinstance(scene.duration, float)
    assert scene.vehicles[0].color == (1.0, 0.0, 0.0) and all(isinstance(c, float) for c in scene.vehicles[0].color)
    assert scene.vehicles[0].path.speed == (1.0, 2.0)
    assert parse_scene({"bed": {"rocks": 0}, "vehicle": [CAR]}).bed.rocks == 0  # no rocks is fine
    assert problems_of(parse_scene, {"seed": True, "vehicle": [CAR]}) == [
        "<scene>: seed: expected an integer, got true"]
    assert problems_of(parse_scene, {"bed": {"rocks": 10.0}, "vehicle": [CAR]}) == [
        "<scene>: bed.rocks: expected an integer, got 10.0"]
    assert problems_of(parse_scene, {"sim": {"precision": 32}, "vehicle": [CAR]}) == [
        '<scene>: sim.precision: expected one of "f32", "f64", got 32']


def test_round_trip_and_overrides():
    scene = load_scene(ROOT / "scenes/slalom.toml")
    data = scene_to_dict(scene)
    assert "vehicle" in data and "vehicles" not in data
    json.dumps(data)  # plain data
    assert parse_scene(data, scene.source, "other") == scene
    changed = scene_with(scene, {"sim.dt": 0.01, "effects.drag": "none", "bed.rocks": 10,
                                 "vehicle[0].path.speed": 5.0, "sim.hash.cell_size": 0.1})
    assert (changed.sim.dt, changed.effects.drag, changed.bed.rocks) == (0.01, "none", 10)
    assert changed.vehicles[0].path.speed == 5.0 and changed.sim.hash.cell_size == 0.1
    assert changed.vehicles[1] == scene.vehicles[1] and changed.source == scene.source and scene.sim.dt == 0.002
    lines = problems_of(scene_with, scene, {"sim.dt": -1.0, "vehicle[1].tire_radius": "big"})
    assert lines == [f"{scene.source}: sim.dt: must be > 0, got -1.0",
                     f'{scene.source}: vehicle[1].tire_radius: expected a number, got "big"']
    assert "no such item" in problems_of(scene_with, scene, {"vehicle[5].name": "x"})[0]


@pytest.mark.parametrize("overrides, words", [
    ([("sim.dt", 0.01)], "overrides must be a dict of dotted keys and values"),
    ("sim.dt=0.01", "overrides must be a dict"), (None, "overrides must be a dict"),
    ({5: 0.01}, "overrides: each key must be a dotted key path .* got 5"),
    ({("sim", "dt"): 0.01}, "overrides: each key must be a dotted key path")])
def test_overrides_that_are_not_a_dict_of_dotted_keys_are_a_type_error(overrides, words):
    scene = load_scene(ROOT / "scenes/minimal.toml")
    with pytest.raises(TypeError, match=words):
        scene_with(scene, overrides)


def test_overrides_take_numpy_numbers_and_arrays_as_toml_values():
    import numpy as np

    scene = load_scene(ROOT / "scenes/minimal.toml")
    changed = scene_with(scene, {"bed.rocks": np.int64(100), "sim.dt": np.float32(0.005), "effects.dust": np.True_,
                                 "dust.wind": np.array([1.5, -2.0]), "vehicle[0].path.points": np.array(
                                     [[0.0, 0.0], [50.0, 0.0]])})
    assert changed.bed.rocks == 100 and type(changed.bed.rocks) is int
    assert changed.sim.dt == pytest.approx(0.005) and changed.effects.dust is True
    assert changed.dust.wind == (1.5, -2.0) and len(changed.vehicles[0].path.points) == 2
    assert "expected an integer" in problems_of(scene_with, scene, {"bed.rocks": np.float64(1.5)})[0]


def test_json_schema():
    schema = json.loads(json.dumps(scene_json_schema()))
    assert schema["$schema"].endswith("2020-12/schema") and schema["title"] and schema["description"]
    assert schema["required"] == ["vehicle"] and schema["additionalProperties"] is False
    assert schema["properties"]["vehicle"]["minItems"] == 1
    defs = schema["$defs"]
    assert defs["Sim"]["properties"]["integrator"]["enum"] == ["symplectic_euler", "heun", "rk4"]
    assert defs["Sim"]["properties"]["dt"] == {**defs["Sim"]["properties"]["dt"], "default": 0.002,
                                               "exclusiveMinimum": 0, "maximum": 0.1}
    assert defs["Bed"]["properties"]["rocks"]["default"] == 100000
    assert "source" not in json.dumps(schema)

    def fields(node):  # every property of every table has a description (a table's may be on its $ref)
        for name, prop in node.get("properties", {}).items():
            assert prop.get("description") or defs[prop["$ref"].split("/")[-1]]["description"], name
    for node in defs.values():
        fields(node)
    fields(schema)
    import jsonschema  # the test extra: without it this test fails, the shipped scenes must be validated

    jsonschema.Draft202012Validator.check_schema(schema)
    assert SCENES
    for path in SCENES:
        jsonschema.validate(scene_to_dict(load_scene(path)), schema)
    bad = scene_to_dict(load_scene(SCENES[0]))
    bad["sim"]["integrator"] = "rk5"  # the validator is not vacuous: what the loader refuses, it refuses too
    with pytest.raises(jsonschema.ValidationError, match="rk5"):
        jsonschema.validate(bad, schema)


def _load_and_fit(path):
    """What ``taichi-rocks check`` does: the file's checks, then the engine's (do the World and the frames fit
    in memory)."""
    scene = load_scene(path)
    check_machine(scene)
    return scene


@pytest.mark.parametrize("path", BAD, ids=lambda p: p.stem)
def test_bad_scene(path):
    first = path.read_text().splitlines()[0]
    assert first.startswith("# expect: "), "bad scene files start with '# expect: <key.path> | <phrase>'"
    key, phrase = (s.strip() for s in first.removeprefix("# expect: ").split("|", 1))
    lines = problems_of(_load_and_fit, str(path))
    assert all(line.startswith(f"{path}: ") for line in lines)
    assert any(line.startswith(f"{path}: {key}: ") and phrase in line for line in lines), lines
    text = "\n".join(lines)
    for leak in ("Traceback", "pydantic", "http", "Input should", "function-", "@a", "@b"):
        assert leak not in text


def test_all_problems_reported(tmp_path):
    path = tmp_path / "many.toml"
    path.write_text("""
duration = -1.0
[bed]
follow = "ghost"
radious = 3.0
rock_radius = [0.06, 0.05]
[sim]
integrator = "rk5"
[[vehicle]]
name = "a"
wheelbase = 9.0
path = { points = [[0.0, 0.0], [1.0, 0.0], [1.0, 0.0]] }
[[vehicle]]
name = "a"
tire_radius = -0.3
[render]
resolution = [1281, 721]
""")
    lines = problems_of(load_scene, path)
    expected = ["duration: must be > 0", "bed.rock_radius: min must be <= max", 'bed.radious: unknown key "radious"',
                'sim.integrator: unknown value "rk5"', "vehicle[0].wheelbase: must be <= length",
                "vehicle[0].path.points[2]: repeats the previous point",
                "vehicle[1].tire_radius: must be > 0, got -0.3",
                "render.resolution[0]: must be even", "render.resolution[1]: must be even",
                'vehicle[1].name: duplicate vehicle name "a"', 'bed.follow: unknown vehicle "ghost"']
    for want in expected:
        assert any(line.startswith(f"{path}: {want}") for line in lines), (want, lines)
    assert len(lines) == len(expected)


def test_unreadable_files(tmp_path):
    for path in (tmp_path / "missing.toml", tmp_path):
        [line] = problems_of(load_scene, path)
        assert line.startswith(f"{path}: cannot read scene: ")
    assert problems_of(parse_scene, [1, 2]) == ["<scene>: expected a table, got [1, 2]"]


def test_summary_prints_the_memory_it_is_given():
    scene = parse_scene({"bed": {"rocks": 1000}, "vehicle": [CAR]})
    assert "memory" not in summarise(scene)
    assert math.isclose(float(summarise(scene, 12_345_678).split("about ")[-1].split()[0]), 12.3, abs_tol=0.05)


def test_an_accuracy_override_applies_its_preset():
    car = [{"name": "car", "path": {"points": [[0, 0], [10, 0]], "speed": 1.0}}]
    base = parse_scene({"sim": {"dt": 0.004, "detection": "ray"}, "vehicle": car})
    game = scene_with(base, {"sim.accuracy": "game"})
    assert (game.sim.accuracy, game.sim.dt, game.sim.integrator, game.sim.detection) == ("game", 1 / 60, "heun", "patch")
    mixed = scene_with(base, {"sim.accuracy": "draft", "sim.dt": 0.01})  # keys given beside it win
    assert (mixed.sim.dt, mixed.sim.detection) == (0.01, "swept")
    assert scene_with(base, {"sim.accuracy": "custom"}).sim.dt == 0.004  # custom: the keys as they are


def test_accuracy_presets_fill_unset_keys_only():
    from taichi_rocks.config.scene import PRESETS, parse_scene

    car = [{"name": "a", "path": {"points": [[0.0, 0.0], [1.0, 0.0]], "speed": 1.0}}]
    for name, preset in PRESETS.items():
        sim = parse_scene({"sim": {"accuracy": name}, "vehicle": car}).sim
        assert {k: getattr(sim, k) for k in preset} == preset
    sim = parse_scene({"sim": {"accuracy": "draft", "dt": 0.01}, "vehicle": car}).sim
    assert sim.dt == 0.01 and sim.integrator == PRESETS["draft"]["integrator"]
    assert parse_scene({"vehicle": car}).sim.integrator == "symplectic_euler"  # "custom" keeps the defaults


def test_vehicle_geometry_must_be_buildable():
    """Each size that must fit in another is refused at its own key, defaults included; the limits are allowed."""
    def lines(**vehicle):
        return problems_of(parse_scene, {"vehicle": [CAR, {"name": "b", **vehicle}]})

    assert lines(height=1.4, tire_radius=1.0) == [
        "<scene>: vehicle[1].tire_radius: must be <= height / 2 (0.7) so that the tire fits in the vehicle's "
        "height, got 1"]
    assert lines(length=1.0, wheelbase=0.5, tire_radius=0.3) == [
        "<scene>: vehicle[1].tire_radius: must be <= wheelbase / 2 (0.25) so that the front and rear tires do not "
        "overlap, got 0.3"]
    assert lines(length=4.0, wheelbase=4.5) == ["<scene>: vehicle[1].wheelbase: must be <= length (4), got 4.5"]
    assert lines(width=1.8, track=2.0) == ["<scene>: vehicle[1].track: must be <= width (1.8), got 2"]
    assert lines(track=0.3, tire_width=0.4) == [
        "<scene>: vehicle[1].tire_width: must be <= track (0.3) so that the left and right tires do not overlap, "
        "got 0.4"]
    assert lines(tire_radius=5.0) == ["<scene>: vehicle[1].tire_radius: must be <= 3, got 5.0"]
    assert lines(length=120.0) == ["<scene>: vehicle[1].length: must be <= 100, got 120.0"]
    # a key the file leaves out is checked against the keys it sets
    assert lines(height=0.5) == ["<scene>: vehicle[1].tire_radius: must be <= height / 2 (0.25) so that the tire "
                                 "fits in the vehicle's height, got 0.33 (the default)"]
    assert lines(length=2.0) == ["<scene>: vehicle[1].wheelbase: must be <= length (2), got 2.7 (the default)"]
    # a key that is wrong itself is reported once, not again at the keys that must fit in it
    assert lines(height=-1.0, tire_radius=1.0) == ["<scene>: vehicle[1].height: must be > 0, got -1.0"]
    # exactly at the limits is buildable
    v = parse_scene({"vehicle": [{"name": "c", "length": 0.8, "wheelbase": 0.8, "height": 0.8, "tire_radius": 0.4,
                                  "width": 0.3, "track": 0.3, "tire_width": 0.3}]}).vehicles[0]
    assert (v.wheelbase, 2 * v.tire_radius, v.track, v.tire_width) == (v.length, v.height, v.width, v.track)


def test_json_schema_holds_the_vehicle_ranges():
    props = scene_json_schema()["$defs"]["Vehicle"]["properties"]
    for key in ("length", "width", "height", "wheelbase", "track", "tire_radius", "tire_width"):
        assert props[key]["exclusiveMinimum"] == 0 and props[key]["maximum"] > props[key]["default"], key
    assert props["tire_radius"]["maximum"] == 3
    for key, other in (("wheelbase", "length"), ("track", "width"), ("tire_radius", "height"),
                       ("tire_radius", "wheelbase"), ("tire_width", "track")):
        assert other in props[key]["description"], (key, other)


DEEP = 5000
NESTED = {   # (text, line and column of the first bracket or brace past the limit, the key named)
    "arrays": ("a = " + "[" * DEEP + "]" * DEEP, (1, 37), "a"),
    "inline tables": ("a = " + "{b = " * DEEP + "1" + "}" * DEEP, (1, 165), "a"),
    "both": ("a = " + "[{b = " * DEEP + "1" + "}]" * DEEP, (1, 101), "a"),
    "in a vehicle": ('[[vehicle]]\nname = "car"\ncolor = [\n  # [[[\n  "[[[",\n' + "[" * DEEP + "]" * DEEP + "]",
                     (6, 32), "color"),
}


@pytest.mark.parametrize("kind", NESTED)
def test_deeply_nested_values_are_one_line_with_their_place(tmp_path, kind):
    """tomllib recurses once per level: without the scan before it, 5,000 levels ended in a RecursionError."""
    text, (line, column), key = NESTED[kind]
    path = tmp_path / "deep.toml"
    path.write_text(text + '\n\n[[vehicle]]\nname = "other"\n')
    [problem] = problems_of(load_scene, path)
    assert problem == (f"{path}: line {line}, column {column}: arrays and inline tables nested deeper than 32 "
                       f"levels in the value of {key}")


def test_nesting_scan_ignores_strings_and_comments():
    import tomllib

    from taichi_rocks.config.tomltext import MAX_NESTING, loads, nesting_overflow

    b = "[{" * 40
    text = f'''name = "{b}\\" {b}"  # {b}
x = \'{b}\'
y = """{b}
"{b}"" """"
z = \'\'\'{b}\'\'\'\'
[[vehicle]]
name = "car"
'''
    assert nesting_overflow(text) is None
    assert loads(text) == tomllib.loads(text) == {"name": f'{b}" {b}', "x": b, "y": f'{b}\n"{b}"" "', "z": f"{b}\'",
                                                 "vehicle": [{"name": "car"}]}
    at_limit = "a = " + "[" * MAX_NESTING + "]" * MAX_NESTING
    assert nesting_overflow(at_limit) is None
    assert nesting_overflow("[[t]]\n" + at_limit.replace("a = [", "a = [[")) == (len("[[t]]\n") + 4 + 32, "a")


def test_deeply_nested_data_built_in_code():
    """parse_scene takes data of any depth: the messages show only the start of the value."""
    deep = []
    for _ in range(DEEP):
        deep = [deep]
    lines = problems_of(parse_scene, {"a": deep, "vehicle": [{"name": "c", "color": deep, "path": {"points": deep}}]})
    want = ['<scene>: a: unknown key "a"', "<scene>: vehicle[0].color[0]: expected a number, got [[[[",
            "<scene>: vehicle[0].path.points[0][0]: "]
    for start in want:
        assert any(line.startswith(start) for line in lines), (start, lines)
    assert max(len(line) for line in lines if "[[[[" in line) < 140


def test_recursion_in_parsing_or_validating_is_a_scene_error(tmp_path, monkeypatch):
    """Belt and braces behind the nesting scan: a RecursionError becomes one line naming the file."""
    import taichi_rocks.config.scene as scene_module
    import taichi_rocks.config.tomltext as tomltext

    def recurse(*args, **kwargs):
        raise RecursionError("maximum recursion depth exceeded")

    path = tmp_path / "s.toml"
    path.write_text('[[vehicle]]\nname = "car"\n')
    monkeypatch.setattr(tomltext.tomllib, "loads", recurse)
    assert problems_of(load_scene, path) == [f"{path}: nested too deeply to read"]
    monkeypatch.undo()
    monkeypatch.setattr(scene_module.Scene, "model_validate", recurse)
    assert problems_of(load_scene, path) == [f"{path}: lists and tables nested too deeply to check"]
