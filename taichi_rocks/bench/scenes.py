"""The benchmark's scenes, built from the default scene by overrides: the fleet scene of the speed study (N
rocks, T rear tires spread over the bed) and the lanes scene of the accuracy study (one vehicle per speed, each
in its own lane, over a bed that stays put)."""

from __future__ import annotations

import math

import numpy as np

from ..config.scene import parse_scene, scene_with
from ..engine.params import drag_coefficients
from .config import TAU_LINEAR, Config

# The studies of passes and accuracy run "full" stepping (its passes can be timed and probed one by one,
# engine/probes.py); the speed and activity studies set the stepping they measure.
BASE = {"name": "bench", "seed": 3, "sim": {"stepping": "full"}, "vehicle": [{"name": "player"}]}
LINEAR_RADIUS = 0.03  # m: the rock whose Stokes time constant is TAU_LINEAR in the lanes scene
LANES_DENSITY = 2600.0  # kg/m^3


def base_scene():
    return parse_scene(dict(BASE), source="<bench>", default_name="bench")


def _fleet_slots(k: int, radius: float) -> list:
    """Body centres of k vehicles spread over a bed of this radius (the first at the centre)."""
    reach = 0.7 * radius
    cands = [(x, y) for x in np.arange(-28.0, 28.1, 7.0) for y in np.arange(-27.0, 27.1, 3.0)
             if math.hypot(x, y) <= reach]
    cands.sort(key=lambda p: (math.hypot(*p), p[0], p[1]))
    if len(cands) < k:
        raise ValueError(f"{k} vehicles do not fit a bed of radius {radius} m")
    return cands[:k]


def fleet_scene(n: int, t_rear: int, radius: float, overrides=None, speed: float = 25.0, spread=None):
    """N rocks, T/2 splashing vehicles spread over the bed, all at ``speed`` m/s along +x (the bed follows the
    first; 0: a parked fleet). ``spread``: the bed radius the vehicles are spread as for (default: the bed's), so
    that beds of different radii can carry the same formation."""
    k = max(1, t_rear // 2)
    vehicles = [{"name": "player" if i == 0 else f"v{i}",
                 "path": {"points": [[float(x), float(y)], [float(x) + 5000.0, float(y)]], "speed": float(speed)}}
                for i, (x, y) in enumerate(_fleet_slots(k, radius if spread is None else spread))]
    s = scene_with(base_scene(), {"name": f"bench-n{n}-t{2 * k}", "bed.rocks": int(n), "bed.radius": float(radius),
                                  "vehicle": vehicles})
    return with_overrides(s, overrides or {})


def with_overrides(scene, overrides: dict):
    """``scene_with``, where a table size may be given per rock ("0.5N": half the rock count)."""
    fixed = {}
    for k, v in overrides.items():
        if isinstance(v, str) and v.endswith("N") and k.endswith("table_size"):
            v = max(1, int(round(float(v[:-1]) * scene.bed.rocks)))
        fixed[k] = v
    return scene_with(scene, fixed) if fixed else scene


def lane_y(i: int, count: int) -> float:
    return 3.0 * (i - 0.5 * (count - 1))


def _linear_drag_viscosity(scene, radius: float, tau: float) -> float:
    """The air viscosity giving a rock of this radius the Stokes time constant tau (tau = r^2 / LINEAR_DRAG):
    the linear drag coefficient of engine/params.py is proportional to the viscosity."""
    per_viscosity = drag_coefficients(scene_with(scene, {"world.air_viscosity": 1.0}))[0]
    return radius * radius / tau / per_viscosity


def probe_scene(cfg: Config, overrides=None):
    """Lanes: a parked, non-splashing anchor that the bed follows, and one vehicle per speed in its own lane,
    straight along +x; no recycling, no ground contact. The linear-drag viscosity makes tau = 1 s for r = 3 cm."""
    x0 = -0.5 * max(cfg.speeds) * cfg.run_time
    vehicles = [{"name": "anchor", "splash": False, "path": {"points": [[0.0, 0.0], [1.0, 0.0]], "speed": 0.0}}]
    for i, v in enumerate(cfg.speeds):
        y = lane_y(i, len(cfg.speeds))
        vehicles.append({"name": f"lane{i}", "path": {"points": [[x0, y], [x0 + 5000.0, y]], "speed": float(v)}})
    dense = scene_with(base_scene(), {"bed.density": LANES_DENSITY})
    mu = _linear_drag_viscosity(dense, LINEAR_RADIUS, TAU_LINEAR)
    s = scene_with(base_scene(), {"name": "bench-probe", "seed": 7, "world.air_viscosity": mu,
                                  "bed.rocks": cfg.probe_n, "bed.radius": cfg.probe_radius,
                                  "bed.density": LANES_DENSITY, "bed.follow": "anchor", "camera.follow": "anchor",
                                  "effects.recycle": False, "effects.ground": "none", "vehicle": vehicles})
    return with_overrides(s, overrides or {})
