"""The scene keys of dust: [effects] dust (from the effects' registry, config/effects/), the [dust] table, and
the Plan's switch."""

import pytest

from scenes_util import problems, scene
from taichi_rocks.config.effects import EFFECTS, dust
from taichi_rocks.config.plan import Plan
from taichi_rocks.config.scene import parse_scene, scene_json_schema, scene_to_dict, summarise

CAR = {"name": "car", "path": {"points": [[0.0, 0.0], [400.0, 0.0]]}}


def test_the_switch_and_table_come_from_the_registry():
    sc = scene()
    assert set(EFFECTS) == {"dust"}
    assert sc.effects.dust is False and sc.dust == dust.Dust()
    schema = scene_json_schema()
    assert "dust" in schema["$defs"]["Effects"]["properties"] and "dust" in schema["properties"]
    again = parse_scene(scene_to_dict(scene(effects={"dust": True}, dust={"rate": 3.0})))
    assert again.effects.dust is True and again.dust.rate == 3.0


def test_plan_runs_dust_only_when_asked_and_a_vehicle_splashes():
    assert Plan.from_scene(scene()).effects == ()
    assert Plan.from_scene(scene(effects={"dust": True})).effects == ("dust",)
    assert "dust (optional effect)" in Plan.from_scene(scene(effects={"dust": True})).passes()
    quiet = [{**CAR, "splash": False}]
    assert Plan.from_scene(scene(vehicles=quiet, effects={"dust": True})).effects == ()
    assert Plan.from_scene(scene(rocks=0, effects={"dust": True})).effects == ("dust",)  # the air's, not the bed's


def test_bad_values_name_the_key():
    assert problems({"vehicle": [CAR], "dust": {"rate": -1.0}}) == ["s.toml: dust.rate: must be >= 0, got -1.0"]
    assert problems({"vehicle": [CAR], "dust": {"capacity": 0, "opacity": 1.5}}) == [
        "s.toml: dust.capacity: must be >= 1, got 0", "s.toml: dust.opacity: must be <= 1, got 1.5"]
    assert problems({"vehicle": [CAR], "effects": {"dust": "yes"}}) == [
        's.toml: effects.dust: expected true or false, got "yes"']
    (p,) = problems({"vehicle": [CAR], "dust": {"rates": 1.0}})
    assert p.startswith("s.toml: dust.rates: unknown key") and "rate" in p and "\n" not in p


def test_the_closed_forms():
    t = dust.Dust(rate=2.0, lift_speed=3.0, diameter=1e-4, density=2000.0)
    assert dust.emission_rate(2.0, t) == 0.0 and dust.emission_rate(3.0, t) == 0.0
    assert dust.emission_rate(13.0, t) == pytest.approx(200.0)
    assert dust.settling_velocity(t, 9.81, 1.81e-5) == pytest.approx(2000 * 9.81 * 1e-8 / (18 * 1.81e-5))
    assert dust.settling_velocity(t, 9.81, 0.0) == float("inf")


def test_check_lists_every_effect_on_its_effects_line():
    line = lambda sc: next(x for x in summarise(sc).splitlines() if x.startswith("effects:"))
    assert line(scene()).endswith(", dust off") and line(scene(effects={"dust": True})).endswith(", dust on")


def test_check_says_why_dust_asked_for_is_off():
    line = lambda sc: next(x for x in summarise(sc).splitlines() if x.startswith("effects:"))
    quiet = scene(vehicles=[{**CAR, "splash": False}], effects={"dust": True})
    assert line(quiet).endswith(", dust off (no vehicle splashes: dust rises behind the splashing ones)")


@pytest.mark.parametrize("key, value, words", [
    ("rate", 1e10, "must be <= 10000"), ("height", 1e40, "must be <= 20"), ("spread", 1e40, "must be <= 50"),
    ("wake_time", 1e-50, "must be >= 0.01"), ("fade", 1e-50, "must be >= 0.01"), ("size", 1e40, "must be <= 5"),
    ("density", 1e40, "must be <= 25000"), ("diameter", 1e-50, "must be >= 1e-07"),
    ("lift_speed", 1e40, "must be <= 100")])
def test_values_past_what_the_physics_and_float32_allow_name_the_key(key, value, words):
    (p,) = problems({"vehicle": [CAR], "effects": {"dust": True}, "dust": {key: value}})
    assert p.startswith(f"s.toml: dust.{key}: {words}") and "\n" not in p


def test_each_wind_component_has_a_range():
    (p,) = problems({"vehicle": [CAR], "dust": {"wind": [0.0, 1e40]}})
    assert p.startswith("s.toml: dust.wind[1]: must be <= 60")
    assert scene(dust={"wind": [-60.0, 60.0]}).dust.wind == (-60.0, 60.0)


def test_every_number_of_dust_is_bounded_on_both_sides():
    """No key of [dust] takes a value a float32 kernel cannot hold, nor a zero it divides by: each number (each
    wind component too) has an upper bound and a lower one (0 where 0 means "none"), in the JSON Schema."""
    props = scene_json_schema()["$defs"]["Dust"]["properties"]
    numbers = {k: v for k, v in props.items() if v.get("type") in ("number", "integer")}
    numbers.update({f"wind[{i}]": v for i, v in enumerate(props["wind"]["prefixItems"])})
    assert len(numbers) == len(props)  # all keys but the colour and the wind, and the wind's two components
    for key, p in numbers.items():
        assert ("maximum" in p or "exclusiveMaximum" in p) and ("minimum" in p or "exclusiveMinimum" in p), key
