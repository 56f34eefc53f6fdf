"""1b. Detection x vehicle speed: recall of true tire-rock contacts in the lanes scene.

Six lanes, one vehicle per speed, drive straight over a bed at rest (no recycling, no ground contact: a
launched rock never lands and is never hit twice). Reference: the analytic sweep of each rear tire's ray over
its straight path between t = 0 and the end of the run, a rectangle (the path is horizontal, the ray
vertical); a rock is a true contact iff its centre lies within its radius of it. Recall = launched true
contacts / true contacts. The lanes simulations (ray, ray in f64, swept, ray with 4 substeps) are stepped in
lockstep, so that a busy machine slows all alike and their step costs compare.
"""

from __future__ import annotations

import numpy as np

from .config import Config
from .measure import Built, launched_ids, stats
from .scenes import probe_scene

REFERENCE = ("Reference: analytic sweep - each rear tire's ray (centre to ground) swept along its straight "
             "path from t = 0 to the end of the run is a vertical rectangle; a rock resting at t = 0 is a "
             "true contact iff its centre is within its radius of that rectangle. Chosen over a small-dt "
             "swept run because it is exact and independent of the engine. Launched rocks never land "
             "(ground none) and the bed is not recycled, so each rock can be launched once. The four "
             "lanes simulations are stepped in lockstep, so their step costs are comparable.")


def rect_dist2(c, a0, a1, b0):
    """Squared distance of points c (n,3) to the parallelogram {a0 + u (a1 - a0) + v (b0 - a0)}, for
    orthogonal edges (a straight horizontal path and a vertical ray: a rectangle)."""
    e1, e2 = a1 - a0, b0 - a0
    l1, l2 = float(e1 @ e1), float(e2 @ e2)
    assert abs(float(e1 @ e2)) <= 1e-9 * max(l1 * l2, 1e-30) ** 0.5 + 1e-12
    d = c - a0
    u = np.clip(d @ e1 / l1, 0.0, 1.0) if l1 > 0 else np.zeros(len(c))
    v = np.clip(d @ e2 / l2, 0.0, 1.0) if l2 > 0 else np.zeros(len(c))
    q = a0 + u[:, None] * e1 + v[:, None] * e2
    return np.sum((c - q) ** 2, axis=1)


def t0_state(sim) -> dict:
    """Every rock (by id, wherever it is: the active list or a tile) and the rear tires at t = 0."""
    r = sim.rock_arrays()
    return {"ids": np.arange(sim.n_rocks), "world": r["pos"].astype(np.float64) + sim.origin,
            "radius": r["radius"].astype(np.float64), "tires0": sim.fleet.rear_tires(sim.fleet.poses(0.0))}


def detection_result(built: Built, t0: dict, times: list, cfg: Config, label: str) -> dict:
    """Recall per lane (speed) against the analytic sweep of each rear tire's ray over [0, t_end]."""
    sim = built.sim
    t1 = sim.fleet.rear_tires(sim.fleet.poses(sim.time))
    hit = set(launched_ids(sim).tolist())
    names = [sim.fleet.names[i] for i in sim.fleet.splashing]
    per_speed, all_ref = [], set()
    rad, ids = t0["radius"], t0["ids"]
    for li, v in enumerate(cfg.speeds):
        vi = names.index(f"lane{li}")
        ref = set()
        for side in (0, 1):
            tt = 2 * vi + side
            d2 = rect_dist2(t0["world"], t0["tires0"].center[tt], t1.center[tt], t0["tires0"].bottom[tt])
            ref |= set(ids[d2 <= rad * rad].tolist())
        all_ref |= ref
        found = len(ref & hit)
        per_speed.append({"speed_m_s": v, "contacts": len(ref), "found": found,
                          "recall": found / len(ref) if ref else float("nan"),
                          "step_displacement_m": v * sim.dt / max(1, sim.plan.substeps)})
    skip = min(3, max(0, len(times) - 1))
    st = stats(times[skip:])
    return {"mode": label, "dt": sim.dt, "substeps": sim.plan.substeps, "swept": sim.plan.swept,
            "per_speed": per_speed, "false_positives": len(hit - all_ref), "launched": len(hit),
            "steps": len(times), "step_ms": st["median_ms"], "step_stats": st, "n_rocks": sim.n_rocks,
            "tires": len(names) * 2}


def detection_runs(builds: dict, cfg: Config, prog) -> dict:
    """Run the lanes scenes in lockstep (one step of each in turn, so a busy machine slows all alike)."""
    t0 = {k: t0_state(b.sim) for k, b in builds.items()}
    steps = {k: int(round(cfg.run_time / b.sim.dt)) for k, b in builds.items()}
    times = {k: [] for k in builds}
    for s in range(max(steps.values())):
        for k, b in builds.items():
            if s < steps[k]:
                times[k] += b.step_timed(1)
    out = {k: detection_result(b, t0[k], times[k], cfg, k) for k, b in builds.items()}
    prog("detection runs")
    return out


def lanes(cfg: Config, arch: str, prog) -> tuple:
    """Build the lanes simulations and run the detection study on them; returns (detection results, the f32
    and f64 ray simulations (for the flights of 1a and 1c), build seconds per simulation)."""
    specs = [("ray", {}), ("ray (f64)", {"sim.precision": "f64"}), ("swept", {"sim.detection": "swept"})]
    if cfg.substeps_mode:
        specs.append(("ray x4 substeps", {"sim.substeps": 4}))
    builds = {}
    for key, ov in specs:
        builds[key] = Built(probe_scene(cfg, ov), arch, f"probe {key}")
        prog(f"build probe {key}")
    det = detection_runs(builds, cfg, prog)
    sims = {"f32": builds["ray"], "f64": builds["ray (f64)"]}
    build_s = {b.label: b.ctor_s + (b.first_step_s or 0.0) for b in builds.values()}
    return det, sims, build_s
