"""engine/tuning.py: runtime parameters set on a running simulation act as if the scene had them, switches
rebuild it from a checkpoint; probes.rocks_in_air counts the flying rocks."""

import numpy as np
import pytest

STEPS = 250


@pytest.fixture(scope="module")
def scene(taichi_cpu, scenes_dir):
    """The small test scene with stones the tread's grooves carry (where wetness and grip matter)."""
    from taichi_rocks.config.scene import load_scene, scene_with

    return scene_with(load_scene(scenes_dir / "minimal.toml"), {"bed.rock_radius": [0.006, 0.012]})


def _run(sim, steps=STEPS):
    sim.step(steps)
    return sim.state()


def _same(a, b):
    for k in ("positions", "velocities", "phase", "launches_total"):
        assert np.array_equal(a[k], b[k]), k


@pytest.mark.parametrize("key, value", [("world.wetness", 0.9), ("world.gravity", 3.0), ("launch.grip", 5.0e4)])
def test_set_at_start_equals_a_scene_with_the_value(scene, key, value):
    from taichi_rocks.config.scene import scene_with
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.engine.tuning import runtime_values, set_runtime

    tuned = Simulation(scene)
    changed = set_runtime(tuned, {key: value})
    assert tuned.scene is changed and np.allclose(runtime_values(tuned)[key], value, rtol=1e-6)
    a = _run(tuned)
    del tuned
    b = _run(Simulation(scene_with(scene, {key: value})))
    _same(a, b)
    c = _run(Simulation(scene))
    assert not np.array_equal(a["positions"], c["positions"])  # the value changed what the rocks do


def test_set_mid_run_changes_only_what_follows_and_survives_restore(scene):
    """A value set after 60 steps: the state at the change is untouched, and the steps after it equal those of a
    simulation of the changed scene restored at step 60, not those of the unchanged one."""
    from taichi_rocks.config.scene import scene_with
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.engine.tuning import runtime_values, set_runtime

    sim = Simulation(scene)
    sim.step(60)
    saved = sim.checkpoint()
    before = sim.state()
    set_runtime(sim, {"world.gravity": 2.0})
    _same(sim.state(), before)  # nothing moved yet
    after = _run(sim, 60)
    sim.restore(saved)  # restore uploads the parameters again: the new ones
    assert runtime_values(sim)["world.gravity"] == pytest.approx(2.0)
    _same(_run(sim, 60), after)
    del sim  # one simulation at a time
    ref = Simulation(scene_with(scene, {"world.gravity": 2.0}))
    ref.restore(saved)
    _same(after, _run(ref, 60))  # the new value acts from the next step, as if the scene had it
    del ref
    plain = Simulation(scene)
    plain.restore(saved)
    unchanged = _run(plain, 60)
    assert np.count_nonzero(unchanged["phase"] == 1) > 0  # rocks in the air, which gravity moves
    assert not np.array_equal(after["positions"], unchanged["positions"])  # the change changed what followed


def test_bad_values_are_refused_and_change_nothing(scene):
    from taichi_rocks.config.scene import SceneError
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.engine.tuning import runtime_values, set_runtime

    sim = Simulation(scene)
    before = runtime_values(sim)
    with pytest.raises(SceneError, match="wetness"):
        set_runtime(sim, {"world.wetness": 1.5})
    with pytest.raises(ValueError, match="not a runtime key"):
        set_runtime(sim, {"sim.integrator": "heun"})
    assert runtime_values(sim) == before and sim.scene is scene


def test_rebuild_continues_from_the_checkpoint_with_the_switch(scene):
    """The viewer's rebuild under a switch: the same layout (the kernels that do not read the switch serve the
    new Simulation as compiled), the state of the checkpoint, then the switch's steps; a rebuild back to the
    switches run before compiles nothing."""
    from compiles import compiled
    from taichi_rocks.config.scene import scene_with
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.engine.tuning import rebuilder

    sim = Simulation(scene)
    sim.step(40)
    state = sim.state()
    layout = sim.world.layout
    make = rebuilder(sim, {"sim.integrator": "heun"})
    del sim
    new = make()
    assert new.world.layout == layout
    assert new.plan.integrator == "heun" and new.step_count == 40
    _same(new.state(), state)
    a = _run(new)
    with compiled() as names:
        back = rebuilder(new, {"sim.integrator": scene.sim.integrator})
        del new
        old = back()
        assert old.plan.integrator == scene.sim.integrator and old.step_count == 40 + STEPS
        old.step(10)
    assert names == [], names
    del old  # one simulation at a time
    saved = _checkpoint_of(scene, 40)
    ref = Simulation(scene_with(scene, {"sim.integrator": "heun"}))
    ref.restore(saved)
    _same(a, _run(ref))


def test_a_launch_model_is_a_switch_of_the_plan_not_of_the_world(scene):
    """Scenes that differ only in the launch model (or the fenders) have one World layout; the tire pass
    compiles per switch set: the uniform model throws differently (no stone of these reaches the fenders this
    early, so the fenders change nothing yet)."""
    from taichi_rocks.config.scene import scene_with
    from taichi_rocks.engine.simulation import Simulation

    sim = Simulation(scene)
    layout, thrown = sim.world.layout, _run(sim, 120)
    del sim
    for changes in ({"launch.model": "uniform"}, {"effects.fenders": False}):
        other = Simulation(scene_with(scene, changes))
        assert other.world.layout == layout, changes
        state = _run(other, 120)
        assert state["launches_total"] > 0
        assert np.array_equal(state["positions"], thrown["positions"]) == ("launch.model" not in changes)
        del other


def _checkpoint_of(scene, steps):
    from taichi_rocks.engine.simulation import Simulation

    sim = Simulation(scene)
    sim.step(steps)
    return sim.checkpoint()


def test_rocks_in_air_counts_the_flying_phase(scene):
    from taichi_rocks.engine.probes import rocks_in_air
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.engine.world import FLYING

    sim = Simulation(scene)
    assert rocks_in_air(sim) == 0
    sim.step(100)
    n = rocks_in_air(sim)
    assert n == int(np.count_nonzero(sim.state()["phase"] == FLYING)) and n > 0
