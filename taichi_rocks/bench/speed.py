"""2. Speed against peers: the full step for N rocks x T rear tires, where its time goes (each pass timed
inside real steps by the engine's timing hook, and each called on its own), the peers on the same state, the
fixed costs of a launch, and what each effect costs (step with it on - step with it off, interleaved)."""

import numpy as np
import taichi as ti

from ..config.scene import scene_with
from ..engine import probes
from ..engine.world import FLYING
from .config import Config
from .measure import (Built, in_step_profile, launched_ids, n_flying, separate_passes_ms, stats, time_calls,
                      timed_call)
from .peers import kdtree_query, numpy_brute


def reorder_cost(sim, reps: int = 3):
    if not sim.plan.reorder_every:
        return None
    return time_calls(lambda: probes.reorder(sim), reps, warmup=1)["median_ms"]


def _peer_state(sim) -> dict:
    """The rocks and the rear-tire rays of the step just taken, float32, in the local frame."""
    r = sim.rock_arrays()  # every rock by id, wherever it is kept (active list or tiles)
    f32 = lambda f: np.ascontiguousarray(r[f], np.float32)
    return {"pos": f32("pos"), "vel": f32("vel"), "rad": f32("radius"), "hit_step": r["hit_step"],
            "phase": r["phase"], "rays": (sim.tire_rays() - sim.origin).astype(np.float32),
            "r_max": float(sim.scene.bed.rock_radius[1]), "step": sim.step_count}


def _peer_checks(s: dict, floor, warp) -> dict:
    """Do the peers find what the step found? (and load the floor and Warp with this state)"""
    ref = numpy_brute(s["pos"], s["rad"], s["rays"])
    ref_ids = np.flatnonzero(ref)
    now = np.flatnonzero(s["hit_step"] == s["step"])
    check = {"numpy_hits": int(len(ref_ids)), "taichi_launched_this_step": int(len(now)),
             "taichi_launched_subset_of_geometric_hits": bool(np.all(ref[now])),
             "geometric_hits_not_launched_are_flying": bool(np.all(s["phase"][np.setdiff1d(ref_ids, now)] == FLYING))}
    kd = kdtree_query(s["pos"], s["rad"], s["rays"], s["r_max"])
    check["kdtree_equals_numpy"] = bool(np.array_equal(np.sort(kd), ref_ids))
    floor.load(s["pos"], s["vel"])
    if warp is not None:
        warp.prepare(s["pos"], s["rad"], s["rays"], s["r_max"])
        warp.run()
        check["warp_sym_diff_vs_numpy"] = int(len(np.setxor1d(warp.hit_ids(), ref_ids)))
    return check


def _step_and_peers(built: Built, e: dict, cfg: Config, floor, warp, prog) -> dict:
    """One more step, then the peers on exactly this state (same rocks, same rays); the step, the floor and
    Warp timed interleaved: rounds of (m steps, 2 floor passes, 1-2 Warp runs)."""
    n, t_rear = e["n"], e["t"]
    built.sim.step()
    ti.sync()
    s = _peer_state(built.sim)
    p = {"check": _peer_checks(s, floor, warp)}
    rounds = 5
    m = max(2, cfg.reps // rounds)
    st, fl, wa = [], [], []
    floor.run()
    for _ in range(rounds):
        st += built.step_timed(m)
        for _ in range(2):
            fl.append(timed_call(floor.run))
        if warp is not None:
            for _ in range(2 if n <= 100_000 else 1):
                wa.append(timed_call(warp.run))
    e["step_stats"] = stats(st)
    e["step_ms"] = e["step_stats"]["median_ms"]
    p["floor_ms"] = stats(fl)["median_ms"]
    p["warp_ms"] = stats(wa)["median_ms"] if wa else None
    prog(f"step N={n} T={t_rear}")
    pos, rad, rays, r_max = s["pos"], s["rad"], s["rays"], s["r_max"]
    p["numpy_ms"] = time_calls(lambda: numpy_brute(pos, rad, rays), cfg.numpy_reps, warmup=0)["median_ms"]
    p["kdtree_ms"] = time_calls(lambda: kdtree_query(pos, rad, rays, r_max), cfg.kdtree_reps, warmup=0)["median_ms"]
    prog(f"numpy, cKDTree N={n} T={t_rear}")
    return p


def grid_entry(built: Built, cfg: Config, floor, warp, prog, record_hits: bool) -> dict:
    """One (N, T) of the speed grid: build, k steps (their launched ids, for the hash study), the passes,
    then the step against its peers."""
    sim = built.sim
    n, t_rear = sim.n_rocks, len(sim.fleet.splashing) * 2
    e = {"n": n, "t": t_rear, "table_size": int(sim.table_size), "cell_size_m": float(sim.cell_size),
         "reorder_every": int(sim.plan.reorder_every)}
    first = built.step_timed(cfg.k_hits)
    e["launched_after_k"] = launched_ids(sim).tolist() if record_hits else None
    e["build_s"] = built.ctor_s + first[0]
    built.step_timed(cfg.warm)
    e["in_step"] = in_step_profile(sim, max(3, cfg.pass_reps))
    if cfg.passes_all or (n, t_rear) == tuple(cfg.main):
        e["separate_passes_ms"] = separate_passes_ms(sim, cfg.pass_reps)
    else:
        e["separate_passes_ms"] = {}
    e["reorder_ms"] = reorder_cost(sim)
    prog(f"passes N={n} T={t_rear}")
    p = _step_and_peers(built, e, cfg, floor, warp, prog)
    e["n_flying"] = n_flying(sim)
    e["peers"] = p
    e["ratios"] = {"numpy_over_step": p["numpy_ms"] / e["step_ms"], "kdtree_over_step": p["kdtree_ms"] / e["step_ms"],
                   "step_over_floor": e["step_ms"] / p["floor_ms"],
                   "step_over_warp": e["step_ms"] / p["warp_ms"] if p["warp_ms"] else None}
    e["_built"] = built
    return e


@ti.kernel
def _empty_kernel():
    pass


def launch_overheads(sim) -> dict:
    """Fixed cost of a kernel call on this machine: an empty kernel, and the rock pass over zero rocks with
    every part off; plus the host part of a step (vehicle poses, rays)."""
    out = {"empty_kernel_ms": time_calls(_empty_kernel, 50, warmup=2)["median_ms"]}
    call = probes.rock_pass_call(sim)
    with probes.active_rocks(sim, 0):
        out["rock_pass_zero_rocks_ms"] = time_calls(call, 50, warmup=2)["median_ms"]
    t, fleet = sim.time, sim.fleet
    out["vehicle_poses_and_rays_ms"] = time_calls(lambda: fleet.rear_tires(fleet.poses(t + 0.01)), 20,
                                                  warmup=1)["median_ms"]
    return out


def ab_steps(built: Built, scene_a, scene_b, rounds: int, m: int) -> tuple:
    """Step times of ``built`` under two scenes, interleaved (``rounds`` x ``m`` steps each, after compiling
    b), so that drifting machine load hits both alike; each switch rebuilds the simulation from the other
    scene, carrying on from where it was (Built.rebuild). Ends on scene b."""
    built.rebuild(scene_b)
    built.step_timed(2)  # compile
    a, b = [], []
    for _ in range(rounds):
        built.rebuild(scene_a)
        a += built.step_timed(m)
        built.rebuild(scene_b)
        b += built.step_timed(m)
    return a, b


EFFECT_VARIANTS = {"gravity off": {"effects.gravity": False}, "drag none": {"effects.drag": "none"},
                   "ground none": {"effects.ground": "none"}, "recycle off": {"effects.recycle": False}}


def effects_costs(main: Built, bed_only: Built, cfg: Config, prog) -> dict:
    """Cost of each effect = step with it on - step with it off, measured interleaved (A, B, A, B, ...) on
    the same rocks so that drift cancels; the splash cost comes from a bed-only scene."""
    scene0 = main.sim.scene
    rounds, m = 3, max(2, cfg.reps // 3)
    base_all, out = [], {}
    for name, ov in EFFECT_VARIANTS.items():
        if name not in cfg.effects:
            continue
        a, b = ab_steps(main, scene0, scene_with(scene0, ov), rounds, m)
        base_all += a
        ma, mb = 1e3 * float(np.median(a)), 1e3 * float(np.median(b))
        out[name] = {"step_ms": mb, "effect_cost_ms": ma - mb, "baseline_ms": ma}
        prog(f"effect {name}")
    if out:
        main.rebuild(scene0)
    if not base_all:
        base_all = main.step_timed(cfg.reps)
    base = 1e3 * float(np.median(base_all))
    res = {"all on (default)": {"step_ms": base}}
    res.update(out)
    bed_only.step_timed(cfg.warm)
    scene_b = bed_only.sim.scene
    a, b = ab_steps(bed_only, scene_b, scene_with(scene_b, {"effects.recycle": False}), rounds, m)
    bed_ms, off = 1e3 * float(np.median(a)), 1e3 * float(np.median(b))
    res["splash off (bed only: recycle)"] = {"step_ms": bed_ms, "effect_cost_ms": base - bed_ms}
    res["everything off (host work only)"] = {"step_ms": off, "effect_cost_ms": None}
    res["recycle alone (bed only - everything off)"] = {"step_ms": None, "effect_cost_ms": bed_ms - off}
    res["n_flying_during_measurement"] = n_flying(main.sim)
    prog("effects")
    return res
