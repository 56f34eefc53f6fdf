"""Changing a running simulation's settings: the engine's face for the view's panel (app/view.py).

Two kinds of scene keys, by how they reach the kernels:

* runtime keys (:data:`RUNTIME_KEYS`, the rows of engine/params.py with ``runtime``; :data:`SLIDERS`, those
  the panel shows as sliders) are only numbers in ``World.par``: :func:`set_runtime` validates a changed Scene
  (``scene_with``: the same ranges and messages as a scene file), packs its parameters again and uploads them;
  the next step uses them. Nothing is recompiled and the rocks keep their state.
* switches (:data:`SWITCH_KEYS`, their choices from the scene's types) are read by the kernels at compile time
  (config/plan.py, ``ti.static``): :func:`rebuilder` takes a checkpoint of the simulation and returns a
  function that builds a Simulation of the changed scene and restores the checkpoint into it (same rocks, clock
  and origin; a new World, whose kernels are compiled already for a layout and switches seen before).
"""

from __future__ import annotations

import numpy as np

from ..config.keys import choices, scene_value
from ..config.plan import Plan
from ..config.scene import scene_with
from .params import RUNTIME_KEYS, SLIDERS
from .setup import scene_params
from .simulation import Simulation

__all__ = ["RUNTIME_KEYS", "SLIDERS", "SWITCH_KEYS", "set_runtime", "runtime_values", "scene_value", "rebuilder"]

# switches the view's panel may change, and their choices (a new Simulation each: see the module docstring)
SWITCH_KEYS = {key: choices(key) for key in ("sim.integrator", "effects.drag", "effects.ground", "effects.gravity",
                                             "effects.fenders")}


def set_runtime(sim, values: dict):
    """Set runtime keys (dotted scene keys of :data:`RUNTIME_KEYS`, scene units) of ``sim`` at once; return
    the changed Scene (also ``sim.scene``). SceneError if a value is out of its range, ValueError for a key
    that is not a runtime key."""
    other = sorted(set(values) - set(RUNTIME_KEYS))
    if other:
        raise ValueError(f"not a runtime key: {', '.join(other)} (runtime keys: {', '.join(RUNTIME_KEYS)})")
    scene = scene_with(sim.scene, dict(values))
    if Plan.from_scene(scene, sim.tumble, sim.track_changes) != sim.plan:  # cannot happen for these keys; a guard for new ones
        raise ValueError("these values change what the kernels compile: build a new Simulation")
    par, _ = scene_params(scene, sim.plan, sim._sizing, ground_z=scene.world.ground_z - sim.origin[2])
    sim.scene = scene
    sim._par = par  # what restore() uploads again
    sim.world.set_params(par)  # ipar (rock and table counts) stays as it is
    return scene


def runtime_values(sim) -> dict:
    """The runtime keys' values the kernels read now (from ``World.par``, back in scene units)."""
    par = sim.world.par.to_numpy().astype(np.float64)
    out = {}
    for key, (idx, factor) in RUNTIME_KEYS.items():
        if isinstance(idx, tuple):
            out[key] = [float(par[i]) / factor for i in idx]
        else:
            out[key] = float(par[idx]) / factor
    return out


def rebuilder(sim, changes: dict):
    """Validate ``changes`` (dotted scene keys, any: switches included) and checkpoint ``sim``; return
    ``make()``, which builds the Simulation of the changed scene (same arch, timer, tumble and change tracking) continuing from the
    checkpoint. Drop every reference to ``sim`` before calling ``make()``, so that its World is freed before
    the new one is allocated (kernels compile once per layout and switch set). SceneError if a value is
    invalid."""
    scene = scene_with(sim.scene, dict(changes))
    state, arch, timer, tumble = sim.checkpoint(), sim.arch, sim.timer, sim.tumble
    coast, track = sim.coast, sim.track_changes

    def make():
        new = Simulation(scene, arch=arch, timer=timer, tumble=tumble, track_changes=track)
        new.restore(state)
        new.coast = coast
        return new

    return make
