"""The scene keys of impacts: [effects] impacts, the [impacts] table, [[vehicle]] hit, and the Plan's switch."""

import json

import pytest

from scenes_util import problems, scene
from taichi_rocks.config.impacts import DAMAGE_CLASSES, Impacts
from taichi_rocks.config.plan import Plan
from taichi_rocks.config.scene import parse_scene, scene_json_schema, scene_to_dict

CAR = {"name": "car", "path": {"points": [[0.0, 0.0], [400.0, 0.0]]}}
BEHIND = {"name": "behind", "splash": False, "path": {"points": [[-20.0, 0.0], [380.0, 0.0]]}}


def test_defaults_off_and_round_trip():
    sc = scene()
    assert sc.effects.impacts is False and sc.vehicles[0].hit is True
    assert sc.impacts == Impacts() and sc.impacts.thresholds() == (0.0055, 0.14)
    assert DAMAGE_CLASSES == ("mark", "chip", "crack")
    again = parse_scene(scene_to_dict(sc))
    assert again.impacts == sc.impacts and again.effects.impacts is False


def test_bad_values_name_the_key():
    assert problems({"vehicle": [CAR], "impacts": {"restitution": 1.5}}) == [
        "s.toml: impacts.restitution: must be <= 1, got 1.5"]
    assert problems({"vehicle": [CAR], "impacts": {"friction": -0.1, "chip_energy": 0}}) == [
        "s.toml: impacts.friction: must be >= 0, got -0.1", "s.toml: impacts.chip_energy: must be > 0, got 0"]
    assert problems({"vehicle": [CAR], "impacts": {"chip_energy": 0.5, "crack_energy": 0.2,
                                                   "crack_momentum": 0.001}}) == [
        "s.toml: impacts.crack_energy: must be > chip_energy (0.5), got 0.2",
        "s.toml: impacts.crack_momentum: must be > chip_momentum (0.0011), got 0.001"]
    assert problems({"vehicle": [CAR], "impacts": {"damage_by": "energie"}}) == [
        's.toml: impacts.damage_by: unknown value "energie", did you mean "energy"? (expected one of "energy", '
        '"momentum")']
    assert problems({"vehicle": [CAR], "impacts": {"restitutoin": 0.2}}) == [
        's.toml: impacts.restitutoin: unknown key "restitutoin", did you mean "restitution"?']
    assert problems({"vehicle": [{**CAR, "hit": 1}]}) == ["s.toml: vehicle[0].hit: expected true or false, got 1"]
    assert problems({"vehicle": [CAR], "effects": {"impacts": "yes"}}) == [
        's.toml: effects.impacts: expected true or false, got "yes"']


def test_momentum_thresholds_when_asked():
    sc = parse_scene({"vehicle": [CAR], "impacts": {"damage_by": "momentum", "chip_momentum": 0.002,
                                                    "crack_momentum": 0.01}})
    assert sc.impacts.thresholds() == (0.002, 0.01)


@pytest.mark.parametrize("fx, vehicles, want", [
    ({"impacts": True}, [CAR, BEHIND], True),
    ({}, [CAR, BEHIND], False),  # not asked for
    ({"impacts": True}, [CAR], False),  # a thrower's own body is not hit
    ({"impacts": True}, [CAR, {**BEHIND, "hit": False}], False),  # the only other body is left out
    ({"impacts": True}, [{**CAR, "hit": False}, {**BEHIND, "splash": True}], True),  # car hit by behind's
    ({"impacts": True, "splash": False}, [CAR, BEHIND], False),  # nothing flies
    ({"impacts": True}, [{**CAR, "splash": False}, BEHIND], False),  # no tire throws
])
def test_the_plan_switch(fx, vehicles, want):
    sc = scene(vehicles=vehicles, effects=fx)
    assert Plan.from_scene(sc).impacts is want


def test_schema_holds_the_keys_with_ranges():
    schema = json.loads(json.dumps(scene_json_schema()))
    props = schema["$defs"]["Impacts"]["properties"]
    assert props["restitution"]["minimum"] == 0 and props["restitution"]["maximum"] == 1
    assert props["friction"]["minimum"] == 0
    assert props["damage_by"]["enum"] == ["energy", "momentum"]
    for key in ("chip_energy", "crack_energy", "chip_momentum", "crack_momentum"):
        assert props[key]["exclusiveMinimum"] == 0 and props[key]["description"], key
    assert "chip_energy" in props["crack_energy"]["description"]
    assert schema["$defs"]["Effects"]["properties"]["impacts"]["default"] is False
    assert schema["$defs"]["Vehicle"]["properties"]["hit"]["default"] is True
    assert schema["properties"]["impacts"]["$ref"].endswith("/Impacts")
