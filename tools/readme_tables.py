"""The measured tables of README.md and docs/, generated from the benchmark results committed under docs/results/:

    docs/results/bench.json    ``taichi-rocks bench`` (its results.json): speed and activity targets, presets
    docs/results/activity.json ``taichi-rocks bench --only activity`` (its activity.json): when present, the
                               activity blocks (targets, notes, where a step's time goes) come from it
    docs/results/launch.json   ``taichi-rocks bench --only launch`` (its launch_study.json): what the tread throws
    docs/results/impacts.json  ``taichi-rocks bench --only impacts [--quick]`` (its impacts.json): the impacts
                               study's targets (its plots and impacts.md sit beside it)
    docs/results/frame.json    ``taichi-rocks bench --only frame`` (its frame.json), when present: the frame of a
                               game loop; without it the ``frame`` blocks stay empty
    docs/results/render_profile.json  ``taichi-rocks render scenes/convoy.toml --profile`` (its profile.json): the
                               renderer's frame stage by stage (docs/rendering.md)

    python tools/readme_tables.py            # rewrite the marked blocks of the pages (PAGES) from those files
    python tools/readme_tables.py --check    # exit 1 (and say which) if a page differs from them

Each generated block sits between ``<!-- results:NAME -->`` and ``<!-- /results:NAME -->``; the text outside the
blocks is left alone, and nothing inside them is written by hand. To show a new run: copy its results.json
(activity.json, launch_study.json, ...) over the files above, run this script, commit them together.
tests/test_readme_tables.py checks that the pages' blocks are what this script makes of the committed files.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path

from taichi_rocks.bench.machine import was_busy

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
RESULTS = DOCS / "results"
# the pages that hold generated blocks, and their blocks (a block may sit in several pages)
PAGES = {README: ("headline-speed", "frame", "presets"),
         DOCS / "performance.md": ("frame", "frame-details", "activity-targets", "activity-notes", "activity-breakdown",
                                   "speed-targets", "speed-notes", "presets"),
         DOCS / "physics.md": ("launch-targets", "launch-cases"),
         DOCS / "rendering.md": ("render-frame",),
         DOCS / "impacts.md": ("impacts-targets",)}

# the per-case rows of the launch study the README shows (the study's report has all 18)
LAUNCH_CASES = ("V10 dry gravel", "V20 dry gravel", "V30 dry gravel", "V20 wet gravel", "V30 wet gravel",
                "V20 dry small", "V20 wet small", "V20 dry large")
INTEGRATOR = {"symplectic_euler": "symplectic Euler", "heun": "Heun", "rk4": "RK4"}
SPEED_TARGETS = ("full step <= 1.0x Warp", "full step <= 3x streaming floor", ">= 100x faster than NumPy",
                 "bed-only scene", "linear in N")
ACTIVITY_TARGETS = ("step at ", "step(", "1,000,000 rocks with the balanced preset", "active step <= 0.5x",
                    "real time with the balanced preset")


def _met(m) -> str:
    return {True: "yes", False: "**no**", None: "-"}[m]


def _length(x: float) -> str:
    """A length with a readable unit."""
    if x == 0:
        return "0 m"
    for unit, scale in (("m", 1.0), ("cm", 1e-2), ("mm", 1e-3), ("µm", 1e-6), ("nm", 1e-9)):
        if abs(x) >= scale:
            return f"{x / scale:.3g} {unit}"
    return f"{x:.2e} m"


def _num(x, digits=3) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    if abs(x) >= 1000:
        return f"{x:,.0f}"
    return f"{x:.{digits}g}"


def run_line(res: dict) -> str:
    """Where and when a run was made, and how busy the machine was (a full benchmark's results.json, or the
    activity study's activity.json)."""
    if "config" not in res:  # bench --only activity
        res = dict(res, config={"mode": f"--only activity, {res['mode']}"}, elapsed_s=res["activity"]["elapsed_s"])
    m = res["machine"]
    la0, la1 = res.get("load_average_start"), res.get("load_average_end")
    load, busy = "", ""
    if la0 and la1:
        load = f"; load average {la0[0]:.1f} at the start, {la1[0]:.1f} at the end"
        if was_busy(la0, la1, m["usable_cores"]):  # the report's own rule
            busy = (" **The machine was busy with other work during this run: its timings are noisy and "
                    "pessimistic.**")
    return (f"*Run of {res['started']} ({res['config']['mode']}, {res['elapsed_s'] / 60:.0f} min): {m['cpu_model']}, "
            f"{m['usable_cores']} cores, Taichi {m['taichi']} ({m['taichi_arch']}){load}.*{busy}")


# ------------------------------------------------------------------------------------------------ launch
def launch_targets(launch: dict, bench: dict) -> list:
    rows = ["| target | measured | met |", "|---|---|---|"]
    for r in launch["table"]:
        rows.append(f"| {r['target']} | {r['shown']} | {'-' if r['met'] is None else ('yes' if r['met'] else 'NO')} |")
    return rows


def launch_cases(launch: dict, bench: dict) -> list:
    rows = ["| case | launches | lost in air | median angle | > 25 deg | median apex | 95 % apex | max apex | "
            "< 1.5 m | landing behind (median) | > 40 m |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for k in LAUNCH_CASES:
        s = launch["stats"][k]
        rows.append(f"| {k} | {s['launches']} | {s['lost_in_air']} | {s['alpha_median_deg']:.1f} deg | "
                    f"{100 * s['alpha_above_25']:.1f} % | {100 * s['apex_median']:.1f} cm | "
                    f"{100 * s['apex_p95']:.1f} cm | {s['apex_max']:.2f} m | {100 * s['below_1_5']:.2f} % | "
                    f"{s['behind_median']:.2f} m | {100 * s['beyond_40']:.2f} % |")
    return rows


# ------------------------------------------------------------------------------------------------ bench
def _targets(bench: dict, prefixes) -> list:
    return [t for t in bench["targets"] if t["target"].startswith(prefixes)]


def speed_targets(launch: dict, bench: dict) -> list:
    rows = [run_line(bench), "", "| target | measured | met |", "|---|---|---|"]
    for t in _targets(bench, SPEED_TARGETS):
        measured = t["detail"] + ("" if t["value"] is None else f" ({_num(t['value'])}x)")
        rows.append(f"| {t['target']} | {measured} | {_met(t['met'])} |")
    return rows


def _grid(bench: dict) -> dict:
    return {(e["n"], e["t"]): e for e in bench["speed"]["grid"]}


def speed_notes(launch: dict, bench: dict) -> list:
    """The speed section's figures: the passes inside a step at the main scene, the hash settings, detection."""
    n, t = bench["config"]["main"]
    main = _grid(bench).get((n, t))
    out = []
    if main:
        prof = main["in_step"]["per_pass_ms"]
        host = prof.get("host and launch overhead")
        passes = "; ".join(f"{k} {_num(v)} ms" for k, v in prof.items() if k != "host and launch overhead")
        out.append(f"- Inside a step at N = {n:,}, T = {t} ({_num(main['step_ms'])} ms, the median): {passes}"
                   + (f"; host work and launches {_num(host)} ms." if host is not None else "."))
    hs = bench["accuracy"]["hash_settings"]
    ok = {r["name"]: r for r in hs["settings"] if "error" not in r}
    rel = [f"\"{name}\" x{r['step_ms'] / ok[next(iter(ok))]['step_ms']:.2f}" for name, r in ok.items()][1:]
    failed = [r["name"] for r in hs["settings"] if "error" in r]
    out.append(f"- Hash settings (N = {hs['n']:,}, T = {hs['t']}, {hs['k_steps']} steps): **{hs['verdict']}**, the "
               f"launched rocks {'identical for every setting' if hs['identical'] else 'DIFFER'}"
               + (f", {len(failed)} failed to build: " + ", ".join(failed) if failed else "")
               + "; step time against the default: " + "; ".join(rel) + ".")
    modes = bench["accuracy"]["detection"]["modes"]
    recall = lambda m: ", ".join(f"{r['recall']:.2f} at {r['speed_m_s']:g} m/s" for r in modes[m]["per_speed"]
                                 if r["speed_m_s"] in (20.0, 60.0))
    line = f"- Detection (recall of the true tire contacts): a single ray {recall('ray')}"
    if "ray x4 substeps" in modes:
        line += f"; four ray substeps {recall('ray x4 substeps')}"
    line += (f"; swept {recall('swept')}, for x{modes['swept']['step_ms'] / modes['ray']['step_ms']:.2f} the "
             "ray's step time (lanes scene).")
    out.append(line)
    pr = bench["accuracy"]["precision"]
    d = pr["distances_m"]
    at = lambda name, k: _length(pr["configs"][name]["max_error_m"][k])
    km = lambda k: f"{d[k] / 1e3:g} km"
    far = len(d) - 1
    near = d.index(1e3) if 1e3 in d else 1
    out.append(f"- Precision: f32 with a world origin is off by {at('f32 world', near)} at {km(near)} and "
               f"{at('f32 world', far)} at {km(far)}; the floating origin keeps f32 at {at('f32 floating', far)} at "
               f"{km(far)} (against an f64 flight launched at the origin).")
    return out


def presets(launch: dict, bench: dict) -> list:
    acc = bench["accuracy"]
    n, t = bench["config"]["main"]
    rows = ["| preset | meets: flight error / recall at 60 m/s / launch-time bound | settings | measured flight "
            f"error | ms per simulated second ({n:,} rocks, {t} tires) |", "|---|---|---|---|---|"]
    for p in acc["presets"]:
        meets = ("one step per 60 Hz frame (no targets)" if p["target_recall"] is None else
                 f"{_length(p['target_flight_error_m'])} / {p['target_recall']:g} / "
                 f"{_length(p['target_launch_time_bound_m'])}")
        if "integrator" not in p:
            rows.append(f"| `{p['name']}` | {meets} | {p['none']} | | |")
            continue
        det = p["detection"] + (f" x{p['substeps']}" if p["substeps"] > 1 else "")
        rows.append(f"| `{p['name']}` | {meets} | {INTEGRATOR[p['integrator']]}, dt {p['dt']:g} s, {det}, "
                    f"{p['precision']} | {_length(p['flight_error_m']) if p['flight_error_m'] is not None else 'n/a'} | "
                    f"{_num(p['ms_per_simulated_s']) if p['ms_per_simulated_s'] is not None else 'n/a'} |")
    rows.append("")
    rows.append(f"The defaults (symplectic Euler, dt 0.002 s, a single ray, f32): flight error "
                f"{_length(_default_error(bench))}, recall {_num(_default_recall(bench), 2)} at 60 m/s, "
                f"{_num(acc['preset_costs']['step_ms']['ray'] / 0.002)} ms per simulated second.")
    return rows


def _default_error(bench: dict) -> float:
    rows = [r for r in bench["accuracy"]["integrator_dt"]["rows"] if r["precision"] == "f32"
            and r["integrator"] == "symplectic_euler" and abs(r["dt"] - 0.002) < 1e-12
            and r["case"] in ("gravity", "quadratic")]
    return max(r["max_error_m"] for r in rows)


def _default_recall(bench: dict) -> float:
    rows = bench["accuracy"]["detection"]["modes"]["ray"]["per_speed"]
    return max(rows, key=lambda r: r["speed_m_s"])["recall"]


def activity_targets(launch: dict, bench: dict) -> list:
    rows = [run_line(bench.get("activity_run", bench)), "", "| target | measured | verdict |", "|---|---|---|"]
    for t in _targets(bench, ACTIVITY_TARGETS):
        how, _, detail = t["detail"].partition(": ")
        verdict = "met" if t["met"] else ("**missed**" if t["met"] is False else "-")
        rows.append(f"| {t['target']} | {_num(t['value'])}: {detail} | {verdict} ({how.split(', ', 1)[-1]}) |")
    mem = bench["activity"]["memory"]
    for series, per in mem.items():
        m = per.get("active")
        if m:
            rows.append(f"| memory, 10M rocks, series ({series}) | {m['peak_10m_gb']:.2f} GB peak RSS ({m['peak_10m_basis']}; "
                        f"fields {_num(m['field_bytes_per_rock'])} B a rock) | fits 24 GB "
                        f"{24.0 / m['peak_10m_gb']:.0f}x over |")
    return rows


def activity_notes(launch: dict, bench: dict) -> list:
    act = bench["activity"]
    out = []
    full = [r for r in act["series"]["a"] if r.get("full") and "error" not in r["full"] and r.get("active")
            and "error" not in r["active"]]
    if full:
        out.append("- Full stepping in the same run: " + "; ".join(
            f"{r['full']['step_ms']:.2f} ms at {r['n']:,} rocks ({r['full']['step_ms'] / r['active']['step_ms']:.1f}x "
            "the active step)" for r in full) + ".")
    a = [r for r in act["series"]["a"] if r.get("active") and "error" not in r["active"]]
    if a:
        out.append("- Active step against N (series (a)): " + "; ".join(
            f"{r['active']['step_ms']:.2f} ms at {r['n']:,}" for r in a) + ".")
    tires = [p for p in act["sweep"] if p["group"] == "tires" and "error" not in p]
    if tires:
        out.append(f"- Against the rear tires at N = {act['reference_n']:,}: " + "; ".join(
            f"{p['step_ms']:.2f} ms with {p['t_rear']}" for p in tires) + ".")
    probe = next((r["active"]["launch_us"] for r in act["series"]["a"] if (r.get("active") or {}).get("launch_us")),
                 None)
    if probe:
        out.append(f"- A launch's Python side: {_num(probe['empty'])} us with no arguments, {_num(probe['step'])} us "
                   f"with a step's (the World, its switches, three integers; {_num(probe['step, same arguments'])} us "
                   f"with the same ones every launch), {_num(probe['arrays'])} us with the arrays of rays and frame a "
                   "step passed before its inputs were on the device.")
    ov = bench["speed"].get("overheads", {})
    if ov and not probe:
        out.append(f"- Fixed costs: an empty kernel launch {_num(ov.get('empty_kernel_ms'))} ms, the rock pass over "
                   f"zero rocks with every part off {_num(ov.get('rock_pass_zero_rocks_ms'))} ms, the vehicles' "
                   f"poses and rays on the host {_num(ov.get('vehicle_poses_and_rays_ms'))} ms a step.")
    return out


def activity_breakdown(launch: dict, bench: dict) -> list:
    """Where a step's time goes (the activity study's profiled points): per N the step, the host side, the
    tasks on the device, launches and tasks per step; then the costliest tasks of each N."""
    act = bench["activity"]
    prof = [p for p in act.get("profile", ()) if "error" not in p]
    if not prof:
        return ["(not measured in this run)"]
    series = {r["n"]: r.get("active") or {} for r in act["series"]["a"]}
    rows = ["| N | rocks in the air | step ms | host side ms | tasks on the device ms | Python of the launches ms | "
            "the rest ms | launches per step | parallel tasks per step | serial tasks per step |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for p in prof:
        a = series.get(p["n"], {})
        step, lu = a.get("step_ms"), (a.get("launch_us") or {}).get("step")
        py = lu * p["launches_per_step"] * 1e-3 if lu else None
        rest = step - p["host_ms"] - p["device_ms"] - py if step and py else None
        rows.append(f"| {p['n']:,} | {p['in_air']:,} | {_num(step)} | {_num(p['host_ms'])} | {_num(p['device_ms'])} | "
                    f"{_num(py)} | {_num(rest)} | {p['launches_per_step']:.0f} | {p['parallel_tasks_per_step']:.0f} | "
                    f"{p['tasks_per_step'] - p['parallel_tasks_per_step']:.0f} |")
    rows.append("")
    for p in prof:
        top = sorted(p["tasks"], key=lambda t: -t["ms_per_step"])[:5]
        rows.append(f"- Costliest tasks at N = {p['n']:,} (ms per step, with the profiler on): " + "; ".join(
            f"{_task_name(t)} {t['ms_per_step']:.3f}" for t in top) + ".")
    rows.append("- The profiler's run is slower than the timed one (its own cost per task), so \"the rest\" can "
                "come out negative: read the columns as shares, not as a sum.")
    return rows


def _task_name(t: dict) -> str:
    """A task's description; the batch upload's tasks by their kernel (runs of the study before they were named)."""
    if t["what"].startswith("task ") and t["kernel"] == "load_batch":
        return f"batch upload ({t['kind']}, once per lookahead batch)"
    return t["what"]


# ------------------------------------------------------------------------------------------------ impacts
def impacts_targets(launch: dict, bench: dict) -> list:
    """The impacts study's run and its targets, each with its measured value (bench/impacts_analysis.py)."""
    res = bench["impacts_run"]
    imp, m = res["impacts"], res["machine"]
    cross = imp["cross_lane"]
    rows = [f"*Run of {res['started']} (`--only impacts`, {res['mode']}: {len(imp['runs'])} runs, "
            f"{imp['elapsed_s'] / 60:.0f} min on {imp['placement']['workers']} processes): {m['cpu_model']}, "
            f"{m['usable_cores']} cores, Taichi {m['taichi']} ({m['taichi_arch']}). {imp['events_total']:,} hits "
            f"on the followers, {cross['cross']} across lanes.*", "",
            "| target | measured | met | detail, and why where missed |", "|---|---|---|---|"]
    for t in imp["targets"]:
        repeated = t["reason"].split(": ", 1)[-1] in t["detail"]  # a reason that only repeats the detail
        why = "; ".join(x for x in (t["detail"], "" if repeated else t["reason"]) if x)
        rows.append(f"| {t['target']} | {t['shown']} | {_met(t['met'])} | {why} |")
    return rows


# ------------------------------------------------------------------------------------------------ headline
def headline_speed(launch: dict, bench: dict) -> list:
    """The README's speed against peers: the main point's full step against Warp, NumPy and the streaming floor
    (the full benchmark, run B), and the active step against the full step at the same N (the activity run, A).
    Each ratio is within one run."""
    n, t = bench["config"]["main"]
    main = _grid(bench)[(n, t)]
    peers, fs = main["peers"], main["step_ms"]
    act = bench.get("activity_run", bench)
    row = next((r for r in bench["activity"]["series"]["a"] if r["n"] == n and "error" not in (r.get("active") or
                {"error": 1}) and "error" not in (r.get("full") or {"error": 1})), None)
    rows = [f"| {n:,} rocks, {t} rear tires | ms per step | against the full step of the same run | run |",
            "|---|---|---|---|"]
    if row:
        a, f = row["active"]["step_ms"], row["full"]["step_ms"]
        rows.append(f"| taichi_rocks, active stepping (the default) | {_num(a)} | {f / a:.1f}x faster | A |")
        rows.append(f"| taichi_rocks, full stepping (every rock, every step) | {_num(f)} | 1x | A |")
    rows.append(f"| taichi_rocks, full stepping | {_num(fs)} | 1x | B |")
    rows.append(f"| NVIDIA Warp {bench['warp'].get('version', '')}, HashGrid build + query | "
                f"{_num(peers['warp_ms'])} | {peers['warp_ms'] / fs:.1f}x slower | B |")
    rows.append(f"| NumPy, brute force | {_num(peers['numpy_ms'])} | {peers['numpy_ms'] / fs:.0f}x slower | B |")
    rows.append(f"| streaming floor: one pass over positions and velocities | {_num(peers['floor_ms'])} | "
                f"{fs / peers['floor_ms']:.1f}x less time | B |")
    rows.append("")
    runs = ([f"A: {_short_run(act)}"] if row else []) + [f"B: {_short_run(bench)}"]
    rows.append("Runs: " + "; ".join(runs) + ".")
    return rows


def _short_run(res: dict) -> str:
    m = res["machine"]
    la0, la1 = res.get("load_average_start"), res.get("load_average_end")
    busy = la0 and la1 and was_busy(la0, la1, m["usable_cores"])
    return (f"{res['started'][:10]}, {m['cpu_model']}, {m['usable_cores']} cores, Taichi {m['taichi']} "
            f"({m['taichi_arch']})" + (", the machine busy with other work (noisy, pessimistic)" if busy else ""))


def frame(launch: dict, bench: dict) -> list:
    """The frame of a game loop (``bench --only frame``: docs/results/frame.json, bench/frame.py's tables);
    nothing without that file."""
    res = bench.get("frame_run")
    if not res:
        return []
    from taichi_rocks.bench.frame import frame_table, live_lines

    m = res["machine"]
    live = ["", *live_lines(res)] if "live" in res else []  # runs before the live player was measured have none
    return frame_table(res) + live + ["", f"Run: {res['started'][:10]}, {m.get('cpu_model', '?')}, "
                                          f"{m.get('usable_cores', '?')} cores, Taichi {m.get('taichi', '?')} "
                                          f"({m.get('taichi_arch', '?')}), load average {res['load_average_start']}."]


def frame_details(launch: dict, bench: dict) -> list:
    """The frame study's task table and its accuracy per preset (docs/performance.md)."""
    res = bench.get("frame_run")
    if not res:
        return []
    from taichi_rocks.bench.frame import accuracy_table, task_cost_table, task_table, variant_table

    out = ["*The step's tasks with the game preset, in each variant of the step (Taichi's kernel profiler, per "
           "step):*", ""] + task_table(res)
    if res.get("variants"):  # runs made before the variants existed have neither table
        out += ["", "*The variants' crossover: the step right after loading, every rock in its loops, serial "
                    "against parallel:*", ""] + variant_table(res)
        out += ["", "*What a task costs from Python (a loop adding 1 to a field):*", ""] + task_cost_table(res)
    return out + ["", "*What each preset costs in accuracy (the frame study's own measurements):*", ""] + \
        accuracy_table(res)


def render_frame(launch: dict, bench: dict) -> list:
    """The renderer's frame stage by stage: a run of ``taichi-rocks render --profile`` (its profile.json,
    app/render.py; docs/results/render_profile.json), per frame drawn: the wall time of each stage, its share of
    the frame, and the process's CPU time in it (every thread's: the kernels', lavapipe's)."""
    res = bench.get("render_run")
    if not res:
        return []
    from taichi_rocks.render.stages import STAGES

    n, prof, cpu, fps = res["frames"], res["profile"], res["profile_cpu"], res["frames_per_second"]
    frame = 1000.0 / fps
    ms = lambda s: 1000.0 * s / n
    rows = ["| stage | what it holds | ms per frame | share | CPU ms per frame |", "|---|---|---|---|---|"]
    stages = {"simulation": "the simulation stepped to the frame's time (the engine)", **STAGES}
    for k, what in stages.items():
        if k in prof:
            rows.append(f"| {k} | {what} | {ms(prof[k]):.1f} | {ms(prof[k]) / frame:.0%} | {ms(cpu[k]):.1f} |")
    rows.append(f"| encoding | waiting on the frame writer (PNG frames, MP4) | {ms(prof['encoding']):.1f} | "
                f"{ms(prof['encoding']) / frame:.0%} | |")
    rows.append(f"| other | the rest of the frame loop | {ms(prof['other']):.1f} | {ms(prof['other']) / frame:.0%} | |")
    rows.append(f"| **the frame** | {n} frames at {fps:.2f} frames/s | **{frame:.1f}** | 100% | {ms(cpu['loop']):.1f} "
                "(the whole loop: the frame writer's thread too) |")
    m = res["machine"]
    la0, la1 = res.get("load_average_start"), res.get("load_average_end")
    busy = la0 and la1 and was_busy(la0, la1, m["usable_cores"])
    w, h = res["resolution"]
    rows += ["", f"Run: {res['started'][:10]}, `{res['scene']}` at {w}x{h}, {m['cpu_model']}, {m['usable_cores']} "
                 f"cores, Taichi {m['taichi']} ({m['taichi_arch']}), load average {la0} at the start, {la1} at the end"
                 + (" (the machine busy with other work: wall times noisy and pessimistic, CPU times less so)"
                    if busy else "") + "."]
    return rows


BLOCKS = {"headline-speed": headline_speed, "frame": frame, "frame-details": frame_details, "launch-targets": launch_targets, "launch-cases": launch_cases, "speed-targets": speed_targets,
          "speed-notes": speed_notes, "presets": presets, "activity-targets": activity_targets,
          "activity-notes": activity_notes, "activity-breakdown": activity_breakdown,
          "impacts-targets": impacts_targets, "render-frame": render_frame}


def load(results: Path = RESULTS) -> tuple:
    """(launch, bench): with an activity.json, bench's activity section and activity targets are its."""
    launch = json.loads((results / "launch.json").read_text())
    bench = json.loads((results / "bench.json").read_text())
    if (results / "activity.json").exists():
        act = json.loads((results / "activity.json").read_text())
        speed = [t for t in bench["targets"] if t["target"].startswith(SPEED_TARGETS)]
        bench = dict(bench, activity=act["activity"], targets=speed + act["targets"], activity_run=act)
    bench = dict(bench, impacts_run=json.loads((results / "impacts.json").read_text()))
    if (results / "frame.json").exists():
        bench = dict(bench, frame_run=json.loads((results / "frame.json").read_text()))
    if (results / "render_profile.json").exists():
        bench = dict(bench, render_run=json.loads((results / "render_profile.json").read_text()))
    return launch, bench


def blocks(launch: dict, bench: dict) -> dict:
    return {name: "\n".join(fn(launch, bench)) for name, fn in BLOCKS.items()}


def rewrite(text: str, generated: dict, names=None, where: str = "README.md") -> str:
    """``text`` with each marked block of ``names`` (default: all) replaced by its generated content (an empty
    block where that is empty); a block missing from ``text`` or present twice is an error."""
    for name in names or generated:
        body = generated[name]
        pattern = re.compile(rf"(<!-- results:{re.escape(name)} -->\n)(?:.*?\n)?(<!-- /results:{re.escape(name)} -->)",
                             re.S)
        found = len(pattern.findall(text))
        if found != 1:
            raise ValueError(f"{where}: block results:{name} found {found} times (expected once)")
        text = pattern.sub(lambda m: m.group(1) + (body + "\n" if body else "") + m.group(2), text)
    return text


def pages(generated: dict) -> dict:
    """Each page of PAGES and the text it should have."""
    return {page: rewrite(page.read_text(), generated, names, str(page.relative_to(ROOT)))
            for page, names in PAGES.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="only compare; exit 1 if a page differs")
    args = ap.parse_args(argv)
    wanted = pages(blocks(*load()))
    differ = [p for p, text in wanted.items() if p.read_text() != text]
    if args.check:
        for p in differ:
            print(f"{p.relative_to(ROOT)}: the measured tables differ from docs/results/ (run python "
                  "tools/readme_tables.py)", file=sys.stderr)
        return 1 if differ else 0
    for p in differ:
        p.write_text(wanted[p])
        print(f"{p.relative_to(ROOT)}: tables rewritten from docs/results/")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
