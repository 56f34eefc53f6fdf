"""1c. Precision x distance from the origin.

Launched rocks are flown 2 s with their positions stored as the engine stores them (local = world - origin:
origin 0 for ``origin = "world"``; for ``"floating"`` the bed centre rounded to 64 m steps from the bed's
start, here the world origin) in f32 and in f64; the error is the world position against an f64 flight launched at the origin (same integrator, dt and drag).
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.simulation import ORIGIN_SNAP
from .config import Config
from .flight import fly


def _launches() -> list:
    """(offset from the launch point reference, v0, r): a vehicle at 25 m/s, three release angles."""
    out = []
    spin = 25.0 * 1.15
    for k, (alpha, r) in enumerate(((10.0, 0.015), (22.0, 0.03), (35.0, 0.05))):
        a = math.radians(alpha)
        out.append((np.array([-1.45, 0.8 if k % 2 else -0.8, r]),
                    np.array([25.0 - spin * math.cos(a), 0.3 * (k - 1), 0.65 * spin * math.sin(a)]), r))
    return out


def _trajectories(sim, launches, distances) -> dict:
    """(origin, distance, launch) -> world position - (distance, 0, 0) over the flight, float64."""
    x0, v0, rr, keys = [], [], [], []
    for origin in ("world", "floating"):
        for d in distances:
            o = 0.0 if origin == "world" else round(d / ORIGIN_SNAP) * ORIGIN_SNAP
            for j, (off, v, r) in enumerate(launches):
                x0.append(np.array([d + off[0] - o, off[1], off[2]]))
                v0.append(v)
                rr.append(r)
                keys.append((origin, d, j, o))
    _, xs = fly(sim, np.array(x0), np.array(v0), np.array(rr), sim.dt, sim.plan.integrator, sim.plan.drag)
    return {(origin, d, j): x + np.array([o, 0.0, 0.0]) - np.array([d, 0.0, 0.0])
            for (origin, d, j, o), x in zip(keys, xs)}


def precision_runs(sims: dict, cfg: Config, prog) -> dict:
    """Flight of launched rocks stored as the engine stores them, at several distances from the origin."""
    launches = _launches()
    trajectories = {}
    for prec, sim in sims.items():
        for key, rel in _trajectories(sim, launches, cfg.distances).items():
            trajectories[(prec, *key)] = rel
        prog(f"precision {prec}")
    ref = {j: trajectories[("f64", "floating", 0.0, j)] for j in range(len(launches))}
    results = {}
    for prec in sims:
        for origin in ("world", "floating"):
            errs = [max(float(np.max(np.linalg.norm(trajectories[(prec, origin, d, j)] - ref[j], axis=1)))
                        for j in range(len(launches))) for d in cfg.distances]
            results[f"{prec} {origin}"] = {"precision": prec, "origin": origin, "max_error_m": errs}
    return {"distances_m": list(cfg.distances), "configs": results,
            "reference": "f64 flight launched at the origin (same integrator, dt, drag)",
            "note": "rock positions stored as the engine stores them (local = world - origin), flown by rock_pass; "
                    "origin shifts of the floating origin (exact multiples of 64 m) are not exercised"}
