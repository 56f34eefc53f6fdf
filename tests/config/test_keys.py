"""config/keys.py: the choices and ranges of scene keys come from the scene's types; config/streams.py: every
random stream id once per family, no two streams overlapping, and no drawing call with an id of its own."""

import ast
import typing
from pathlib import Path

import pytest

from taichi_rocks.config import streams
from taichi_rocks.config.keys import Bounds, bounds, choices, scene_value
from taichi_rocks.config.scene import Effects, Sim, parse_scene

PACKAGE = Path(__file__).resolve().parents[2] / "taichi_rocks"


def test_choices_are_the_literals_of_the_models_in_their_order():
    assert choices("sim.integrator") == typing.get_args(Sim.model_fields["integrator"].annotation)
    assert choices("effects.drag") == typing.get_args(Effects.model_fields["drag"].annotation)
    assert choices("sim.hash.scope") == ("tires", "all")  # a nested table
    assert choices("vehicle.kind")[0] == "auto"  # a list of tables, by its key in the file ([[vehicle]])
    assert choices("effects.fenders") == (False, True)
    assert "custom" in choices("sim.accuracy") and "balanced" in choices("sim.accuracy")


@pytest.mark.parametrize("key", ["world.gravity", "sim.nope", "nope.dt"])
def test_what_is_not_a_choice_is_refused(key):
    with pytest.raises(KeyError):
        choices(key)


def test_bounds_are_the_model_constraints():
    assert bounds("world.wetness") == Bounds(0.0, 1.0)
    assert bounds("world.rest_speed") == Bounds(0.0, float("inf"), lo_open=True)
    assert bounds("launch.release_angle") == Bounds(0.0, 90.0)  # a [min, max] pair: its items' range
    assert bounds("camera.fov") == Bounds(0.0, 180.0, lo_open=True, hi_open=True)
    assert 0.0 not in bounds("world.rest_speed") and 1e-9 in bounds("world.rest_speed")
    assert bounds("world.ground_z") == Bounds()  # unbounded


def test_scene_value_reads_a_dotted_key():
    scene = parse_scene({"vehicle": [{"name": "car"}], "launch": {"release_angle": [5.0, 6.0]}})
    assert scene_value(scene, "launch.release_angle") == [5.0, 6.0]
    assert scene_value(scene, "sim.hash.insert") == "center"


# ------------------------------------------------------------------------------------------ random streams
def test_streams_are_unique_and_no_two_overlap():
    assert streams.STREAMS and all(s.family in streams.FAMILIES for s in streams.STREAMS)
    for family in streams.FAMILIES:
        taken = {}
        for s in (s for s in streams.STREAMS if s.family == family):
            assert s.count >= 1 and s.first >= 0 and s.what
            for i in s.ids:
                assert i not in taken, f"{family} stream {i}: {s.what!r} and {taken[i]!r}"
                taken[i] = s.what
    # the bed's rejection sampling takes 0..63: two ids per attempt
    assert list(streams.RECYCLE_TRIES.ids) == list(range(64))


# drawing functions -> the argument that is a stream id (0-based position)
DRAWS = {"uniform01": 3, "uniform01_np": 3, "_unit": 1, "_unit_np": 1, "uniforms": 1}


def test_no_draw_names_a_stream_id_of_its_own():
    """Every call of a drawing function in the package takes its stream from config/streams.py (an expression
    over a Stream's ``first`` or ``ids``), never a number written at the call."""
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                name = getattr(node.func, "id", getattr(node.func, "attr", None))
                if name in DRAWS and len(node.args) > DRAWS[name]:
                    arg = node.args[DRAWS[name]]
                    if isinstance(arg, ast.Constant):
                        offenders.append(f"{path.relative_to(PACKAGE)}:{node.lineno}")
    assert not offenders, offenders
