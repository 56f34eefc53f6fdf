"""4. Cost against activity: the step's time against the number of rocks N at fixed activity, and against
activity (rocks in the air, vehicles, speed) at fixed N; the memory per rock.

Every job of points runs in a process of its own (the sweep runner, runner/tasks.py: locally one at a time,
or spread over a Ray cluster; ``python -m taichi_rocks.bench.activity JOB`` runs one by hand), so that its memory is
its own (Taichi never frees fields) and no point's fields or compiled kernels weigh on another's (the tiny
configuration of the tests, ``act_isolated`` False, runs all but the profiled job in the calling process: its
memory figures are then not each point's own). A point:
build the fleet scene, step 1 s (steady state: rocks in the air, the bed's rim moving), read the memory
(``/proc/self/status``: VmRSS and VmHWM, against the process's RSS before the simulation was built; and the
bytes of the World's fields), then time rounds of m steps (``ti.sync()`` around each round) interleaved with
the streaming floor of the same N (peers.py: one fused pass over N rocks' position and velocity), medians of
the rounds. The rocks in the air (phase != resting) and the active list's length are read after the rounds.

Series against N (the same vehicles, formation and speed at every point):
  (a) fixed bed radius: density, and so the rocks thrown and recycled per step, grow with N;
  (b) fixed density (that of the reference N on the radius of (a); the bed radius grows as sqrt(N)): the same
      rocks in the air; the rim, and so the rocks recycled per step, grows as sqrt(N).
Against activity at the reference N: rear tires (vehicles), speed, a parked fleet, and the `balanced` preset.

Where a step's time goes (``act_profile_n``, series (a), active stepping), in a process of its own with
Taichi's kernel profiler on: the host side of a step (the engine's timing hook, "vehicles + rays"), the
launches (kernels launched and offloaded tasks per step, parallel or serial, from the profiler's records) and
each task's time on the device (medians over the steps; engine/probes.py names them); the series (a) point of
that N also measures what a launch costs in Python for the step's arguments (engine/probes.py
``launch_costs``: the profiler, on, adds to every launch).
"""

from __future__ import annotations

import gc
import json
import math
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import taichi as ti

from ..config.presets import PRESETS
from ..engine import probes
from ..engine.runtime import init_taichi
from ..engine.simulation import Simulation
from ..engine.timing import NO_TIMER, PassTimer, clear_kernel_tasks, kernel_tasks
from ..output.atomic import new_folders, write_atomically
from .config import make_config
from .machine import Progress, loadavg, machine
from .measure import timed_call
from .peers import Floor
from .plots import PNG, plot_activity
from .report import _activity, _targets, check_out_dir, jsonable
from .scenes import fleet_scene

try:
    import resource  # Unix only: the peak memory where /proc is missing
except ImportError:
    resource = None

from ..runner.tasks import WHOLE_NODE, run_tasks

from ..config.keys import choices

PREFIX = "ACTIVITY-POINT "
MB = 1024.0 * 1024.0


# --------------------------------------------------------------------------------------------- the points
def series_radius(cfg, series: str, n: int) -> float:
    """Bed radius of a point of series "a" (fixed radius) or "b" (the density of act_ref_n on that radius)."""
    if series == "a":
        return float(cfg.act_radius)
    return float(cfg.act_radius) * math.sqrt(n / cfg.act_ref_n)


def _point(cfg, label, n, radius, t_rear=None, speed=None, stepping="active", accuracy=None, memory=False,
           floor=False, group="", profile=False, launch=False):
    return {"label": label, "group": group, "n": int(n), "radius": float(radius), "profile": profile, "launch": launch,
            "t_rear": int(cfg.act_t if t_rear is None else t_rear),
            "speed": float(cfg.act_speed if speed is None else speed), "stepping": stepping, "accuracy": accuracy,
            "memory": memory, "floor": floor, "spread": float(cfg.act_radius)}


def plan_jobs(cfg) -> list:
    """The processes of the section, each a list of points: one per (series, N, stepping) with its memory
    and floor, then one for the activity sweep at the reference N. A series-(b) point whose bed equals the
    series-(a) one (at the reference N) is measured once."""
    jobs = []
    for series in ("a", "b"):
        for n in cfg.act_n:
            r = series_radius(cfg, series, n)
            if series == "b" and abs(r - cfg.act_radius) < 1e-9:
                continue
            for stepping in choices("sim.stepping"):
                if stepping == "full" and not cfg.act_full_min <= n <= cfg.act_full_max:
                    continue
                launch = series == "a" and stepping == "active" and n in cfg.act_profile_n
                jobs.append([_point(cfg, f"{series} N={n:,} {stepping}", n, r, stepping=stepping, memory=True,
                                    floor=True, group=f"series {series}", launch=launch)])
    n, r = cfg.act_fixed_n, cfg.act_radius
    sweep = [_point(cfg, f"{t} rear tires", n, r, t_rear=t, group="tires") for t in cfg.act_tires]
    sweep += [_point(cfg, f"{v:g} m/s", n, r, speed=v, group="speed") for v in cfg.act_speeds]
    sweep.append(_point(cfg, "parked fleet (0 m/s)", n, r, speed=0.0, group="parked"))
    if cfg.act_balanced:
        sweep.append(_point(cfg, "balanced preset", n, r, accuracy="balanced", group="balanced"))
    jobs.append(sweep)
    jobs.append([_point(cfg, f"profile N={m:,}", m, r, group="profile", profile=True) for m in cfg.act_profile_n])
    return jobs


def point_scene(p: dict):
    ov = {"sim.stepping": p["stepping"]}
    if p["accuracy"]:
        ov["sim.accuracy"] = p["accuracy"]
        ov.update({f"sim.{k}": v for k, v in PRESETS[p["accuracy"]].items()})
    return fleet_scene(p["n"], p["t_rear"], p["radius"], ov, speed=p["speed"], spread=p["spread"])


# --------------------------------------------------------------------------------------------- a worker
def proc_memory() -> dict:
    """VmRSS and VmHWM (bytes) of this process (Linux), else the peak from getrusage."""
    out = {}
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            key, _, rest = line.partition(":")
            if key in ("VmRSS", "VmHWM"):
                out[key] = int(rest.split()[0]) * 1024
    except OSError:
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
        out = {"VmRSS": peak, "VmHWM": peak}
    return out


def field_bytes(world) -> int:
    """Bytes of a World's data on the device (its ndarray groups: engine/worlddata.py)."""
    return world.nbytes()


def _memory(sim, base: dict) -> dict:
    now = proc_memory()
    fb = field_bytes(sim.world)
    grow = now["VmHWM"] - base["VmRSS"]
    return {"baseline_rss_mb": base["VmRSS"] / MB, "rss_mb": now["VmRSS"] / MB, "hwm_mb": now["VmHWM"] / MB,
            "hwm_growth_bytes_per_rock": grow / sim.n_rocks,
            "rss_growth_bytes_per_rock": (now["VmRSS"] - base["VmRSS"]) / sim.n_rocks,
            "field_mb": fb / MB, "field_bytes_per_rock": fb / sim.n_rocks}


def _timed_rounds(sim, floor, rounds: int, m: int) -> tuple:
    """Rounds of (m steps timed as one block, two floor passes timed each): ms per step and ms per pass."""
    st, fl = [], []
    if floor is not None:
        floor.run()
    for _ in range(rounds):
        st.append(1e3 * timed_call(lambda: sim.step(m)) / m)
        if floor is not None:
            fl += [1e3 * timed_call(floor.run) for _ in range(2)]
    ti.sync()
    return st, fl


def run_point(p: dict, cfg: dict, arch: str) -> dict:
    """Build, step to steady state, memory, timed rounds (with the floor), rocks in the air."""
    base = proc_memory()
    t0 = time.perf_counter()
    sim = Simulation(point_scene(p), arch=arch)
    sim.step(1)
    ti.sync()
    out = dict(p, build_s=time.perf_counter() - t0, dt=sim.dt, t_rear=2 * len(sim.fleet.splashing),
               integrator=sim.scene.sim.integrator, detection=sim.scene.sim.detection,
               stepping_plan="active" if sim.plan.active else "full")
    warm = max(1, int(round(cfg["act_warm_s"] / sim.dt)) - 1)
    t1 = time.perf_counter()
    sim.step(warm)
    ti.sync()
    out["warm_steps"], out["warm_s"] = warm + 1, time.perf_counter() - t1
    if p["memory"]:
        out["memory"] = _memory(sim, base)
    floor = None
    if p["floor"]:
        r = sim.rock_arrays()
        floor = Floor(sim.n_rocks)
        floor.load(r["pos"], r["vel"])
        del r
    st, fl = _timed_rounds(sim, floor, cfg["act_rounds"], cfg["act_steps"])
    out["step_rounds_ms"] = st
    out["step_ms"] = float(np.median(st))
    out["floor_ms"] = float(np.median(fl)) if fl else None
    phase = sim.rock_arrays()["phase"]
    out["in_air"] = int(np.count_nonzero(phase))
    out["active_count"] = sim.active_count
    out["launches_total"], out["recycles_total"] = sim.launches_total, sim.recycles_total
    out["steps_coasted"] = int(sim.steps_coasted)
    out["sim_s_per_wall_s"] = sim.dt / (out["step_ms"] * 1e-3)
    if p.get("launch"):
        out["launch_us"] = probes.launch_costs(sim)
    del sim, floor
    gc.collect()
    return out


def task_rows(records: list, steps: int) -> list:
    """Per (kernel, task): what it does, its kind, its launches per step and its median and minimum ms."""
    labels = probes.task_labels()
    by = {}
    for r in records:
        by.setdefault((r.kernel, r.task), []).append(r)
    rows = []
    for (kernel, task), rs in by.items():
        n_tasks = 1 + max(t for k, t in by if k == kernel)
        names = next((v for v in labels.get(kernel, ()) if len(v) == n_tasks), None)
        what = names[task] if names else f"task {task}"
        ms = np.array([r.ms for r in rs])
        rows.append({"kernel": kernel, "task": task, "what": what, "kind": rs[0].kind, "per_step": len(rs) / steps,
                     "median_ms": float(np.median(ms)), "min_ms": float(ms.min()), "ms_per_step": float(ms.sum()) / steps})
    rows.sort(key=lambda x: (x["kernel"] != "active_step", x["kernel"], x["task"]))
    return rows


def run_profile(p: dict, cfg: dict, arch: str) -> dict:
    """Where a step's time goes (module docstring), Taichi's kernel profiler on: steps timed as a block, then
    with the engine's timing hook (host side against the launches), then the profiler's records of as many
    steps, then the launch probe."""
    sim = Simulation(point_scene(p), arch=arch)
    sim.step(max(1, int(round(cfg["act_warm_s"] / sim.dt))))
    ti.sync()
    m = cfg["act_rounds"] * cfg["act_steps"]
    out = dict(p, t_rear=2 * len(sim.fleet.splashing), steps=m)
    out["step_ms"] = 1e3 * min(timed_call(lambda: sim.step(cfg["act_steps"])) for _ in range(cfg["act_rounds"])) \
        / cfg["act_steps"]
    timer = sim.timer = PassTimer()
    sim.step(m)
    sim.timer = NO_TIMER
    out["passes_ms"] = timer.ms_per_step(m)
    out["host_ms"] = out["passes_ms"].get("vehicles + rays", 0.0)
    clear_kernel_tasks()
    sim.step(m)
    ti.sync()
    records = kernel_tasks()
    out["launches_per_step"] = sum(1 for r in records if r.task == 0) / m
    out["tasks_per_step"] = len(records) / m
    out["parallel_tasks_per_step"] = sum(1 for r in records if r.kind != "serial") / m
    out["device_ms"] = sum(r.ms for r in records) / m
    out["tasks"] = task_rows(records, m)
    out["in_air"] = int(np.count_nonzero(sim.rock_arrays()["phase"]))
    out["active_count"] = sim.active_count
    out["loops"] = sim.loops  # the step's variant that ran (engine/variant.py)
    sim = None  # the World goes back to the pool (a del here reads as an undefined name in the lambda above)
    gc.collect()
    return out


def run_points(job: dict) -> dict:
    """One job's points in order, in this process (a worker of the sweep runner, runner/tasks.py): their
    results, or an error each. A job of profile points starts Taichi with its kernel profiler on."""
    arch = init_taichi(job["arch"], profiler=any(p.get("profile") for p in job["points"]))
    out = []
    for p in job["points"]:
        try:
            out.append(run_profile(p, job["cfg"], arch) if p.get("profile") else run_point(p, job["cfg"], arch))
        except Exception as exc:  # a point that fails is reported, the others still run
            out.append(dict(p, error=f"{type(exc).__name__}: {exc}".splitlines()[0]))
    return {"points": out}


def worker(job_json: str) -> int:
    """Run one job's points (``python -m taichi_rocks.bench.activity JOB``); print each result as one line
    (PREFIX + JSON) on stdout."""
    for res in run_points(json.loads(job_json))["points"]:
        print(PREFIX + json.dumps(res), flush=True)
    return 0


# --------------------------------------------------------------------------------------------- the parent
def run_jobs(jobs: list, cfg, arch: str, prog, backend: str = "local", address=None, timeout: float = 3600.0) -> list:
    """Every job in a process of its own, through the sweep runner: one at a time on this machine (each
    point's timing and memory undisturbed), or with ``backend="ray"`` one job per node of the cluster at
    ``address`` at a time (each actor holds a whole node). The points' results (or an error per point) in
    job order."""
    keys = ("act_warm_s", "act_rounds", "act_steps")
    tasks = [{"id": str(i), "arch": arch, "points": job, "cfg": {k: getattr(cfg, k) for k in keys}}
             for i, job in enumerate(jobs)]
    got = {}

    def report(o):
        job = jobs[int(o.task["id"])]
        got[o.task["id"]] = o.result["points"] if o.result else [dict(p, error=o.error) for p in job]
        prog(f"activity: {job[0]['label']}")

    if not cfg.act_isolated and backend == "local":  # the tiny run: all but the profiled job here, at once
        here = [t for t in tasks if not any(p.get("profile") for p in t["points"])]
        for t in here:
            report(SimpleNamespace(task=t, result=run_points(t), error=None))
        tasks = [t for t in tasks if t not in here]
    if backend == "ray":
        run_tasks(tasks, "taichi_rocks.bench.activity:run_points", backend="ray", address=address,
                  threads=WHOLE_NODE, retries=0, report=report, fresh=True)
    else:
        run_tasks(tasks, "taichi_rocks.bench.activity:run_points", workers=1, retries=0, report=report, fresh=True,
                  timeout=timeout)
    return [p for i in range(len(jobs)) for p in got[str(i)]]


def _by_n(points: list, series: str, cfg) -> list:
    """The rows of a series against N: per N the active and full points and the floor."""
    rows = []
    for n in cfg.act_n:
        r = series_radius(cfg, series, n)
        s = "a" if abs(r - cfg.act_radius) < 1e-9 else series
        row = {"n": n, "radius": r}
        for stepping in choices("sim.stepping"):
            row[stepping] = next((p for p in points if p["label"] == f"{s} N={n:,} {stepping}"), None)
        act = row["active"] if row["active"] and "error" not in row["active"] else None
        row["floor_ms"] = act["floor_ms"] if act else None
        rows.append(row)
    return rows


def memory_summary(rows: list) -> dict:
    """Per stepping mode: bytes per rock (the slope of peak RSS between the two largest N, and at the largest N
    growth / N) and the 10M projection; the fields' bytes per rock."""
    out = {}
    for stepping in choices("sim.stepping"):
        pts = [(r["n"], r[stepping]["memory"]) for r in rows
               if r.get(stepping) and "memory" in r[stepping]]
        if not pts:
            continue
        pts.sort(key=lambda x: x[0])
        n_hi, m_hi = pts[-1]
        slope = None
        if len(pts) >= 2:
            n_lo, m_lo = pts[-2]
            slope = (m_hi["hwm_mb"] - m_lo["hwm_mb"]) * MB / (n_hi - n_lo)
        basis = "peak RSS slope" if slope and slope > 0 else "field bytes"
        per_rock = slope if basis == "peak RSS slope" else m_hi["field_bytes_per_rock"]
        proj = m_hi["hwm_mb"] * MB + per_rock * (10_000_000 - n_hi)
        out[stepping] = {"largest_n": n_hi, "hwm_mb_at_largest": m_hi["hwm_mb"],
                         "growth_bytes_per_rock_at_largest": m_hi["hwm_growth_bytes_per_rock"],
                         "slope_bytes_per_rock": slope, "field_bytes_per_rock": m_hi["field_bytes_per_rock"],
                         "peak_10m_gb": proj / 1e9, "peak_10m_basis": "measured" if n_hi == 10_000_000 else
                         f"projected from N={n_hi:,} with the {basis} per rock"}
    return out


def activity_section(cfg, arch: str, prog, backend: str = "local", address=None) -> dict:
    """Run every job of the section (run_jobs); the results by series and sweep."""
    t0 = time.perf_counter()
    points = run_jobs(plan_jobs(cfg), cfg, arch, prog, backend, address)
    res = {"points": points, "series": {s: _by_n(points, s, cfg) for s in ("a", "b")},
           "sweep": [p for p in points if p["group"] in ("tires", "speed", "parked", "balanced")],
           "profile": [p for p in points if p["group"] == "profile"],
           "reference_n": cfg.act_fixed_n, "radius": cfg.act_radius, "t_rear": cfg.act_t,
           "speed": cfg.act_speed, "density_b": cfg.act_ref_n / (math.pi * cfg.act_radius ** 2),
           "isolated": bool(cfg.act_isolated)}
    res["memory"] = {s: memory_summary(res["series"][s]) for s in ("a", "b")}
    res["errors"] = [f"activity {p['label']}: {p['error']}" for p in points if "error" in p]
    res["elapsed_s"] = time.perf_counter() - t0
    return res


# --------------------------------------------------------------------------------------------- targets
def _verdict(value, limit, at_most: bool) -> tuple:
    """(met, "PASS/MISS ... by how much") of a measured value against its limit."""
    met = value <= limit if at_most else value >= limit
    if at_most:
        how = f"{100 * (1 - value / limit):.0f} % under the limit" if met else f"{value / limit:.2f}x the limit"
    else:
        how = f"{value / limit:.2f}x the limit" if met else f"{100 * (1 - value / limit):.0f} % short"
    return met, ("PASS, " if met else "MISS, ") + how


def _ok(p):
    return p if p and "error" not in p and p.get("step_ms") else None


def activity_targets(act: dict, cfg) -> list:
    """The targets of a step whose cost is the work, each with its measured ratio, PASS / MISS and by how
    much: at the reference N (1M) against the streaming floor of that N; at the smallest N of series (a)
    (100k) against the same floor and against full stepping there; the balanced preset against real time;
    the largest N against the reference N, series (a) (the fixed 30 m bed) and (b)."""
    out = []
    n_ref = cfg.act_fixed_n
    note = "" if n_ref == 1_000_000 else f" ({cfg.mode} run: N={n_ref:,}; the target is stated at 1M)"

    def add(name, value, limit, at_most, detail, at, also=None):
        if value is None:
            out.append({"target": name, "value": None, "limit": limit, "met": None, "detail": detail, "at": at})
            return
        met, how = _verdict(value, limit, at_most)
        if also is not None and not also[0]:  # a second condition that failed
            met, how = False, f"MISS, {also[1]}; {how.split(', ', 1)[1]}"
        out.append({"target": name, "value": value, "limit": limit, "met": bool(met), "detail": f"{how}: {detail}",
                    "at": at})

    rows = {r["n"]: r for r in act["series"]["a"]}
    ref = _ok(rows.get(n_ref, {}).get("active"))
    floor = ref["floor_ms"] if ref and ref.get("floor_ms") else None
    add(f"step at {n_ref:,} rocks, {cfg.act_t} rear tires <= 0.5x the streaming floor of {n_ref:,} rocks",
        ref["step_ms"] / floor if floor else None, 0.5, True,
        f"{ref['step_ms']:.3f} ms vs floor {floor:.3f} ms, {ref['in_air']:,} rocks in the air" if floor else
        "not measured", f"series (a), R = {cfg.act_radius:g} m{note}")
    n_lo = min(rows)
    lo = _ok(rows[n_lo].get("active"))
    full = _ok(rows[n_lo].get("full"))
    if n_lo < n_ref:
        beats = (full is not None and lo is not None and lo["step_ms"] < full["step_ms"],
                 f"not below full stepping's {full['step_ms']:.3f} ms" if full else "full stepping not measured")
        add(f"step at {n_lo:,} rocks, same formation <= 0.25x the floor of {n_ref:,} rocks and below full "
            "stepping's", lo["step_ms"] / floor if lo and floor else None, 0.25, True,
            f"{lo['step_ms']:.3f} ms vs floor {floor:.3f} ms; full stepping {full['step_ms']:.3f} ms"
            if lo and floor and full else "not measured", f"series (a), R = {cfg.act_radius:g} m", also=beats)
    bal = next((_ok(q) for q in act["sweep"] if q["group"] == "balanced"), None)
    add(f"{n_ref:,} rocks with the balanced preset >= 2x real time (simulated s per wall s)",
        bal["sim_s_per_wall_s"] if bal else None, 2.0, False,
        f"{bal['step_ms']:.3f} ms per step of {bal['dt'] * 1e3:g} ms ({bal['integrator']}, {bal['detection']})"
        if bal else "not measured", f"N={n_ref:,}, {cfg.act_t} rear tires{note}")
    for series, what in (("a", f"fixed bed radius {cfg.act_radius:g} m (the issue's fleet scene)"),
                         ("b", "fixed density (bed radius grows as sqrt(N))")):
        by = {r["n"]: r for r in act["series"][series]}
        hi = max(by)
        lo_n = n_ref if n_ref < hi else sorted(by)[-2] if len(by) > 1 else hi
        a, b = _ok(by[hi].get("active")), _ok(by.get(lo_n, {}).get("active"))
        add(f"step({hi:,}) <= 1.5x step({lo_n:,}), series ({series})", a["step_ms"] / b["step_ms"] if a and b else None,
            1.5, True, f"{a['step_ms']:.3f} / {b['step_ms']:.3f} ms; {a['in_air']:,} / {b['in_air']:,} rocks in the "
            "air" if a and b else "not measured",
            what + ("" if hi == 10_000_000 else f" ({cfg.mode} run: the target is stated at 10M vs 1M)"))
    return out


# --------------------------------------------------------------------------------------------- --only activity
def run_activity_study(out_dir="renders/bench", quick: bool = False, arch: str = "cpu", progress=None,
                       tiny: bool = False, overwrite: bool = False, backend: str = "local", address=None) -> dict:
    """`taichi-rocks bench --only activity`: this section alone; writes activity.md (its targets and the
    section), activity.json and activity.png to ``out_dir`` (atomically), which must not hold them already
    unless ``overwrite`` (FileExistsError before anything runs). ``backend``, ``address``: see run_jobs."""
    cfg = make_config(quick=quick, tiny=tiny)
    out = Path(out_dir)
    check_out_dir(out, ("activity.md", "activity.json", PNG["activity"]), overwrite)
    with new_folders(out):
        used = init_taichi(arch)
        prog = Progress(count_jobs(cfg), progress)
        res = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": machine(used), "mode": cfg.mode,
               "load_average_start": loadavg()}
        res["activity"] = act = activity_section(cfg, used, prog, backend, address)
        res["targets"] = activity_targets(act, cfg)
        res["load_average_end"] = loadavg()
        res["errors"] = act["errors"]
        plots = [plot_activity(res, out)]
        m = res["machine"]
        head = [f"# taichi-rocks benchmark: cost against activity\n",
                f"Mode **{cfg.mode}**, {act['elapsed_s']:.0f} s, {res['started']}; {m['cpu_model']}, "
                f"{m['usable_cores']} usable cores, {m['memory_gb']} GB; Taichi {m['taichi']} ({used}). Load average "
                f"(1, 5, 15 min) at the start {res['load_average_start']}, at the end {res['load_average_end']}.\n"]
        text = "\n".join(head + _targets(res, plots) + _activity(res, plots)
                         + [f"- error: {e}" for e in res["errors"]])
        write_atomically(out / "activity.md", lambda f: f.write(text.encode()))
        blob = json.dumps(jsonable(res), indent=1)
        write_atomically(out / "activity.json", lambda f: f.write(blob.encode()))
        prog.close()
    res["plots"], res["report"] = plots, str(out / "activity.md")
    return res


def count_jobs(cfg) -> int:
    return len(plan_jobs(cfg)) if getattr(cfg, "activity", False) else 0


if __name__ == "__main__":
    sys.exit(worker(sys.argv[1]))
