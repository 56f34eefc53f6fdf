"""The frame in a game's budget (``taichi-rocks bench --only frame``): the default scene in a 60 Hz game loop.

A game calls, every frame f, ``advance_to(f / 60)``, ``impacts()`` and ``changes()`` (the rocks whose drawn state
changed: engine/changes.py), and draws. This study times each of the three per frame (median and 95th
percentile over the frames after a warm-up, the clock read around each call with the device synchronised), and
for comparison ``state()`` (every rock, O(N)) on every 10th frame, for:

* ``[sim] accuracy = "game"`` (one step per frame, dt = 1/60 s) and the default dt = 2 ms (8-9 steps a frame);
* the game preset with the player live (docs/drives.md: ``drive()`` each frame with the poses its scripted path
  has at the frame times), measured in one process against the scripted player, frame by frame in turn;
* Taichi's CPU thread pool of 1 thread, of every core, and the engine's choice (engine/runtime.py
  ``auto_threads``), each in a process of its own (the pool is sized once per process); on every core, the
  step's parallel variant forced beside the engine's choice of variant (engine/variant.py: serial loops on a
  few cores with a game's active list);
* the step's tasks (Taichi's kernel profiler: kind, launches, median time and share of the device time per
  task, per step), with the game preset, in both variants of the step, in a process of its own (the profiler
  slows every launch);
* the variants' crossover: the step right after rocks are loaded (every rock in the active list) at several
  bed sizes, serial against parallel on every core, in one process, alternating (engine/variant.py
  ``CROSSOVER`` is the count where the parallel one starts to win);
* what the game preset costs in accuracy beside the other presets: the flight error of a 2 s flight against its
  closed form (gravity, quadratic drag; bench/flight.py), the recall of the tire contacts at 60 m/s in the lanes
  scene (bench/detection.py), the launch-time bound v_launch dt (modelled, v_launch <= 30 m/s) and the frame's
  cost.

Writes ``frame.json`` and ``frame.md`` into the output folder (atomically).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import taichi as ti

from ..config.presets import PRESETS
from ..config.scene import load_scene, scene_with
from ..engine.params import drag_coefficients
from ..engine.runtime import auto_threads, init_taichi, threads_in_use
from ..engine.simulation import Simulation
from ..engine.timing import clear_kernel_tasks, kernel_tasks
from ..motion.vehicles import Fleet
from ..output.atomic import new_folders, write_atomically
from .activity import task_rows
from .config import PRESET_SPEED, SAMPLE_EVERY, V_LAUNCH_MAX, make_config
from .detection import detection_runs
from .taskcosts import measure_task_costs
from .flight import exact_gravity, exact_quadratic_vertical, fly
from .machine import Progress, loadavg, machine
from .measure import Built, stats
from .report import check_out_dir
from .scenes import probe_scene

PREFIX = "frame-result: "
SCENE = Path(__file__).resolve().parents[2] / "scenes" / "convoy.toml"
CASES = (("game", {"sim.accuracy": "game"}), ("dt = 2 ms", {}))
LIVE = ("game, live player", {"sim.accuracy": "game"})  # the player driven by drive() (docs/drives.md)
OUTPUTS = ("frame.json", "frame.md")


def _stats(ms: list) -> dict:
    """measure.stats of times in ms, with the 95th percentile."""
    return {**stats(np.asarray(ms, float) / 1e3), "p95_ms": float(np.percentile(ms, 95))}


def _scene(overrides: dict, path=SCENE):
    """The scene file with ``overrides`` (``sim.accuracy`` applies its preset: config/scene.py scene_with)."""
    sc = load_scene(path)
    return scene_with(sc, overrides) if overrides else sc


def _timed(fn):
    ti.sync()
    t0 = time.perf_counter()
    out = fn()
    ti.sync()
    return out, 1e3 * (time.perf_counter() - t0)


def live_twin(scene):
    """``scene`` with the vehicle the bed follows live, starting where and as its path does, and that path (the
    poses a game drives it with: motion/paths.py)."""
    i = scene.vehicle_index(scene.bed.follow)
    path = Fleet(scene).paths[i]
    p = path.pose(0.0)
    live = scene_with(scene, {f"vehicle[{i}].path": {"kind": "live", "start": [float(v) for v in p.position],
                                                     "heading": math.degrees(p.heading), "speed": float(p.speed)}})
    return live, scene.vehicles[i].name, path


def measure_live(overrides: dict, arch: str, frames: int, warm: int, fps: float = 60.0, path=SCENE) -> dict:
    """The game loop with the player live (driven each frame with the poses its scripted path has at the frame
    times: ``drive()`` + ``advance_to`` + ``impacts()`` + ``changes()``) and, in the same process, frame by frame
    in turn, the loop with the player scripted: the frame of each ("live", "scripted") and the median of the
    frame-by-frame differences."""
    scene = _scene(overrides, path)
    live_scene, name, twin = live_twin(scene)
    sims = {"scripted": Simulation(scene, arch=arch), "live": Simulation(live_scene, arch=arch)}
    ms = {k: {"drive": [], "advance_to": [], "impacts": [], "changes": [], "frame": []} for k in sims}
    rows = []
    for f in range(warm + frames):
        p = twin.pose(f / fps)
        for k, sim in sims.items():
            a = 0.0
            if k == "live":
                _, a = _timed(lambda: sim.drive(name, p.position, p.heading, speed=p.speed, yaw_rate=p.yaw_rate))
            _, b = _timed(lambda: sim.advance_to(f / fps))
            _, c = _timed(sim.impacts)
            ch, d = _timed(sim.changes)
            if f >= warm and k == "live":
                rows.append(len(ch.ids))
            if f >= warm:
                for part, v in zip(ms[k], (a, b, c, d, a + b + c + d)):
                    ms[k][part].append(v)
    out = {k: {part: _stats(v) for part, v in parts.items()} for k, parts in ms.items()}
    diff = np.asarray(ms["live"]["frame"]) - np.asarray(ms["scripted"]["frame"])
    out.update(extra_ms=float(np.median(diff)), extra_p95_ms=float(np.percentile(diff, 95)), dt=sims["live"].dt,
               steps_per_frame=(1.0 / fps) / sims["live"].dt, rocks=sims["live"].n_rocks, frames=frames, warm=warm,
               vehicle=name, rows_median=float(np.median(rows)), loops=sims["live"].loops)
    return out


def measure_loop(overrides: dict, arch: str, frames: int, warm: int, fps: float = 60.0, path=SCENE,
                 loops: str = "auto") -> dict:
    """The game loop in this process: ``warm`` frames, then ``frames`` timed ones; ``loops``: the step's variant
    ("auto": the engine's choice, engine/variant.py)."""
    timed = _timed
    sim = Simulation(_scene(overrides, path), arch=arch)
    sim.loops = loops
    sim.changes()
    for f in range(warm):
        sim.advance_to(f / fps)
        sim.impacts()
        sim.changes()
    parts = {"advance_to": [], "impacts": [], "changes": [], "frame": []}
    state_ms, rows, hits = [], [], 0
    for f in range(warm, warm + frames):
        _, a = timed(lambda: sim.advance_to(f / fps))
        ev, b = timed(sim.impacts)
        ch, c = timed(sim.changes)
        for k, v in zip(parts, (a, b, c, a + b + c)):
            parts[k].append(v)
        rows.append(len(ch["ids"]))
        hits += len(ev)
        if f % 10 == 0:
            state_ms.append(timed(sim.state)[1])
    out = {k: _stats(v) for k, v in parts.items()}
    out["state"] = _stats(state_ms)
    out.update(rows_median=float(np.median(rows)), rows_max=int(max(rows)), impact_events=hits, dt=sim.dt,
               loops_asked=loops, loops=sim.loops, active=sim.active_count,
               steps_per_frame=(1.0 / fps) / sim.dt, rocks=sim.n_rocks, frames=frames, warm=warm,
               detection=sim.scene.sim.detection, integrator=sim.scene.sim.integrator)
    return out


def measure_tasks(overrides: dict, arch: str, steps: int, warm: int, path=SCENE) -> dict:
    """The step's tasks with Taichi's kernel profiler (this process must have started it), in each variant of the
    step (engine/loops.py), the same simulation taking turns: {"parallel": ..., "serial": ...}."""
    sim = Simulation(_scene(overrides, path), arch=arch)
    sim.step(warm)
    out = {}
    for loops in ("parallel", "serial"):
        sim.loops = loops
        sim.step(2)  # compiled before the profiler counts
        ti.sync()
        clear_kernel_tasks()
        sim.step(steps)
        ti.sync()
        records = kernel_tasks()
        rows = task_rows(records, steps)
        device = sum(r.ms for r in records) / steps
        for r in rows:
            r["share"] = r["ms_per_step"] / device if device > 0 else 0.0
        serial = [r for r in rows if r["kind"] == "serial"]
        out[loops] = {"steps": steps, "tasks": rows, "tasks_per_step": len(records) / steps,
                      "parallel_tasks_per_step": sum(1 for r in records if r.kind != "serial") / steps,
                      "launches_per_step": sum(1 for r in records if r.task == 0) / steps,
                      "device_ms_per_step": device, "active": sim.active_count,
                      "largest_serial_us": 1e3 * max((r["median_ms"] for r in serial), default=0.0)}
    return out


def measure_variants(arch: str, sizes, rounds: int) -> dict:
    """The step right after every rock was loaded into the active list (a Simulation's first step, a restore), at
    each bed size of ``sizes`` (rocks at the default scene's density), in the serial and the parallel variant
    taking turns, ``rounds`` each: ms per step (median). Past the crossover the parallel variant wins."""
    base = _scene(dict(CASES[0][1]))
    rows = []
    for n in sizes:
        r0 = base.bed.radius * float(np.sqrt(n / base.bed.rocks))
        sim = Simulation(scene_with(base, {"bed.rocks": int(n), "bed.radius": r0}), arch=arch)
        sim.step(30)
        times = {"serial": [], "parallel": []}
        for r in range(rounds + 1):
            for loops in ("serial", "parallel"):
                sim.loops = loops
                sim.set_rocks(np.zeros(0, np.int64))  # every rock back into the active list
                ti.sync()
                t0 = time.perf_counter()
                sim.step(1)
                ti.sync()
                if r:  # the first round compiles
                    times[loops].append(1e3 * (time.perf_counter() - t0))
        rows.append({"rocks": n, **{f"{k}_ms": float(np.median(v)) for k, v in times.items()}})
        del sim
    return {"rows": rows, "crossover": crossover_of(rows), "threads": threads_in_use()}


def crossover_of(rows: list):
    """The rock count where the parallel variant starts to win (linear between the measured sizes), None when it
    never does in the range, 0 when it always does."""
    prev = None
    for r in rows:
        gain = r["serial_ms"] - r["parallel_ms"]
        if gain > 0:
            if prev is None:
                return 0
            g0, n0 = prev
            return int(n0 + (r["rocks"] - n0) * (-g0) / (gain - g0))
        prev = (gain, r["rocks"])
    return None


def worker(job: dict) -> dict:
    """One job in this process (``python -m taichi_rocks.bench.frame JOB``)."""
    arch = init_taichi(job["arch"], profiler=job["kind"] == "tasks")
    if job["kind"] == "tasks":
        out = measure_tasks(job["overrides"], arch, job["steps"], job["warm"], job["scene"])
    elif job["kind"] == "variants":
        out = measure_variants(arch, job["sizes"], job["rounds"])
        out["task_costs"] = measure_task_costs(calls=20 if job["rounds"] <= 1 else 200)
    elif job["kind"] == "live":
        out = measure_live(job["overrides"], arch, job["frames"], job["warm"], path=job["scene"])
    else:
        out = measure_loop(job["overrides"], arch, job["frames"], job["warm"], path=job["scene"],
                           loops=job.get("loops", "auto"))
    out["threads"] = threads_in_use()
    out["arch"] = arch
    return out


def _run_job(job: dict, threads) -> dict:
    env = dict(os.environ)
    env.pop("TAICHI_ROCKS_THREADS", None)
    if threads is not None:
        env["TAICHI_ROCKS_THREADS"] = str(threads)
    p = subprocess.run([sys.executable, "-m", "taichi_rocks.bench.frame", json.dumps(job)], env=env,
                       capture_output=True, text=True, timeout=3600)
    for line in p.stdout.splitlines():
        if line.startswith(PREFIX):
            return json.loads(line[len(PREFIX):])
    tail = (p.stderr.strip().splitlines() or ["no output"])[-1]
    return {"error": f"exit {p.returncode}: {tail}"}


def accuracy_rows(arch: str, quick: bool) -> list:
    """Flight error, recall at 60 m/s, launch-time bound of each preset (module docstring)."""
    cfg = make_config(quick=True)
    rows = []
    for name, p in PRESETS.items():
        if quick and p["precision"] == "f64" and arch not in ("cpu", "cuda"):
            continue
        ov = {"sim.dt": p["dt"], "sim.integrator": p["integrator"], "sim.detection": p["detection"],
              "sim.precision": p["precision"]}
        b = Built(probe_scene(cfg, ov), arch, f"preset {name}")
        err = _flight_error(b.sim, p)
        det = detection_runs({name: b}, cfg, lambda *a: None)[name]
        top = [x["recall"] for x in det["per_speed"] if x["speed_m_s"] == PRESET_SPEED and x["contacts"]]
        rows.append({"preset": name, **p, "flight_error_m": err, "recall_at_60": top[0] if top else None,
                     "launch_time_bound_m": V_LAUNCH_MAX * p["dt"], "steps_per_60hz_frame": (1 / 60) / p["dt"]})
        del b
    return rows


def _flight_error(sim, p: dict) -> float:
    """The largest error of a 2 s flight (gravity only from an oblique throw, quadratic drag straight up)."""
    dt = p["dt"]
    if abs(round(SAMPLE_EVERY / dt) * dt - SAMPLE_EVERY) > 1e-9:
        return float("nan")
    x0, r = np.array([0.0, 0.0, 50.0]), 0.03
    t, xs = fly(sim, x0[None], np.array([[12.0, 3.0, 15.0]]), np.array([r]), dt, p["integrator"], "none")
    e = float(np.max(np.linalg.norm(xs[0] - exact_gravity(x0, np.array([12.0, 3.0, 15.0]), t), axis=1)))
    _, quad = drag_coefficients(sim.scene)
    r_stored = float(np.float32(r)) if p["precision"] == "f32" else r
    vt = float(np.sqrt(9.81 * r_stored / quad))
    t, xs = fly(sim, x0[None], np.array([[0.0, 0.0, 20.0]]), np.array([r]), dt, p["integrator"], "quadratic")
    ref = exact_quadratic_vertical(x0[2], 20.0, vt, t)
    return max(e, float(np.max(np.abs(xs[0][:, 2] - ref))))


def run_frame_study(out_dir="renders/bench", quick: bool = False, arch: str = "cpu", progress=None,
                    overwrite: bool = False, tiny: bool = False) -> dict:
    """Run the study (module docstring); write frame.json and frame.md into ``out_dir``; return the results."""
    out = Path(out_dir)
    check_out_dir(out, OUTPUTS, overwrite)
    frames, warm = (20, 5) if tiny else (120, 60) if quick else (270, 60)
    scene = Path(__file__).resolve().parents[2] / "scenes" / "minimal.toml" if tiny else SCENE
    cores = os.cpu_count() or 1
    threads = [] if tiny or arch != "cpu" else sorted({1, cores})
    # each case: 1 thread, every core and the engine's thread count, each with the engine's choice of the step's
    # variant; and on every core the parallel variant forced (the A/B of the variants, engine/variant.py)
    forced = [(cores, "parallel")] if arch == "cpu" and cores > 1 else []
    loops = [(name, ov, t, v) for name, ov in CASES for t, v in [(t, "auto") for t in threads + [None]] + forced]
    prog = Progress(len(loops) + 4, progress)
    res = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": machine(arch), "load_average_start": loadavg(),
           "scene": scene.name, "fps": 60.0, "auto_threads": auto_threads(), "loops": [], "errors": []}
    with new_folders(out):
        for name, ov, t, v in loops:
            job = {"kind": "loop", "arch": arch, "overrides": ov, "frames": frames, "warm": warm, "scene": str(scene),
                   "loops": v}
            r = _run_job(job, t)
            res["loops"].append({"case": name, "threads_asked": t if t is not None else "auto", **r})
            if "error" in r:
                res["errors"].append(f"{name}, {t} threads, {v} loops: {r['error']}")
            prog(f"frame: {name}, {t or 'auto'} threads, {v} loops")
        job = {"kind": "live", "arch": arch, "overrides": dict(LIVE[1]), "frames": frames, "warm": warm,
               "scene": str(scene)}
        r = _run_job(job, None)
        res["live"] = r
        if "error" in r:
            res["errors"].append(f"{LIVE[0]}: {r['error']}")
        else:
            res["loops"].append({"case": LIVE[0], "threads_asked": "auto", "threads": r["threads"],
                                 "loops_asked": "auto", "loops": r.get("loops", "serial"),
                                 "steps_per_frame": r["steps_per_frame"], "rows_median": r["rows_median"],
                                 "frames": r["frames"], "state": {"median_ms": None},  # (the frame has drive())
                                 **{k: r["live"][k] for k in ("drive", "advance_to", "impacts", "changes", "frame")}})
        prog("frame: live player")
        steps = 20 if tiny else 120
        job = {"kind": "tasks", "arch": arch, "overrides": dict(CASES[0][1]), "steps": steps, "warm": 30,
               "scene": str(scene)}
        res["tasks"] = _run_job(job, None)
        prog("frame: tasks")
        sizes = (2_000, 6_000) if tiny else (20_000, 60_000, 200_000) if quick else \
            (10_000, 30_000, 60_000, 100_000, 200_000, 500_000)
        job = {"kind": "variants", "arch": arch, "sizes": list(sizes), "rounds": 1 if tiny else 3 if quick else 5}
        res["variants"] = _run_job(job, cores) if arch == "cpu" else {"error": "the CPU's choice: not measured"}
        prog("frame: variants")
        res["accuracy"] = [] if tiny else accuracy_rows(arch, quick)
        prog("frame: accuracy")
        res["load_average_end"] = loadavg()
        write_atomically(out / "frame.json", lambda f: f.write(json.dumps(res, indent=1).encode()))
        write_atomically(out / "frame.md", lambda f: f.write(("\n".join(report_lines(res)) + "\n").encode()))
    prog.close()
    res["report"] = str(out / "frame.md")
    return res


def _f(x, nd=3) -> str:
    return "n/a" if x is None or (isinstance(x, float) and not np.isfinite(x)) else f"{x:.{nd}g}"


def _ms(x) -> str:
    """A time in ms for a table's cell; "not timed" for None (the live player's row times no ``state()``)."""
    return "not timed" if x is None else f"{_f(x)} ms"


def frame_table(res: dict) -> list:
    """The frame per case and thread count (README and docs/performance.md, tools/readme_tables.py)."""
    L = ["| case | threads | loops | steps / frame | `advance_to` | `impacts()` | `changes()` (rows) | frame median | "
         "frame p95 | `state()` |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in res["loops"]:
        if "error" in r:
            L.append(f"| {r['case']} | {r['threads_asked']} | {r.get('loops_asked', '')} | {r['error']} |||||||")
            continue
        t = f"{r['threads']}" + (" (auto)" if r["threads_asked"] == "auto" else "")
        v = r.get("loops", "parallel") + (" (auto)" if r.get("loops_asked") == "auto" else "")
        L.append(f"| {r['case']} | {t} | {v} | {r['steps_per_frame']:.3g} | {_f(r['advance_to']['median_ms'])} ms | "
                 f"{_f(r['impacts']['median_ms'])} ms | {_f(r['changes']['median_ms'])} ms "
                 f"({r['rows_median']:,.0f}) | **{_f(r['frame']['median_ms'])} ms** | {_f(r['frame']['p95_ms'])} ms "
                 f"| {_ms(r['state']['median_ms'])} |")
    return L


def live_lines(res: dict) -> list:
    """The live player against the scripted one, measured in one process frame by frame in turn."""
    r = res.get("live")
    if not r or "error" in r:
        return [f"(live player: {r.get('error', 'not measured') if r else 'not measured'})"]
    lv, sc = r["live"], r["scripted"]
    return [f"The game frame with the player live (`drive()` each frame with its scripted path's poses, "
            f"{_f(lv['drive']['median_ms'])} ms of it) against the scripted player, in one process, frame by frame "
            f"in turn ({r['threads']} threads): **{_f(lv['frame']['median_ms'])} ms against "
            f"{_f(sc['frame']['median_ms'])} ms** (medians), the frame-by-frame difference "
            f"{_f(r['extra_ms'])} ms (median; 95th percentile {_f(r['extra_p95_ms'])} ms)."]


def task_table(res: dict) -> list:
    """The step's tasks in each variant: kernel, task, what it does, its kind, launches per step, median time and
    share of the step's device time."""
    t = res.get("tasks", {})
    if "error" in t or not t:
        return [f"(task table: {t.get('error', 'not measured')})"]
    # per variant; results written before the variants existed hold the parallel one's alone
    variants = {k: v for k, v in t.items() if isinstance(v, dict) and "tasks" in v} if "tasks" not in t else \
        {"parallel": t}
    L = ["| variant | kernel | task | what | kind | per step | median (µs) | share |", "|---|---|---|---|---|---|---|---|"]
    for name, v in variants.items():
        for r in v["tasks"]:
            share = f"{100 * r['share']:.0f} %" if "share" in r else ""
            L.append(f"| {name} | {r['kernel']} | {r['task']} | {r['what']} | {r['kind']} | {r['per_step']:.3g} | "
                     f"{1e3 * r['median_ms']:.3g} | {share} |")
        if "device_ms_per_step" in v:  # (not in results written before the variants existed)
            L.append(f"| {name} | | | device time per step: **{1e3 * v['device_ms_per_step']:.0f} µs**, "
                     f"{v['tasks_per_step']:.3g} tasks ({v.get('parallel_tasks_per_step', 0):.3g} parallel), "
                     f"{v.get('active', 0):,} rocks active | | | | |")
    return L


def task_cost_table(res: dict) -> list:
    """What a task costs from Python (measure_task_costs): the fixed cost a parallel task pays before any work."""
    t = (res.get("variants") or {}).get("task_costs")
    if not t:
        return ["(task costs: not measured)"]
    L = ["| loop adding 1 to a field of | parallel (`for i in f`) | serial (`ti.loop_config(serialize=True)`) | "
         "4 parallel loops in one kernel |", "|---|---|---|---|"]
    for r in t["rows"]:
        L.append(f"| {r['items']:,} items | {r['parallel_us']:.0f} µs | {r['serial_us']:.0f} µs | "
                 f"{r['four_parallel_us']:.0f} µs |")
    return L + ["", f"An empty kernel: {t['empty_us']:.1f} µs from Python ({t['threads']} threads)."]


def variant_table(res: dict) -> list:
    """The step after loading every rock, per bed size, serial against parallel on every core, and the crossover
    (engine/variant.py CROSSOVER)."""
    v = res.get("variants")
    if not v or "error" in v:
        return [f"(variants: {(v or {}).get('error', 'not measured')})"]
    L = ["| rocks in the step's loops | serial loops | parallel loops | faster |", "|---|---|---|---|"]
    for r in v["rows"]:
        best = "serial" if r["serial_ms"] <= r["parallel_ms"] else "parallel"
        L.append(f"| {r['rocks']:,} | {_f(r['serial_ms'])} ms | {_f(r['parallel_ms'])} ms | {best} |")
    c = v.get("crossover")
    L += ["", "Crossover: " + ("the parallel variant never won in this range" if c is None else
                               "the parallel variant won at every size" if c == 0 else f"about {c:,} rocks") +
          f" ({v.get('threads', '?')} threads)."]
    return L


def accuracy_table(res: dict) -> list:
    L = ["| preset | dt (s) | steps / 60 Hz frame | integrator, detection, precision | flight error, 2 s (m) | "
         "recall at 60 m/s | launch-time bound (m) |", "|---|---|---|---|---|---|---|"]
    for r in res.get("accuracy", []):
        L.append(f"| {r['preset']} | {r['dt']:.4g} | {r['steps_per_60hz_frame']:.3g} | {r['integrator']}, "
                 f"{r['detection']}, {r['precision']} | {_f(r['flight_error_m'])} | {_f(r['recall_at_60'])} | "
                 f"{_f(r['launch_time_bound_m'])} |")
    return L


def report_lines(res: dict) -> list:
    m = res["machine"]
    L = [f"# The frame in a game loop ({res['scene']}, 60 Hz)", "",
         f"{res['started']}, {m.get('cpu_model', '?')}, {m.get('usable_cores', '?')} cores, arch "
         f"{m.get('taichi_arch', '?')}, load "
         f"{res['load_average_start']} -> {res.get('load_average_end')}; the engine's thread choice here: "
         f"{res['auto_threads']}.", "",
         "Per frame: `advance_to(f / 60)`, `impacts()`, `changes()`; medians (and the frame's 95th percentile) "
         "over the timed frames. `state()` (every rock) for comparison.", ""]
    L += frame_table(res)
    L += [""] + live_lines(res)
    L += ["", "## The step's tasks, game preset (kernel profiler), in both variants", ""] + task_table(res)
    L += ["", "## The variants' crossover: the step with every rock active", ""] + variant_table(res)
    L += ["", "## What a task costs from Python", ""] + task_cost_table(res)
    L += ["", "## What each preset costs in accuracy", ""] + accuracy_table(res)
    if res["errors"]:
        L += ["", "Errors: " + "; ".join(res["errors"])]
    return L


if __name__ == "__main__":
    print(PREFIX + json.dumps(worker(json.loads(sys.argv[1]))), flush=True)
