"""What a sweep run measures: the metric registry (docs/sweeps.md).

A metric is one generator function of the run (worker.py's :class:`Run`: the Simulation, its scene, its folder
and its clock). It yields once before the run starts, ``EVERY_STEP`` to be resumed after every step (with
True) or nothing to be resumed only at the end; at the end it is resumed with False and returns its columns,
a flat dict of plain values (the order of the dict is the order of the columns)::

    def digest(run):
        yield                                  # nothing to do while the run steps
        return {"digest": state_digest(run.sim.state())}

A new metric is that function plus its line in METRICS.

* ``launch``: every launch followed from the ground to its apex and its landing (bench/launch.py's Tracker,
  statistics and bands): launches, apex percentiles (m above the resting height), release angles recovered
  from the launch velocity in the frame of the splashing vehicle whose rear axle is nearest (its speed
  along its heading and its slip), the shares the launch bands are stated on, and how many bands are met.
* ``timing``: the build (fields, first kernels), the first step (mostly compiling) and the ms per step after
  it, ``ti.sync()`` around each timed block; reading states for other metrics is not counted.
* ``digest``: the SHA-256 of the final state: every array of ``Simulation.state()`` by name, in sorted order,
  each as its name, dtype, shape and bytes (the same scene and seed give the same digest on any backend of
  the runner and any machine of the same arch).
* ``render``: the run rendered to a video (app/render.py ``render_scene``, its own simulation of the same
  scene, deterministic) in ``runs/<id>/render/``.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from ...bench.launch import BAND_TARGETS, Tracker, band_met, launch_stats, release_angles
from ..render import render_scene

EVERY_STEP = "every step"


def state_digest(state: dict) -> str:
    """SHA-256 over the state's arrays, sorted by name: name, dtype, shape and bytes of each."""
    h = hashlib.sha256()
    for name in sorted(state):
        a = np.ascontiguousarray(np.asarray(state[name]))
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def digest(run):
    yield
    return {"digest": state_digest(run.sim.state())}


def timing(run):
    yield
    clock = run.clock
    later = clock.steps - 1
    return {"build_s": clock.build_s, "first_step_s": clock.first_step_s,
            "ms_per_step": 1e3 * clock.later_s / later if later > 0 else math.nan, "steps": clock.steps}


def _launch_frames(scene, st: dict, prev: dict, dt: float, rocks: list) -> list:
    """Per new launch (rock indices ``rocks``): the launching vehicle's (forward speed, heading, slip), the
    splashing vehicle whose rear axle is nearest to the rock."""
    vehicles = [i for i, v in enumerate(scene.vehicles) if v.splash]
    if not vehicles or not rocks:
        return [(0.0, 0.0, 0.0)] * len(rocks)
    pos, head = st["vehicle_positions"][vehicles, :2], st["vehicle_headings"][vehicles]
    fwd = np.stack([np.cos(head), np.sin(head)], axis=1)
    axle = pos - 0.5 * np.array([scene.vehicles[i].wheelbase for i in vehicles])[:, None] * fwd
    moved = (pos - prev["vehicle_positions"][vehicles, :2]) if dt > 0 else np.zeros_like(pos)
    speed = np.einsum("ij,ij->i", moved, fwd) / dt if dt > 0 else np.zeros(len(vehicles))
    out = []
    for i in rocks:
        k = int(np.argmin(np.linalg.norm(axle - st["positions"][i, :2], axis=1)))
        out.append((float(speed[k]), float(head[k]), float(scene.vehicles[vehicles[k]].slip)))
    return out


def _angles(v: np.ndarray, frames: list, restitution: float) -> tuple:
    """Release angles (rad) and |v| / V of launches with velocities ``v`` (world) in their vehicles' frames."""
    alpha, ratio = np.zeros(len(v)), np.zeros(len(v))
    for j, (speed, head, slip) in enumerate(frames):
        c, s = math.cos(head), math.sin(head)
        local = np.array([[c * v[j, 0] + s * v[j, 1], -s * v[j, 0] + c * v[j, 1], v[j, 2]]])
        alpha[j] = release_angles(local, speed, restitution, slip)[0] if abs(speed) > 1e-9 else math.nan
        ratio[j] = np.linalg.norm(v[j]) / abs(speed) if abs(speed) > 1e-9 else math.nan
    return alpha, ratio


def launch(run):
    sim, scene = run.sim, run.scene
    prev = sim.state()
    tracker, frames = Tracker(prev), []
    while (yield EVERY_STEP):
        st = sim.state()
        known = set(map(id, tracker.open.values()))
        tracker.update(st, 0.0)
        fresh = [i for i, rec in tracker.open.items() if id(rec) not in known]
        frames += _launch_frames(scene, st, prev, st["time"] - prev["time"], fresh)
        tracker.step_done(st)
        prev = st
    rows = tracker.rows
    v = np.array([r["v"] for r in rows]).reshape(-1, 3)
    alpha, ratio = _angles(v, frames, scene.world.restitution)
    ok = np.isfinite(alpha)
    d = {"alpha": alpha[ok], "speed_ratio": ratio[ok], "radius": np.array([r["r"] for r in rows])[ok],
         "apex": np.array([r["apex"] for r in rows])[ok], "lost": np.array([r["lost"] for r in rows], bool)[ok],
         "behind": np.full(int(ok.sum()), np.nan), "launches_total": sim.launches_total}
    s = launch_stats(d)
    apex = d["apex"][~d["lost"]]
    out = {"launches": sim.launches_total, "followed": s["launches"], "lost_in_air": s["lost_in_air"],
           "apex_median_m": s["apex_median"], "apex_p95_m": s["apex_p95"],
           "apex_p99_m": float(np.percentile(apex, 99)) if len(apex) else math.nan, "apex_max_m": s["apex_max"],
           "alpha_median_deg": s["alpha_median_deg"], "alpha_mean_deg": s["alpha_mean_deg"],
           "alpha_p95_deg": float(np.degrees(np.percentile(d["alpha"], 95))) if len(d["alpha"]) else math.nan,
           "below_1_5": s["below_1_5"], "below_3": s["below_3"], "alpha_above_25": s["alpha_above_25"],
           "big_above_1": s["big_above_1"], "speed_ratio_max": s["speed_ratio_max"]}
    met = [band_met(s, key) for _, key, _, _ in BAND_TARGETS]
    out["bands_met"], out["meets_bands"] = int(sum(met)), bool(all(met))
    return out


def render(run):
    yield
    info = render_scene(run.scene, out_dir=run.out / "render", fmt="mp4", arch=run.arch, overwrite=True,
                        progress=False)
    return {"video": str(run.rel / "render" / f"{run.scene.name}.mp4"), "render_frames": info["frames"],
            "render_s": info["seconds"]}


# name -> metric; "impacts" (hits per km by vehicle and class) joins here as one more line
METRICS = {"launch": launch, "timing": timing, "digest": digest, "render": render}
