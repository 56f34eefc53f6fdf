"""engine/params.py: one table of the kernels' parameters. The indices, the packing of a scene, the runtime keys
and the panel's sliders all come from it; the sliders stay within the scene schema's ranges. And the launch
models' registry (engine/launch/): one module per model, the same interface, the scene's choices."""

import ast
import inspect
import math
import re

import numpy as np
import pytest

from taichi_rocks.config.keys import bounds, choices, scene_value
from taichi_rocks.config.plan import Plan
from taichi_rocks.config.scene import load_scene, scene_with
from taichi_rocks.config.streams import LAUNCH
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
    """Every row from a scene key is the key's value times its factor; every derived row has a NumPy reference
    here (a new derivation needs one)."""
    scene = scene_with(load_scene(scenes_dir / "minimal.toml"),
                       {"world.ground_z": 3.0, "launch.release_angle": [12.0, 33.0], "seed": 2 ** 31 + 5})
    plan = Plan.from_scene(scene)
    sizing = hash_sizing(scene, plan, initial_rocks(scene).radius, 2)
    par, ipar = scene_params(scene, plan, sizing, ground_z=1.25)
    for table, cls, out in ((TABLE, Par, par), (INT_TABLE, IPar, ipar)):
        for p in (p for p in table if p.key is not None):
            want = np.atleast_1d(np.asarray(scene_value(scene, p.key), np.float64)) * p.factor
            assert [out[getattr(cls, n)] for n in p.names] == list(want), p.key  # the same bits
    assert par[Par.ANGLE_MIN] == np.radians(12.0) and par[Par.GRIP_RELAX] == math.radians(scene.launch.grip_relax)
    wd, bed = scene.world, scene.bed
    r_max, cell = bed.rock_radius[1], plan.cell_size
    derived = {"GROUND_Z": 1.25, "CELL": plan.cell_size, "R_MAX": r_max, "TIE_EPS": 1e-5, "MARGIN": sizing.margin,
               "LINEAR_DRAG": 4.5 * wd.air_viscosity / bed.density,
               "QUAD_DRAG": 3.0 * wd.air_density * bed.drag_coefficient / (8.0 * bed.density),
               "PATCH_TOL": 1e-4 + 64.0 * float(np.finfo(np.float32).eps) * 3.0,
               "CHIP": scene.impacts.chip_energy, "CRACK": scene.impacts.crack_energy, "DAMAGE_MOMENTUM": 0.0,
               "MASS_PER_R3": 4.0 / 3.0 * math.pi * bed.density,
               "CONTACT_SLOP": 4.0 * float(np.finfo(np.float32).eps) * (256.0 + bed.radius)}
    int_derived = {"SEED": 5, "TABLE": sizing.table, "DILATE": int(math.floor(r_max / cell * (1 + 1e-6))) + 1}
    for table, cls, out, ref in ((TABLE, Par, par, derived), (INT_TABLE, IPar, ipar, int_derived)):
        assert set(ref) == {n for p in table if p.derive is not None for n in p.names}
        for name, v in ref.items():
            assert out[getattr(cls, name)] == v, name


def test_impact_parameters_follow_the_damage_measure(scenes_dir):
    """By momentum: the momentum thresholds and DAMAGE_MOMENTUM = 1; f64: the contact slop of f64."""
    scene = scene_with(load_scene(scenes_dir / "minimal.toml"),
                       {"impacts.damage_by": "momentum", "impacts.chip_momentum": 0.002, "sim.precision": "f64"})
    plan = Plan.from_scene(scene)
    sizing = hash_sizing(scene, plan, initial_rocks(scene).radius, 2)
    par, _ = scene_params(scene, plan, sizing, ground_z=0.0)
    assert (par[Par.CHIP], par[Par.CRACK], par[Par.DAMAGE_MOMENTUM]) == (0.002, 0.0055, 1.0)
    assert par[Par.CONTACT_SLOP] == 4.0 * float(np.finfo(np.float64).eps) * (256.0 + scene.bed.radius)


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
    """PARAMS: the rows it reads; STREAMS: distinct ids of the launch models' block, the only ones it draws."""
    for name, model in launch.MODELS.items():
        src = inspect.getsource(model)
        assert set(model.PARAMS) == set(re.findall(r"\bPar\.([A-Z_0-9]+)", src)), name
        assert len(set(model.STREAMS)) == len(model.STREAMS) and set(model.STREAMS) <= set(LAUNCH.ids), name
        drawn = [c.args[3] for c in ast.walk(ast.parse(src)) if isinstance(c, ast.Call)
                 and getattr(c.func, "id", None) == "uniform01"]
        assert drawn and all(isinstance(a, ast.Name) and vars(model)[a.id] in model.STREAMS for a in drawn), name
