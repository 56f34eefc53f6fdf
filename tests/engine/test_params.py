"""engine/params.py: one table of the kernels' parameters. The indices, the packing of a scene, the runtime keys
and the panel's sliders all come from it; the sliders stay within the scene schema's ranges. And the launch
models' registry (engine/launch/): one module per model, the same interface, the scene's choices."""

import inspect
import math
import re

import numpy as np
import pytest

from taichi_rocks.config.keys import bounds, choices, scene_value
from taichi_rocks.config.plan import Plan
from taichi_rocks.config.scene import load_scene, scene_with
from taichi_rocks.config.streams import STREAMS
from taichi_rocks.engine import launch, params
from taichi_rocks.engine.params import INT_TABLE, SLIDERS, TABLE, IPar, Par, Slider
from taichi_rocks.engine.setup import hash_sizing, initial_rocks, scene_params
from taichi_rocks.engine.tuning import RUNTIME_KEYS


def test_indices_are_the_places_in_the_tables():
    names = [n for p in TABLE for n in p.names]
    assert [getattr(Par, n) for n in names] == list(range(len(names))) == list(range(Par.COUNT))
    int_names = [n for p in INT_TABLE for n in p.names]
    assert [getattr(IPar, n) for n in int_names] == list(range(IPar.COUNT))


def test_sliders_lie_within_the_scene_schema_and_are_runtime_keys():
    assert list(SLIDERS)[0] == "world.wetness"  # the panel's first widget (tests/render/test_view.py drags it)
    for key, (label, lo, hi) in SLIDERS.items():
        b = bounds(key)
        assert lo < hi and lo in b and hi in b, (key, lo, hi, b)
        assert key in RUNTIME_KEYS and label
    for p in TABLE:
        if p.runtime:
            assert p.key is not None and isinstance(p.runtime, (bool, Slider))


def test_a_runtime_key_changes_no_compile_time_switch(scenes_dir):
    """set_runtime refuses a key that changes the Plan; no key of the table does (within its range)."""
    scene = load_scene(scenes_dir / "minimal.toml")
    for key in RUNTIME_KEYS:
        value = scene_value(scene, key)
        b = bounds(key)
        new = [0.5 * (v + (b.hi if math.isfinite(b.hi) else 2 * v + 1)) for v in np.atleast_1d(value)]
        changed = scene_with(scene, {key: new if isinstance(value, list) else new[0]})
        assert Plan.from_scene(changed) == Plan.from_scene(scene), key


def test_packing_a_scene_gives_each_parameter_its_source(scenes_dir):
    """A NumPy reference of every row: the scene's value in the kernels' units, or its derivation."""
    scene = scene_with(load_scene(scenes_dir / "minimal.toml"),
                       {"world.ground_z": 3.0, "launch.release_angle": [12.0, 33.0], "seed": 2 ** 31 + 5})
    plan = Plan.from_scene(scene)
    sizing = hash_sizing(scene, plan, initial_rocks(scene).radius, 2)
    par, ipar = scene_params(scene, plan, sizing, ground_z=1.25)
    wd, bed, ln = scene.world, scene.bed, scene.launch
    want = {"GRAVITY": wd.gravity, "GROUND_Z": 1.25, "BED_RADIUS": bed.radius, "RESTITUTION": wd.restitution,
            "GROUND_FRICTION": wd.ground_friction, "REST_SPEED": wd.rest_speed, "CELL": plan.cell_size,
            "ANGLE_MIN": np.radians(12.0), "ANGLE_MAX": np.radians(33.0), "SPREAD": np.radians(ln.spread),
            "LINEAR_DRAG": 4.5 * wd.air_viscosity / bed.density,
            "QUAD_DRAG": 3.0 * wd.air_density * bed.drag_coefficient / (8.0 * bed.density),
            "R_MAX": bed.rock_radius[1], "TIE_EPS": 1e-5, "MARGIN": sizing.margin, "DENSITY": bed.density,
            "WETNESS": wd.wetness, "GROOVE": ln.groove, "GRIP": ln.grip, "GRIP_RELAX": math.radians(ln.grip_relax),
            "GRIP_SPREAD": ln.grip_spread, "ADHESION": ln.adhesion, "TRANSFER": ln.transfer,
            "PATCH_TOL": 1e-4 + 64.0 * float(np.finfo(np.float32).eps) * 3.0}
    assert set(want) == {n for p in TABLE for n in p.names}
    for name, v in want.items():
        assert par[getattr(Par, name)] == v, name  # the same bits
    r_max, cell = bed.rock_radius[1], plan.cell_size
    assert ipar[IPar.SEED] == 5 and ipar[IPar.N_ROCKS] == bed.rocks and ipar[IPar.TABLE] == sizing.table
    assert ipar[IPar.DILATE] == int(math.floor(r_max / cell * (1 + 1e-6))) + 1


def test_pack_by_name_and_unknown_names():
    par, ipar = params.pack({"GRAVITY": 2.0, "N_ROCKS": 7})
    assert par[Par.GRAVITY] == 2.0 and ipar[IPar.N_ROCKS] == 7 and par.sum() == 2.0 and ipar.sum() == 7
    with pytest.raises(KeyError, match="NOPE"):
        params.pack({"NOPE": 1.0})


def test_a_row_needs_one_source():
    with pytest.raises(ValueError):
        params.Param("X", "world.gravity", derive=lambda s: 1.0)
    with pytest.raises(ValueError):
        params.Param("X", derive=lambda s: 1.0, runtime=True)


# ------------------------------------------------------------------------------------------ launch models
def test_the_registry_holds_the_scenes_launch_models():
    assert set(launch.MODELS) == set(choices("launch.model"))
    for name, model in launch.MODELS.items():
        assert model.NAME == name and model.__doc__
        assert list(inspect.signature(model.launch_velocity).parameters) == ["w", "plan", "t", "i", "step"]


def test_each_model_declares_the_parameters_and_streams_it_uses():
    engine_streams = [s for s in STREAMS if s.family == "engine"]
    for name, model in launch.MODELS.items():
        src = inspect.getsource(model)
        assert set(model.PARAMS) == set(re.findall(r"\bPar\.([A-Z_0-9]+)", src)), name
        assert all(s in engine_streams for s in model.STREAMS), name
        used = set(re.findall(r"\b([A-Z][A-Z_]+)\.first\b", src))
        assert used == {k for k, v in vars(model).items() if v in model.STREAMS}, name
