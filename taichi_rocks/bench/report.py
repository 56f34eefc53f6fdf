"""The benchmark's report (report.md: targets, presets, the accuracy sections 1a-1d, speed against peers,
build times) and its results as JSON (results.json: every number, private ``_`` keys left out).

Like every output of the project, the files are written atomically (output/atomic.py ``write_atomically``:
a temporary beside the final name, renamed when complete), and a study refuses an out folder that already
holds its outputs unless asked to overwrite them (:func:`check_out_dir`)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..config.keys import choices
from ..output.atomic import write_atomically
from .config import CASE_OF_DRAG, DRAGS, INTEGRATORS, PRESET_SPEED, TAU_LINEAR, V_LAUNCH_MAX
from .machine import was_busy


def _fmt(x, unit="", digits=3):
    if x is None:
        return "n/a"
    if isinstance(x, float) and not math.isfinite(x):
        return "nan"
    if isinstance(x, (int, np.integer)):
        return f"{x:,}{unit}"
    if x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e5):
        return f"{x:.{digits - 1}e}{unit}"
    return f"{x:.{digits}g}{unit}"


def _default_error(res):
    rows = [r for r in res["accuracy"]["integrator_dt"]["rows"] if r["precision"] == "f32"
            and r["integrator"] == "symplectic_euler" and abs(r["dt"] - 0.002) < 1e-12
            and r["case"] in ("gravity", "quadratic")]
    return max((r["max_error_m"] for r in rows), default=None)


def _default_recall(res):
    rows = res["accuracy"]["detection"]["modes"]["ray"]["per_speed"]
    top = [r["recall"] for r in rows if r["speed_m_s"] == max(x["speed_m_s"] for x in rows)]
    return top[0] if top else None


def _header(res: dict, plots: list) -> list:
    L = []
    m = res["machine"]
    L.append("# taichi-rocks benchmark\n")
    L.append(f"Mode **{res['config']['mode']}**, {res['elapsed_s']:.0f} s wall time, {res['started']}.\n")
    L.append(f"Machine: {m['cpu_model']}, {m['usable_cores']} usable cores ({m['logical_cores']} logical), "
             f"{m['memory_gb']} GB; Python {m['python']}; Taichi {m['taichi']} ({m['taichi_arch']}, threads "
             f"{m['taichi_threads']}); NumPy {m['numpy']}; SciPy {m['scipy']}; "
             f"Warp {res['warp'].get('version') or 'not available'}.\n")
    la0, la1 = res.get("load_average_start"), res.get("load_average_end")
    if la0 and la1:
        busy = was_busy(la0, la1, m["usable_cores"])
        L.append(f"Load average (1, 5, 15 min) at the start {la0}, at the end {la1}"
                 + (": **the machine was busy with other work; timings are noisy**." if busy else ".") + "\n")
    if not res["warp"]["available"]:
        L.append(f"> **warp-lang is not installed** ({res['warp']['error']}): the Warp peer was skipped. "
                 "Install it with `pip install warp-lang` (the `bench` extra).\n")
    L.append("Timings: warm-up (compile) first, then the median of repeated calls with `ti.sync()` around the "
             "timed region. Warp runs on the CPU (its CPU kernels are single-threaded); NumPy/SciPy on the CPU "
             "(cKDTree queries with all cores).\n")
    return L


def _targets(res: dict, plots: list) -> list:
    L = []
    L.append("## Targets\n")
    L.append("| target | measured | limit | met | detail | at |")
    L.append("|---|---|---|---|---|---|")
    for t in res["targets"]:
        met = {True: "**met**", False: "**NOT met**", None: "-"}[t["met"]]
        L.append(f"| {t['target']} | {_fmt(t['value'])} | {_fmt(t['limit'])} | {met} | {t['detail']} | {t['at']} |")
    L.append("")
    return L


def _presets(res: dict, plots: list) -> list:
    L = []
    L.append("## Proposed presets (`[sim] accuracy = ...`)\n")
    L.append("The cheapest measured setting meeting all of: (1) error = max of the flight error over a 2 s flight "
             "of the default-physics cases (gravity only, quadratic drag) and the f32/f64 error of a flight 100 km "
             f"from the origin with the floating origin (measured); (2) recall of true tire contacts at "
             f"{PRESET_SPEED:g} m/s (swept: measured; single ray: from the recall-vs-displacement-per-ray fit of "
             "section 1b); (3) launch-time bound: a rock is launched at the end of the step in which the tire "
             f"reaches it, so its path can be off by up to v_launch dt with v_launch <= {V_LAUNCH_MAX:g} m/s "
             "(modelled, not measured). Candidates: the integrator x dt grid of 1a (dt <= 0.02 s), detection ray "
             "x1/2/4/8 or swept, f32 or f64 with the floating origin. Cost = main-scene step (measured with ray and "
             "swept, interleaved, the simulation rebuilt from the changed scene at each switch) + the integrator's "
             "extra flight cost with every rock flying (worst case), x the f64/f32 step ratio of the lanes scene, "
             "/ dt. Not covered: ground contact and sliding at large dt.\n")
    L.append("| preset | targets: error / recall / launch bound | integrator | dt (s) | detection | precision, origin | "
             "flight error (m) | f32/f64 error far (m) | recall @60 | validated recall @60 | launch bound (m) | "
             "ms/step | ms per simulated s |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for p in res["accuracy"]["presets"]:
        tg = ("one step per 60 Hz frame" if p["target_recall"] is None else
              f"{_fmt(p['target_flight_error_m'])} m / {p['target_recall']} / "
              f"{_fmt(p.get('target_launch_time_bound_m'))} m")
        if "integrator" not in p:
            L.append(f"| {p['name']} | {tg} | {p['none']} |||||||||||")
            continue
        det = p["detection"] + (f" x{p['substeps']}" if p["substeps"] > 1 else "")
        L.append(f"| **{p['name']}** | {tg} | {p['integrator']} | {p['dt']:g} | {det} | {p['precision']}, "
                 f"{p['origin']} | {_fmt(p['flight_error_m'])} | {_fmt(p['precision_error_far_m'])} | "
                 f"{_fmt(p['recall_at_60'])} ({p['recall_source']}) | {_fmt(p.get('validated_recall_at_60'))} | "
                 f"{_fmt(p['launch_time_bound_m'])} | {_fmt(p['step_ms'])} | {_fmt(p['ms_per_simulated_s'])} |")
    d0 = res["accuracy"]["preset_costs"]
    L.append(f"\nFor comparison, the engine defaults (symplectic Euler, dt 0.002 s, ray x1, f32 floating): flight error "
             f"{_fmt(_default_error(res))} m, recall at 60 m/s "
             f"{_fmt(_default_recall(res))}, {_fmt(d0['step_ms'].get('ray'))} ms/step, "
             f"{_fmt(d0['step_ms'].get('ray', float('nan')) / 0.002)} ms per simulated s.\n")
    return L


def _integrators(res: dict, plots: list) -> list:
    L = []
    acc = res["accuracy"]["integrator_dt"]
    L.append("## 1a. Integrator x dt\n")
    L.append(f"![integrators]({plots[0]})\n")
    L.append("Closed forms: " + "; ".join(f"{k}: {v}" for k, v in acc["closed_forms"].items()) + ". "
             f"Linear drag uses air viscosity raised so that tau = {TAU_LINEAR:g} s for a 3 cm rock (with the "
             "default 1.81e-5 Pa s tau is about 2 h and the drag is invisible); the other cases use the default "
             "physics. Errors are sampled every 0.1 s.\n")
    dts = sorted({r["dt"] for r in acc["rows"]})
    for prec in sorted({r["precision"] for r in acc["rows"]}):
        L.append(f"Max position error (m), {prec}:\n")
        L.append("| case | integrator | " + " | ".join(f"dt {d:g}" for d in dts) + " |")
        L.append("|---|---|" + "---|" * len(dts))
        for case in (CASE_OF_DRAG[d] for d in DRAGS):
            for integ in INTEGRATORS:
                vals = {r["dt"]: r["max_error_m"] for r in acc["rows"]
                        if r["precision"] == prec and r["case"] == case and r["integrator"] == integ}
                L.append(f"| {case} | {integ} | " + " | ".join(_fmt(vals.get(d)) for d in dts) + " |")
        L.append("")
    fc = res["accuracy"]["flight_cost"]
    L.append(f"Flight pass alone with all {fc['n_rocks']:,} rocks flying (ms per step): " + "; ".join(
        f"{i}: " + ", ".join(f"drag {d} {v:.2f}" for d, v in dd.items()) for i, dd in fc["ms_per_step"].items()) + "\n")
    return L


def _detection(res: dict, plots: list) -> list:
    L = []
    dd = res["accuracy"]["detection"]
    L.append("## 1b. Detection x vehicle speed\n")
    L.append(f"![detection]({plots[1]})\n")
    L.append(dd["reference"] + "\n")
    modes = list(dd["modes"])
    speeds = [r["speed_m_s"] for r in dd["modes"]["ray"]["per_speed"]]
    L.append("| mode | ms/step | false positives | " + " | ".join(f"{s:g} m/s" for s in speeds) + " |")
    L.append("|---|---|---|" + "---|" * len(speeds))
    for k in modes:
        d = dd["modes"][k]
        L.append(f"| {k} | {d['step_ms']:.3f} | {d['false_positives']} | " + " | ".join(
            f"{r['recall']:.4f} ({r['found']}/{r['contacts']})" for r in d["per_speed"]) + " |")
    L.append(f"\nLanes scene: {dd['modes']['ray']['n_rocks']:,} rocks, {dd['modes']['ray']['tires']} rear tires, "
             f"dt {dd['modes']['ray']['dt']:g} s, {dd['modes']['ray']['steps']} steps.\n")
    return L


def _precision(res: dict, plots: list) -> list:
    L = []
    dd = res["accuracy"]["detection"]
    pr = res["accuracy"]["precision"]
    L.append("## 1c. Precision x distance from the origin\n")
    L.append(f"![precision]({plots[2]})\n")
    L.append(f"Reference: {pr['reference']}. {pr['note']}.\n")
    L.append("| config | " + " | ".join(f"{d / 1e3:g} km" for d in pr["distances_m"]) + " | step ms (lanes) |")
    L.append("|---|" + "---|" * len(pr["distances_m"]) + "---|")
    for name, c in pr["configs"].items():
        ms = dd["modes"]["ray (f64)" if c["precision"] == "f64" else "ray"]["step_ms"]
        L.append(f"| {name} | " + " | ".join(_fmt(e) for e in c["max_error_m"]) + f" | {ms:.3f} |")
    L.append("")
    return L


def _hash(res: dict, plots: list) -> list:
    L = []
    hs = res["accuracy"]["hash_settings"]
    L.append("## 1d. Hash settings\n")
    L.append(f"![hash]({plots[3]})\n")
    failed = [r["name"] for r in hs["settings"] if "error" in r]
    L.append(f"**{hs['verdict']}**: launched rock ids after {hs['k_steps']} steps "
             f"{'identical for every setting' if hs['identical'] else 'DIFFER between settings'} "
             f"(N={hs['n']:,}, T={hs['t']})"
             + (f"; {len(failed)} setting(s) failed to build or run: {', '.join(failed)}" if failed else "") + ".\n")
    L.append("| setting | cell (m) | table | launched | identical | step ms | count | scan | scatter | trace | "
             "tire | build+compile s |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in hs["settings"]:
        if "error" in r:
            L.append(f"| {r['name']} | **FAILED**: {r['error']} |||||||||||")
            continue
        s = r["separate_passes_ms"]
        L.append(f"| {r['name']} | {r['cell_size_m']:g} | {r['table_size']:,} | {r['launched']} | "
                 f"{'yes' if r['identical'] else '**NO**'} | {r['step_ms']:.3f} | {_fmt(s.get('hash count'))} | "
                 f"{_fmt(s.get('hash scan'))} | {_fmt(s.get('hash scatter'))} | {_fmt(s.get('trace rays'))} | "
                 f"{_fmt(s.get('tire pass'))} | {r['build_s']:.1f} |")
    L.append("")
    return L


def _grid(res: dict, plots: list) -> list:
    L = []
    L.append("## 2. Speed against peers\n")
    L.append(f"![peers]({plots[4]})\n")
    L.append(f"![passes]({plots[5]})\n")
    L.append("| N | T | step ms (median) | mean | floor | Warp | cKDTree | NumPy | step/floor | step/Warp | "
             "NumPy/step | cKDTree/step | flying | hits agree |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for e in res["speed"]["grid"]:
        p, r, c = e["peers"], e["ratios"], e["peers"]["check"]
        agree = (c["kdtree_equals_numpy"] and c["taichi_launched_subset_of_geometric_hits"]
                 and c.get("warp_sym_diff_vs_numpy", 0) == 0)
        L.append(f"| {e['n']:,} | {e['t']} | {e['step_ms']:.3f} | {e['step_stats']['mean_ms']:.3f} | "
                 f"{p['floor_ms']:.3f} | {_fmt(p['warp_ms'])} | {p['kdtree_ms']:.1f} | {p['numpy_ms']:.1f} | "
                 f"{r['step_over_floor']:.2f} | {_fmt(r['step_over_warp'])} | {r['numpy_over_step']:.0f} | "
                 f"{r['kdtree_over_step']:.0f} | {e['n_flying']:,} | {'yes' if agree else 'NO'} |")
    L.append("")
    return L


def _passes(res: dict, plots: list) -> list:
    L = []
    L.append("Per pass (ms per step), each kernel called on its own after a normal step (`rock_pass` with one "
             "flag at a time, `inclusive_scan`, `scatter`, `trace_rays`, `tire_pass`):\n")
    keys = []
    for e in res["speed"]["grid"]:
        for k in e["separate_passes_ms"]:
            if k not in keys:
                keys.append(k)
    L.append("| N | T | " + " | ".join(keys) + " | reorder (every k steps) |")
    L.append("|---|---|" + "---|" * (len(keys) + 1))
    for e in res["speed"]["grid"]:
        s = e["separate_passes_ms"]
        L.append(f"| {e['n']:,} | {e['t']} | " + " | ".join(_fmt(s.get(k)) for k in keys)
                 + f" | {_fmt(e['reorder_ms'])} (every {e['reorder_every']}) |")
    L.append("")
    L.append("Inside a real step (each pass timed with syncs by the step itself; the rock pass fuses flight, recycle "
             "and count):\n")
    keys = []
    for e in res["speed"]["grid"]:
        for k in e["in_step"]["per_pass_ms"]:
            if k not in keys:
                keys.append(k)
    L.append("| N | T | " + " | ".join(keys) + " |")
    L.append("|---|---|" + "---|" * len(keys))
    for e in res["speed"]["grid"]:
        s = e["in_step"]["per_pass_ms"]
        L.append(f"| {e['n']:,} | {e['t']} | " + " | ".join(_fmt(s.get(k)) for k in keys) + " |")
    L.append("")
    return L


def _effects(res: dict, plots: list) -> list:
    L = []
    ov = res["speed"].get("overheads", {})
    if ov:
        L.append(f"Fixed costs: an empty Taichi kernel call {_fmt(ov.get('empty_kernel_ms'))} ms; `rock_pass` over "
                 f"zero rocks with every pass off {_fmt(ov.get('rock_pass_zero_rocks_ms'))} ms (the cost of a "
                 "launch with all its arguments); "
                 f"vehicle poses + rear-tire rays on the host {_fmt(ov.get('vehicle_poses_and_rays_ms'))} ms "
                 f"(main scene).\n")
    eff = res["speed"]["effects"]
    L.append(f"Effects (N={res['config']['main'][0]:,}, T={res['config']['main'][1]}; "
             f"{eff['n_flying_during_measurement']:,} rocks flying while measured):\n")
    efa = res["accuracy"]["flight_cost"].get("effects_all_flying_ms")
    if efa:
        L.append(f"With every one of the {res['accuracy']['flight_cost']['n_rocks']:,} rocks flying (flight pass "
                 "alone): " + "; ".join(f"{k} costs {v:+.2f} ms" for k, v in efa.items()) + ".\n")
    L.append("| variant | step ms | effect cost ms (on - off) |")
    L.append("|---|---|---|")
    for k, v in eff.items():
        if isinstance(v, dict):
            L.append(f"| {k} | {_fmt(v.get('step_ms'))} | {_fmt(v.get('effect_cost_ms'))} |")
    L.append("")
    return L


def _ms(p, key="step_ms"):
    return p.get(key) if p and "error" not in p else None


def _activity_n_table(act: dict) -> list:
    L = ["| series | N | bed radius (m) | rocks in the air | active list | active ms | full ms | floor ms | "
         "active/floor | full/active | simulated s per wall s |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for series in ("a", "b"):
        for r in act["series"][series]:
            a, f = r.get("active"), r.get("full")
            am, fm, fl = _ms(a), _ms(f), r.get("floor_ms")
            err = "; ".join(p["error"] for p in (a, f) if p and "error" in p)
            L.append(f"| ({series}) | {r['n']:,} | {r['radius']:.1f} | {_fmt(_ms(a, 'in_air'))} | "
                     f"{_fmt(_ms(a, 'active_count'))} | {_fmt(am)} | {_fmt(fm)} | {_fmt(fl)} | "
                     f"{_fmt(am / fl if am and fl else None)} | {_fmt(fm / am if am and fm else None)} | "
                     f"{_fmt(_ms(a, 'sim_s_per_wall_s'))} |" + (f" error: {err}" if err else ""))
    return L + [""]


def _activity_sweep_table(act: dict) -> list:
    L = [f"Against activity at N = {act['reference_n']:,}, bed radius {act['radius']:g} m (active stepping):\n",
         "| sweep | point | rear tires | speed (m/s) | integrator, detection | rocks in the air | active list | "
         "step ms | simulated s per wall s |", "|---|---|---|---|---|---|---|---|---|"]
    for p in act["sweep"]:
        if "error" in p:
            L.append(f"| {p['group']} | {p['label']} | error: {p['error']} |||||||")
            continue
        L.append(f"| {p['group']} | {p['label']} | {p['t_rear']} | {p['speed']:g} | {p['integrator']}, "
                 f"{p['detection']} | {p['in_air']:,} | {p['active_count']:,} | {_fmt(p['step_ms'])} | "
                 f"{_fmt(p['sim_s_per_wall_s'])} |")
    return L + [""]


def _activity_memory(act: dict) -> list:
    alone = "each point in a process of its own" if act.get("isolated", True) else \
        "the points in one process, one after another: not each point's own"
    L = [f"Memory per rock ({alone}; growth = peak RSS (VmHWM) - the process's RSS "
         "before the simulation was built, after 1 s of steps; fields = the bytes of the World's Taichi fields):\n",
         "| series | stepping | N | fields MB | fields B/rock | RSS MB | peak RSS MB | peak growth B/rock |",
         "|---|---|---|---|---|---|---|---|"]
    for series in ("a", "b"):
        for r in act["series"][series]:
            for stepping in choices("sim.stepping"):
                m = (r.get(stepping) or {}).get("memory")
                if m:
                    L.append(f"| ({series}) | {stepping} | {r['n']:,} | {_fmt(m['field_mb'])} | "
                             f"{_fmt(m['field_bytes_per_rock'])} | {_fmt(m['rss_mb'])} | {_fmt(m['hwm_mb'])} | "
                             f"{_fmt(m['hwm_growth_bytes_per_rock'])} |")
    L.append("")
    for series, per in act["memory"].items():
        for stepping, m in per.items():
            L.append(f"- ({series}) {stepping}: {_fmt(m['slope_bytes_per_rock'])} B per rock of peak RSS between "
                     f"the two largest N, {_fmt(m['field_bytes_per_rock'])} B per rock of fields; 10M rocks: "
                     f"**{m['peak_10m_gb']:.2f} GB** peak ({m['peak_10m_basis']}), "
                     f"{100 * m['peak_10m_gb'] / 24.0:.0f} % of 24 GB.")
    return L + [""]


def activity_breakdown(act: dict) -> list:
    """Where a step's time goes at each profiled N (activity.py run_profile, with the series (a) point of that
    N: its step time and launch probe, without the profiler): the table, the launch probe, the tasks."""
    prof = [p for p in act.get("profile", ()) if "error" not in p]
    if not prof:
        return [f"- profile {p['label']}: error: {p['error']}" for p in act.get("profile", ())]
    series = {r["n"]: r.get("active") for r in act["series"]["a"]}
    L = ["| N | rocks in the air | active list | step ms | host side ms | tasks on the device ms | launches "
         "per step | tasks per step (parallel) | Python per launch us | the rest ms | step ms, profiler on |",
         "|---|---|---|---|---|---|---|---|---|---|---|"]
    probe = None
    for p in prof:
        a = series.get(p["n"])
        a = a if a and "error" not in a else None
        step = a["step_ms"] if a else None
        lu = (a or {}).get("launch_us")
        probe = lu or probe
        rest = step - p["host_ms"] - p["device_ms"] - lu["step"] * p["launches_per_step"] * 1e-3 if lu and step \
            else None
        L.append(f"| {p['n']:,} | {p['in_air']:,} | {p['active_count']:,} | {_fmt(step)} | {_fmt(p['host_ms'])} | "
                 f"{_fmt(p['device_ms'])} | {p['launches_per_step']:.2f} | {p['tasks_per_step']:.1f} "
                 f"({p['parallel_tasks_per_step']:.1f}) | {_fmt(lu['step'] if lu else None)} | {_fmt(rest)} | "
                 f"{_fmt(p['step_ms'])} |")
    L.append("")
    if probe:
        L.append(f"A launch's Python side (kernels doing nothing): {probe['empty']:.1f} us with no arguments, "
                 f"{probe['step']:.1f} us with a step's (the World, its switches, three integers), "
                 f"{probe['step, same arguments']:.1f} us with the same integers every launch, {probe['arrays']:.1f} "
                 "us with the arguments before the step's inputs were on the device (rays and frame arrays, a "
                 "float, two integers).\n")
    for p in prof:
        L.append(f"Tasks of a step at N = {p['n']:,} (the kernel profiler's medians over {p['steps']} steps; serial "
                 "tasks run on one thread, the others are parallel loops):\n")
        L.append("| kernel | task | does | kind | median ms | min ms |")
        L.append("|---|---|---|---|---|---|")
        for t in p["tasks"]:
            L.append(f"| {t['kernel']} | {t['task']} | {t['what']} | {t['kind']} | {t['median_ms']:.4f} | "
                     f"{t['min_ms']:.4f} |")
        L.append("")
    return L


def _activity(res: dict, plots: list) -> list:
    act = res.get("activity")
    if not act:
        return []
    png = next((p for p in plots if p and p.startswith("activity")), "")
    L = ["## 4. Cost against activity\n"]
    if png:
        L.append(f"![activity]({png})\n")
    L.append(f"Step time against N at fixed activity: {act['t_rear']} rear tires at {act['speed']:g} m/s, the "
             f"same formation at every point. Series (a): bed radius {act['radius']:g} m (the density, and so "
             "the rocks thrown and recycled per step, grow with N). Series (b): fixed density "
             f"({act['density_b']:.0f} rocks/m^2, the bed radius grows as sqrt(N): the same rocks in the air; "
             "the rim, and so the rocks recycled per step, grows as sqrt(N)). Each point runs in a process of "
             "its own: build, 1 s of steps (steady state), memory, then rounds of steps timed as one block each "
             "(ti.sync() around it), interleaved with two passes of the streaming floor of the same N; medians of "
             "the rounds. Rocks in the air: phase != resting after the rounds; active list: its length then "
             f"(all N with full stepping). Section time {act['elapsed_s']:.0f} s.\n")
    L += _activity_n_table(act) + _activity_sweep_table(act) + _activity_memory(act)
    if act.get("profile"):
        L.append("### Where a step's time goes\n")
        L.append("Each profiled N in a process of its own with Taichi's kernel profiler on (series (a), active "
                 "stepping): step = steps timed as a block (the best of the rounds); host side = the engine's timing "
                 "hook around the host work of a step (vehicles, bed, origin, rays); tasks on the device = the sum of "
                 "the profiler's task times per step (a parallel task's time includes waking the thread pool); "
                 "step ms and Python per launch (the launch probe: a kernel doing nothing, a step's arguments) "
                 "come from the series (a) point of that N, without the profiler; the rest = step - host - tasks - "
                 "launches x Python per launch (the step's other Python, the batch upload).\n")
        L += activity_breakdown(act)
    return L


def _impacts(res: dict, plots: list) -> list:
    return list(res.get("_impacts_md", []))  # run.py: the study's section (impacts_report.section_lines)


def _tail(res: dict, plots: list) -> list:
    L = []
    L.append("## Build (compile) time per simulation\n")
    L.append(", ".join(f"{k}: {v:.1f} s" for k, v in res["build_s"].items()) + "\n")
    if res.get("errors"):
        L.append("## Errors\n")
        for e in res["errors"]:
            L.append(f"- {e}")
        L.append("")
    return L

_SECTIONS = (_header, _targets, _presets, _integrators, _detection, _precision, _hash, _grid, _passes, _effects,
             _activity, _impacts, _tail)


def check_out_dir(out, names, overwrite: bool) -> None:
    """Before a study runs: refuse (one line) an ``out`` that is a file (ValueError), or a folder already
    holding one of ``names``, the files the study writes (FileExistsError), unless ``overwrite``."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: is a file, expected a folder for the results")
    found = [n for n in names if (out / n).exists()]
    if found and not overwrite:
        raise FileExistsError(f"{out}: holds the results of an earlier run ({found[0]}"
                              f"{f' and {len(found) - 1} more' if len(found) > 1 else ''}); pass --overwrite to "
                              "replace them")


def write_report(res: dict, out: Path, plots: list) -> Path:
    lines = []
    for section in _SECTIONS:
        lines += section(res, plots)
    path = out / "report.md"
    text = "\n".join(lines)
    write_atomically(path, lambda f: f.write(text.encode()))
    return path


def write_results(res: dict, out: Path) -> Path:
    """results.json: every number of ``res`` (:func:`jsonable`)."""
    path = out / "results.json"
    blob = json.dumps(jsonable(res), indent=1)
    write_atomically(path, lambda f: f.write(blob.encode()))
    return path


def jsonable(x):
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items() if not str(k).startswith("_")}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating,)):
        x = float(x)
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, Path):
        return str(x)
    return x
