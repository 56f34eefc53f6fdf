"""Proposed presets (``[sim] accuracy = ...``): the cheapest measured setting meeting each preset's targets.

Targets (config.py PRESET_TARGETS): (1) error = max of the flight error over a 2 s flight of the
default-physics cases (gravity only, quadratic drag) and the f32/f64 error of a flight 100 km from the origin
with the floating origin (measured); (2) recall of true tire contacts at 60 m/s (swept: measured; single ray:
from a recall-vs-displacement-per-ray fit); (3) launch-time bound: a rock is launched at the end of the step in
which the tire reaches it, so its path can be off by up to v_launch dt, v_launch <= 30 m/s (modelled).
Cost = main-scene step (ray and swept measured interleaved) + the integrator's extra flight cost with every
rock flying (worst case), x the f64/f32 step ratio of the lanes scene, / dt.
"""

from __future__ import annotations

import math

import numpy as np

from ..config.keys import choices
from ..config.presets import PRESETS
from ..config.scene import scene_with
from .config import PRESET_SPEED, PRESET_TARGETS, V_LAUNCH_MAX, Config
from .detection import detection_runs
from .measure import Built
from .scenes import probe_scene

DETECTIONS = (("ray", 1), ("ray", 2), ("ray", 4), ("ray", 8), ("swept", 1))


def recall_model(det: dict):
    """Recall of single-ray detection as a function of the ray's displacement per evaluation s (m),
    from the ray and ray-with-substeps runs; monotone non-increasing; 1/s tail beyond the data."""
    pts = []
    for key in ("ray", "ray x4 substeps"):
        if key in det:
            for row in det[key]["per_speed"]:
                if row["contacts"]:
                    pts.append((row["step_displacement_m"], row["recall"]))
    pts.sort()
    s = np.array([p[0] for p in pts])
    r = np.minimum.accumulate(np.array([p[1] for p in pts]))

    def model(x):
        if not len(s):
            return float("nan")
        if x <= s[0]:
            return float(r[0])
        if x >= s[-1]:
            return float(r[-1] * s[-1] / x)
        return float(np.interp(math.log(x), np.log(s), r))

    return model


def _inputs(res: dict) -> dict:
    """What the choice needs from the measurements."""
    acc = res["accuracy"]
    det, prec = acc["detection"]["modes"], acc["precision"]["configs"]
    fc = acc["flight_cost"]["ms_per_step"]
    se = fc.get("symplectic_euler", {}).get("quadratic")
    err = {}
    for row in acc["integrator_dt"]["rows"]:
        if row["case"] in ("gravity", "quadratic"):
            key = (row["precision"], row["integrator"], row["dt"])
            err[key] = max(err.get(key, 0.0), row["max_error_m"])
    return {"model": recall_model(det), "cost": acc["preset_costs"], "err": err,
            "integ_extra": {i: max(0.0, fc[i]["quadratic"] - se) for i in fc if se is not None and "quadratic" in fc[i]},
            "swept_recall": min((r["recall"] for r in det["swept"]["per_speed"] if r["contacts"]), default=float("nan")),
            "far": max(acc["precision"]["distances_m"]),
            "prec_err": {p: prec[f"{p} floating"]["max_error_m"][-1] for p in choices("sim.precision")
                         if f"{p} floating" in prec}}


def _step_cost(x: dict, detection: str, substeps: int, integ: str, p: str):
    """ms per step of a candidate, or None if it cannot be costed."""
    cost = x["cost"]
    c = cost["step_ms"].get(detection)
    if c is None:
        return None
    c += x["integ_extra"].get(integ, 0.0)
    if substeps > 1:
        if cost["substep_ms_per_extra"] is None:
            return None
        c += cost["substep_ms_per_extra"] * (substeps - 1)
    return c * cost["f64_factor"] if p == "f64" else c


def _best(x: dict, name: str, e_target: float, r_target: float, q_target: float):
    best = None
    for (p, integ, dt), e in x["err"].items():
        total_e = max(e, x["prec_err"].get(p, 0.0))
        if total_e > e_target or V_LAUNCH_MAX * dt > q_target * (1 + 1e-9):
            continue
        for detection, substeps in DETECTIONS:
            recall = x["swept_recall"] if detection == "swept" else x["model"](PRESET_SPEED * dt / substeps)
            c = _step_cost(x, detection, substeps, integ, p) if recall >= r_target else None
            if c is None:
                continue
            per_s = c / dt
            rank = per_s * (1.05 if p == "f64" else 1.0)  # prefer f32 unless f64 is clearly cheaper
            if best is None or rank < best["_rank"]:
                best = {"name": name, "target_flight_error_m": e_target, "target_recall": r_target,
                        "target_launch_time_bound_m": q_target, "launch_time_bound_m": V_LAUNCH_MAX * dt,
                        "integrator": integ, "dt": dt, "detection": detection, "substeps": substeps,
                        "precision": p, "origin": "floating", "flight_error_m": e,
                        "precision_error_far_m": x["prec_err"].get(p), "far_m": x["far"], "error_m": total_e,
                        "recall_at_60": recall, "recall_source": "measured" if detection == "swept" else "modelled",
                        "step_ms": c, "ms_per_simulated_s": per_s, "_rank": rank}
    if best:
        best.pop("_rank")
    return best


def fixed_preset(x: dict, name: str, p: dict) -> dict:
    """A preset set by its purpose, not chosen by targets ("game": one step per 60 Hz frame), measured as the
    chosen ones are: flight error at its (precision, integrator, dt), recall (patch detection finds what swept
    finds and more: swept's measured recall is its bound), launch-time bound and cost."""
    detection = "swept" if p["detection"] in ("swept", "patch") else p["detection"]
    e = x["err"].get((p["precision"], p["integrator"], p["dt"]))
    c = _step_cost(x, detection, 1, p["integrator"], p["precision"])
    recall = x["swept_recall"] if detection == "swept" else x["model"](PRESET_SPEED * p["dt"])
    return {"name": name, "target_flight_error_m": None, "target_recall": None, "target_launch_time_bound_m": None,
            "launch_time_bound_m": V_LAUNCH_MAX * p["dt"], "integrator": p["integrator"], "dt": p["dt"],
            "detection": p["detection"], "substeps": 1, "precision": p["precision"], "origin": "floating",
            "flight_error_m": e, "precision_error_far_m": x["prec_err"].get(p["precision"]), "far_m": x["far"],
            "error_m": None if e is None else max(e, x["prec_err"].get(p["precision"], 0.0)),
            "recall_at_60": recall, "recall_source": "measured, swept" if detection == "swept" else "modelled",
            "step_ms": c, "ms_per_simulated_s": None if c is None else c / p["dt"]}


def choose_presets(res: dict) -> list:
    x = _inputs(res)
    out = []
    for name, e_target, r_target, q_target in PRESET_TARGETS:
        best = _best(x, name, e_target, r_target, q_target)
        out.append(best or {"name": name, "target_flight_error_m": e_target, "target_recall": r_target,
                            "target_launch_time_bound_m": q_target,
                            "none": "no measured setting meets this target"
                                    + ("" if any(k[0] == "f64" for k in x["err"]) else " (f64 flights are measured "
                                                                                      "in the full run only)")})
    out.append(fixed_preset(x, "game", PRESETS["game"]))
    return out


def preset_costs(main: Built, cfg: Config, det: dict, prog) -> dict:
    """Step cost of the main scene with ray and with swept detection, interleaved (each switch rebuilds the
    simulation from the changed scene on the same fields); the integrators' extra cost is taken from the
    flight pass with every rock flying (worst case)."""
    scene0 = main.sim.scene
    scenes = {d: scene_with(scene0, {"sim.detection": d}) for d in ("ray", "swept")}
    times = {d: [] for d in scenes}
    m = max(2, cfg.reps // 4)
    for d, sc in scenes.items():
        main.rebuild(sc)
        main.step_timed(2)  # compile
    for _ in range(4):
        for d, sc in scenes.items():
            main.rebuild(sc)
            times[d] += main.step_timed(m)
    prog("preset costs")
    main.rebuild(scene0)
    out = {d: 1e3 * float(np.median(ts)) for d, ts in times.items()}
    t_probe = det["ray"]["tires"]
    t_main = len(main.sim.fleet.splashing) * 2
    extra = None
    if "ray x4 substeps" in det:
        extra = max(0.0, (det["ray x4 substeps"]["step_ms"] - det["ray"]["step_ms"]) / 3.0 * t_main / max(1, t_probe))
    f64 = det["ray (f64)"]["step_ms"] / det["ray"]["step_ms"]
    return {"step_ms": out, "substep_ms_per_extra": extra, "f64_factor": f64, "n": main.sim.n_rocks,
            "t": t_main, "note": "main scene step (symplectic Euler) + the integrator's extra flight cost with "
                                 "every rock flying; substeps and f64 scaled from the lanes scene"}


def validate_presets(presets: list, cfg: Config, arch: str, prog) -> None:
    """Run the lanes scene with each preset's settings and measure its recall at every speed."""
    for p in presets:
        if "integrator" not in p:
            continue
        ov = {"sim.dt": p["dt"], "sim.integrator": p["integrator"], "sim.detection": p["detection"],
              "sim.substeps": p["substeps"], "sim.precision": p["precision"]}
        b = Built(probe_scene(cfg, ov), arch, f"preset {p['name']}")
        r = detection_runs({p["name"]: b}, cfg, lambda *a: None)[p["name"]]
        top = [x for x in r["per_speed"] if x["speed_m_s"] == max(cfg.speeds)]
        p["validated_recall_at_60"] = top[0]["recall"] if top else None
        p["validated_recall_all_speeds"] = [x["recall"] for x in r["per_speed"]]
        prog(f"validate {p['name']}")
