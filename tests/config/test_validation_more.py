"""Scene validation beyond tests/bad_scenes: a path back at its first point, a sun below the horizon, text that is
not UTF-8 and the errors of ``scene_with`` (the dotted-key overrides the view's panel, --seed and the bench use).
Each problem is one line, compared exactly. No Taichi."""

import numpy as np
import pytest

from taichi_rocks.config.scene import SceneError, load_scene, parse_scene, scene_with

SCENE = """name = "closed"
[[vehicle]]
name = "car"
path = {{ points = [[0.0, 0.0], [30.0, 0.0], [30.0, 20.0], [0.0, 0.0]], loop = {loop}, speed = 10.0 }}
"""


def problems(fn, *args) -> list:
    with pytest.raises(SceneError) as info:
        fn(*args)
    return info.value.problems


def _car(**path):
    return {"vehicle": [{"name": "car", "path": {"points": [[0.0, 0.0], [30.0, 0.0]], **path}}]}


# ---------------------------------------------------------------------------------------------- paths
def test_a_loop_repeating_its_first_point_is_refused_at_that_point(tmp_path):
    path = tmp_path / "closed.toml"
    path.write_text(SCENE.format(loop="true"))
    assert problems(load_scene, path) == [
        f"{path}: vehicle[0].path.points[3]: repeats the first point (a loop closes by itself)"]
    assert problems(parse_scene, _car(points=[[0.0, 0.0], [9.0, 0.0], [0.0, 0.0]], loop=True)) == [
        "<scene>: vehicle[0].path.points[2]: repeats the first point (a loop closes by itself)"]
    # two points: the second is the first, the previous point too (one problem, not two)
    assert problems(parse_scene, _car(points=[[0.0, 0.0], [0.0, 0.0]], loop=True)) == [
        "<scene>: vehicle[0].path.points[1]: repeats the previous point, got [0.0, 0.0]"]


def test_a_path_that_is_not_a_loop_may_end_where_it_started(tmp_path):
    """Driven once, a path may come back to its start: accepted, and the vehicle ends there."""
    from taichi_rocks.motion.vehicles import Fleet

    path = tmp_path / "closed.toml"
    path.write_text(SCENE.format(loop="false"))
    scene = load_scene(path)
    assert scene.vehicles[0].path.points[0] == scene.vehicles[0].path.points[-1] == (0.0, 0.0)
    fleet = Fleet(scene)
    length = fleet.paths[0].length
    assert length > 30.0 + 20.0 + 36.0  # round the three sides (a smooth spline: a little longer)
    end = fleet.paths[0].pose(length / 10.0 + 1.0)  # past its end: parked at the last point
    np.testing.assert_allclose(end.position[:2], [0.0, 0.0], atol=1e-9)
    middle = fleet.paths[0].pose(0.5 * length / 10.0)
    assert np.hypot(*middle.position[:2]) > 10.0  # it did go somewhere


# ---------------------------------------------------------------------------------------------- the sun
@pytest.mark.parametrize("sun, shown", [([0.0, 0.0, -1.0], "[0.0, 0.0, -1.0]"),
                                        ([0.3, -0.2, -0.5], "[0.3, -0.2, -0.5]"),
                                        ([1.0, 0.0, 0.0], "[1.0, 0.0, 0.0]")])  # on the horizon: no light
def test_a_sun_that_does_not_point_up_is_refused(tmp_path, sun, shown):
    path = tmp_path / "night.toml"
    path.write_text(f"[render]\nsun = {sun}\n[[vehicle]]\nname = \"car\"\n")
    assert problems(load_scene, path) == [f"{path}: render.sun: must point up (z > 0), got {shown}"]


@pytest.mark.parametrize("elevation", [-10.0, 0.0])
def test_a_sun_below_the_horizon_by_its_angles_is_refused(elevation):
    data = {"render": {"sun": {"azimuth": 45.0, "elevation": elevation}}, **_car()}
    assert problems(parse_scene, data) == [f"<scene>: render.sun.elevation: must be > 0, got {elevation}"]
    data["render"]["sun"]["elevation"] = 90.0  # straight down from above: fine
    assert parse_scene(data).render.sun.elevation == 90.0


# ---------------------------------------------------------------------------------------------- text
@pytest.mark.parametrize("data, where", [
    (b'name = "caf\xe9"\n[[vehicle]]\nname = "car"\n', "invalid continuation byte at byte 11"),  # Latin-1
    ('name = "x"\n[[vehicle]]\nname = "car"\n'.encode("utf-16"), "invalid start byte at byte 0"),
    (b'[[vehicle]]\nname = "car"\n# \x80\n', "invalid start byte at byte 27"),
])
def test_text_that_is_not_utf8_is_one_line_naming_the_byte(tmp_path, capsys, data, where):
    path = tmp_path / "latin.toml"
    path.write_bytes(data)
    line = f"{path}: cannot read scene: not UTF-8 text ({where})"
    assert problems(load_scene, path) == [line]
    from taichi_rocks.cli import main

    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [line], err


def test_a_utf8_byte_order_mark_is_not_an_error(tmp_path):
    """Some editors start UTF-8 files with a byte-order mark; TOML parsers reject it as an "Invalid statement"
    at line 1: it is dropped."""
    path = tmp_path / "bom.toml"
    path.write_bytes(b'\xef\xbb\xbfname = "marked"\n[[vehicle]]\nname = "car"\n')
    assert load_scene(path).name == "marked"


# ---------------------------------------------------------------------------------------------- scene_with
@pytest.fixture(scope="module")
def minimal(scenes_dir):
    return load_scene(scenes_dir / "minimal.toml")


@pytest.mark.parametrize("key, message", [
    ("sim..dt", "sim..dt: not a key path like sim.dt or vehicle[0].path.speed"),
    ("sim.dt x", "sim.dt x: not a key path like sim.dt or vehicle[0].path.speed"),
    ("vehicle[-1].name", "vehicle[-1].name: not a key path like sim.dt or vehicle[0].path.speed"),
    ("vehicle[1].name", "vehicle[1]: no such item"),
    ("vehicle[0].path.points[2]", "vehicle[0].path.points[2]: no such item"),
    ("vehicle[0].path.points[0][2]", "vehicle[0].path.points[0][2]: no such item"),
    ("bed[0]", "bed[0]: no such item"),
    ("sim.dt.x", "sim.dt.x: not inside a table"),  # was a TypeError: the last step was not checked
    ("vehicle.name", "vehicle.name: not inside a table"),  # a list of tables, not a table: a TypeError too
    ("sim.dt.x.y", "sim.dt.x: not inside a table"),
    ("camera.offset.x", "camera.offset.x: not inside a table"),  # unset (None): not a table either
])
def test_scene_with_bad_keys_are_one_line(minimal, key, message):
    assert problems(scene_with, minimal, {key: 1.0}) == [f"{minimal.source}: {message}"]


@pytest.mark.parametrize("overrides, message", [
    ({"sim.dt": "fast"}, 'sim.dt: expected a number, got "fast"'),
    ({"seed": -1}, "seed: must be >= 0, got -1"),
    ({"vehicle[0]": 5}, "vehicle[0]: expected a table, got 5"),
    ({"vehicle[0].path.points[1]": [0.0, 0.0]}, "vehicle[0].path.points[1]: repeats the previous point, got "
                                                "[0.0, 0.0]"),
    ({"sim.hash.bucket": 3}, 'sim.hash.bucket: unknown key "bucket"'),
])
def test_scene_with_invalid_values_are_the_file_messages(minimal, overrides, message):
    lines = problems(scene_with, minimal, overrides)
    assert len(lines) == 1 and lines[0].startswith(f"{minimal.source}: {message}"), lines


def test_scene_with_changes_only_what_it_names(minimal):
    changed = scene_with(minimal, {"vehicle[0].path.points[1]": [50.0, 0.0], "seed": 9})
    assert changed.vehicles[0].path.points == ((0.0, 0.0), (50.0, 0.0)) and changed.seed == 9
    assert changed.bed == minimal.bed and changed.sim == minimal.sim and minimal.seed == 1
