"""Changing a running simulation's settings: the engine's face for the view's panel (app/view.py).

Two kinds of scene keys, by how they reach the kernels:

* runtime keys (:data:`RUNTIME_KEYS`) are only numbers in ``World.par`` (engine/setup.py ``scene_params``;
  the tread model's ``tread_params``): :func:`set_runtime` validates a changed Scene (``scene_with``: the same
  ranges and messages as a scene file), packs its parameters again and uploads them; the next step uses them.
  Nothing is recompiled and the rocks keep their state.
* switches (:data:`SWITCH_KEYS`) are read by the kernels at compile time (config/plan.py, ``ti.static``):
  :func:`rebuilder` takes a checkpoint of the simulation and returns a function that builds a Simulation of
  the changed scene and restores the checkpoint into it (same rocks, clock and origin; a World of the same
  layout comes back from the pool, engine/world.py ``acquire``, once the old Simulation is gone).
"""

from __future__ import annotations

import gc
import math

import numpy as np

from ..config.plan import Plan
from ..config.scene import scene_with
from .setup import scene_params
from .simulation import Simulation
from .world import Par

__all__ = ["RUNTIME_KEYS", "SWITCH_KEYS", "set_runtime", "runtime_values", "scene_value", "rebuilder"]

# key -> (Par index or pair of indices, factor from the scene's unit to the kernels')
_DEG = math.pi / 180.0
RUNTIME_KEYS = {
    "world.gravity": (Par.GRAVITY, 1.0),
    "world.wetness": (Par.WETNESS, 1.0),
    "world.restitution": (Par.RESTITUTION, 1.0),
    "world.ground_friction": (Par.GROUND_FRICTION, 1.0),
    "world.rest_speed": (Par.REST_SPEED, 1.0),
    "launch.release_angle": ((Par.ANGLE_MIN, Par.ANGLE_MAX), _DEG),
    "launch.spread": (Par.SPREAD, _DEG),
    "launch.groove": (Par.GROOVE, 1.0),
    "launch.grip": (Par.GRIP, 1.0),
    "launch.grip_relax": (Par.GRIP_RELAX, _DEG),
    "launch.grip_spread": (Par.GRIP_SPREAD, 1.0),
    "launch.adhesion": (Par.ADHESION, 1.0),
    "launch.transfer": (Par.TRANSFER, 1.0),
}
# switches a Simulation compiles in, and their choices (a new Simulation each: see the module docstring)
SWITCH_KEYS = {
    "sim.integrator": ("symplectic_euler", "heun", "rk4"),
    "effects.drag": ("none", "linear", "quadratic"),
    "effects.ground": ("none", "stop", "bounce"),
    "effects.gravity": (False, True),
    "effects.fenders": (False, True),
}


def set_runtime(sim, values: dict):
    """Set runtime keys (dotted scene keys of :data:`RUNTIME_KEYS`, scene units) of ``sim`` at once; return
    the changed Scene (also ``sim.scene``). SceneError if a value is out of its range, ValueError for a key
    that is not a runtime key."""
    other = sorted(set(values) - set(RUNTIME_KEYS))
    if other:
        raise ValueError(f"not a runtime key: {', '.join(other)} (runtime keys: {', '.join(RUNTIME_KEYS)})")
    scene = scene_with(sim.scene, dict(values))
    if Plan.from_scene(scene) != sim.plan:  # cannot happen for these keys; a guard for new ones
        raise ValueError("these values change what the kernels compile: build a new Simulation")
    par, _ = scene_params(scene, sim.plan, sim._sizing, ground_z=scene.world.ground_z - sim.origin[2])
    sim.scene = scene
    sim._par = par  # what restore() uploads again
    sim.world.par.from_numpy(par.astype(sim.world.np_real()))  # ipar (rock and table counts) stays as it is
    return scene


def scene_value(scene, key: str):
    """The value of a dotted key of the tables (e.g. "world.wetness") in ``scene``; pairs as lists."""
    node = scene
    for part in key.split("."):
        node = getattr(node, part)
    return list(node) if isinstance(node, tuple) else node


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
    ``make()``, which builds the Simulation of the changed scene (same arch and timer) continuing from the
    checkpoint. Drop every reference to ``sim`` before calling ``make()``, so that its World goes back to the
    pool and the new one reuses it when the layout allows (no new fields; kernels compiled once per switch
    set). SceneError if a value is invalid."""
    scene = scene_with(sim.scene, dict(changes))
    state, arch, timer = sim.checkpoint(), sim.arch, sim.timer
    coast = sim.coast

    def make():
        gc.collect()
        new = Simulation(scene, arch=arch, timer=timer)
        new.restore(state)
        new.coast = coast
        return new

    return make
