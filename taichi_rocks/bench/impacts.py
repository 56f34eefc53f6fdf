"""The impacts study (`taichi-rocks bench --only impacts`, also a section of the full benchmark): stones thrown by
a car or a truck that hit the car following it, counted by following distance and speed (issue 21; the method of
Gruen, Schoenberger & Schulz, FISITA 2010, F2010-C-098: hits and their surface-normal momentum).

Setup of a run (:func:`study_scene`). Five lanes side by side, 10 m apart, one per gap (5, 10, 20, 30 and 40 m,
the clear distance from the leader's rear to the follower's front; the long gaps in the middle lanes, where the
bed is widest): in each a leader (car or truck: it throws, ``hit = false``) and a follower (a car: ``splash =
false``, ``hit = true``), all driving straight along +x at the run's speed. The bed (30 m, the shipped convoy's
70 rocks per m^2) follows a pacer that neither throws nor is hit, placed so that every leader's rear tires and
every follower's windscreen lie at least 2 m inside it: a thrown stone lies nearly where it was thrown in the
ground frame while the vehicles drive on, so the bed must hold it until the follower g m back has passed it.
The throw's scatter is +-8 deg ([launch] spread): a stone thrown 40 m back drifts at most 5.6 m sideways, so a
lane's follower is hit by its own leader's stones only; events carry their thrower, and hits across lanes are
counted and reported. A run's variables: leader, speed, wetness, gravel class (coarse: r 7.5-25 mm; road
chippings: r 2-8 mm), mud flaps on the leader; everything else is the scene format's default. The throw's
settings are those of the launch study (bench/launch.py: accuracy "balanced", detection "patch"), whose bands
are measured on its reference case here too (the launch case, one more task), with the same car through the
coarse gravel: which releases lift stones over 20 mm above a car's bonnet line (the events carry no launch).

Distance (adaptive): the vehicles first drive ``warm_m`` (the stones of the start reach the farthest follower;
its events are dropped), then ``min_m``, then on in chunks of ``chunk_m`` until every lane has ``enough``
windscreen hits or its 95 % upper bound is under ``bound_per_km``, or ``max_m`` is driven.

One compile: every run of a study has the same World layout (the same rock count, vehicles, tire count, hash
cell (2 r_max of the coarse gravel, for both classes), hash table and the largest tire radius (the pacer's wheels
are the truck's)); wetness, gravel radii and mud flaps are runtime values. The runs go through the sweep runner
(runner/tasks.py) on ``workers`` processes, each keeping its Taichi runtime and World pool from run to run.
The analysis and the targets: bench/impacts_analysis.py; plots and the report: bench/impacts_report.py.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

from ..config.scene import parse_scene
from ..engine.runtime import init_taichi
from ..engine.simulation import Simulation
from ..output.atomic import new_folders
from ..runner.tasks import Outcome, error_line, run_tasks
from . import launch as launch_study
from .impacts_analysis import BIG_RADIUS, GRAVEL, WINDSCREEN, poisson_upper, summary
from .impacts_report import OUTPUTS, write_outputs
from .machine import Progress, loadavg, machine
from .report import check_out_dir

GAPS = (5.0, 10.0, 20.0, 30.0, 40.0)
LANE_SPACING = 10.0  # m between lanes
CELL = 0.05  # m: the hash cell of both classes (2 r_max of the coarse gravel): one World layout
TABLE = 8191  # hash slots, a prime: above "auto" for every leader and gravel (~3,800-4,000), so one layout
FOLLOWER = {"kind": "car"}  # the scene format's default car (4.5 x 1.8 x 1.4 m)
LEADERS = {"car": {"kind": "car"},
           "truck": {"kind": "truck", "length": 8.0, "width": 2.5, "height": 3.2, "wheelbase": 5.0, "track": 2.1,
                     "tire_radius": 0.5, "tire_width": 0.3}}  # the shipped convoy's truck
PACER = {"kind": "car", "tire_radius": 0.5, "splash": False, "hit": False}  # wheels as the truck's: one layout
INSIDE = 2.0  # m: the leaders' tires and the followers' windscreens lie this far inside the bed
SEED = 1  # every run the same seed: comparisons (flaps on / off, dry / wet) see the same bed
BONNET_Z = 0.95  # m: about the default car's bonnet line (its bonnet's hits are at 0.96 m)


@dataclasses.dataclass(frozen=True)
class StudyConfig:
    mode: str
    leaders: tuple = ("car", "truck")
    speeds: tuple = (10.0, 15.0, 20.0, 22.5, 25.0, 30.0)
    wetness: tuple = (0.0, 1.0)
    gravels: tuple = ("coarse", "chippings")
    flaps: tuple = (False, True)
    gaps: tuple = GAPS
    radius: float = 30.0  # m, at least (grown if the lanes need more)
    density: float = 70.7  # rocks per m^2 (the shipped convoy: 200,000 on 30 m)
    warm_m: float = 50.0
    min_m: float = 400.0
    max_m: float = 1000.0
    chunk_m: float = 200.0
    enough: int = 20
    bound_per_km: float = 10.0
    workers: int = 2  # 0: every run in this process (tests)
    launch: str | None = "quick"  # the launch study's size for its bands' case (None: not run)
    timeout_s: float = 3600.0


def make_study_config(mode: str = "full") -> StudyConfig:
    """"full": the issue's grid (+ 22.5 m/s for the long tail), 96 runs (over 70 min on 2 busy cores); "quick":
    10, 20 and 25 m/s, dry, both gravels, 24 runs (~8 min): the smallest grid that measures every target (the
    coarse gravel for "large stones stay low"); "tiny": one short run (tests)."""
    if mode == "full":
        return StudyConfig("full")
    if mode == "quick":
        return StudyConfig("quick", speeds=(10.0, 20.0, 25.0), wetness=(0.0,), gravels=("chippings", "coarse"),
                           min_m=200.0, max_m=400.0, chunk_m=100.0, bound_per_km=15.0)
    if mode == "tiny":
        return StudyConfig("tiny", leaders=("car",), speeds=(20.0,), wetness=(0.0,), gravels=("chippings",),
                           flaps=(False,), gaps=(5.0, 10.0), radius=8.0, density=40.0, warm_m=10.0, min_m=20.0,
                           max_m=20.0, chunk_m=20.0, workers=0, launch=None)
    raise ValueError(f"impacts study: mode must be full, quick or tiny, got {mode!r}")


# --------------------------------------------------------------------------------------------- the scene
def lane_layout(gaps) -> list:
    """(gap, lane y) with the longest gap in the middle lane and the shorter ones outwards, alternating sides."""
    order = sorted(gaps, reverse=True)
    return [(g, LANE_SPACING * ((k + 1) // 2) * (1.0 if k % 2 else -1.0) + 0.0) for k, g in enumerate(order)]


def _vehicle(spec: dict, key: str):
    return spec.get(key, {"length": 4.5, "wheelbase": 2.7, "track": 1.6, "width": 1.8}[key])


def placement(leader: str, gaps, radius: float) -> dict:
    """Body centres (x at t = 0, y) of the lanes' leaders and followers and of the pacer, and the bed radius:
    the pacer sits where the bed (at least ``radius``) holds every leader's rear tires and every follower's
    windscreen INSIDE m inside its rim."""
    lead = LEADERS[leader]
    l_lead, l_f = _vehicle(lead, "length"), _vehicle(FOLLOWER, "length")
    lanes, points = [], []
    for gap, y in lane_layout(gaps):
        xf = -(0.5 * l_lead + gap + 0.5 * l_f)
        lanes.append({"gap": gap, "y": y, "leader_x": 0.0, "follower_x": xf})
        for side in (-0.5, 0.5):
            points.append((-0.5 * _vehicle(lead, "wheelbase"), y + side * _vehicle(lead, "track")))
        points.append((xf + 0.5 * l_f - 1.5, y))  # the foot of the follower's windscreen, about
    pts = np.array(points)
    xs = np.linspace(pts[:, 0].min(), pts[:, 0].max(), 401)
    reach = [np.hypot(pts[:, 0] - x, pts[:, 1]).max() for x in xs]
    k = int(np.argmin(reach))
    return {"lanes": lanes, "pacer_x": float(xs[k]), "radius": float(max(radius, reach[k] + INSIDE))}


def study_scene(run: dict):
    """The scene of one run (module docstring): ``run`` holds leader, speed, wet, gravel, flaps, gaps, radius,
    density, and the distance to drive (warm_m + max_m)."""
    v = float(run["speed"])
    place = placement(run["leader"], run["gaps"], run["radius"])
    duration = (run["warm_m"] + run["max_m"]) / v + 5.0
    far = v * duration + 200.0

    def path(x, y):
        return {"points": [[x, y], [x + far, y]], "speed": v}

    vehicles = [dict(PACER, name="pacer", path=path(place["pacer_x"], 0.0))]
    for k, lane in enumerate(place["lanes"]):
        vehicles.append(dict(LEADERS[run["leader"]], name=f"leader{k}", hit=False, mud_flaps=bool(run["flaps"]),
                             path=path(lane["leader_x"], lane["y"])))
        vehicles.append(dict(FOLLOWER, name=f"follower{k}", splash=False, hit=True,
                             path=path(lane["follower_x"], lane["y"])))
    r = place["radius"]
    data = {"name": "impacts_study", "seed": SEED, "duration": duration, "world": {"wetness": float(run["wet"])},
            "bed": {"radius": r, "rocks": int(round(run["density"] * math.pi * r * r)),
                    "rock_radius": list(GRAVEL[run["gravel"]]), "follow": "pacer"},
            "sim": {"accuracy": "balanced", "detection": "patch", "hash": {"cell_size": CELL, "table_size": TABLE}},
            "effects": {"impacts": True}, "camera": {"follow": "pacer"}, "vehicle": vehicles}
    return parse_scene(data, source="<impacts study>")


def lane_indices(scene, gaps) -> list:
    """Per lane: its gap and the scene indices of its leader and follower."""
    return [{"gap": gap, "y": y, "leader": scene.vehicle_index(f"leader{k}"),
             "follower": scene.vehicle_index(f"follower{k}")} for k, (gap, y) in enumerate(lane_layout(gaps))]


# --------------------------------------------------------------------------------------------- a run
def _resolved(events: np.ndarray, lanes: list, km: float, enough: int, bound: float) -> bool:
    """Every lane has ``enough`` windscreen hits, or its 95 % upper bound per km is under ``bound``."""
    for lane in lanes:
        n = int(np.count_nonzero((events["vehicle"] == lane["follower"]) & (events["thrower"] == lane["leader"])
                                 & (events["part"] == WINDSCREEN)))
        if n < enough and poisson_upper(n) / km > bound:
            return False
    return True


def drive(sim, metres: float, speed: float, chunks: list) -> None:
    """Step until the vehicles have driven ``metres`` more, draining the events every simulated second."""
    steps = int(round(metres / speed / sim.dt))
    per = max(1, int(round(1.0 / sim.dt)))
    while steps > 0:
        n = min(per, steps)
        sim.step(n)
        steps -= n
        chunks.append(sim.impacts())


def run_point(task: dict) -> dict:
    """One run (a worker of the sweep runner): build, warm up, drive the adaptive distance; the events and the
    run's figures."""
    arch = init_taichi(task.get("arch", "cpu"))
    if task.get("kind") == "launch":
        return launch_case(task, arch)
    t0 = time.perf_counter()
    scene = study_scene(task)
    sim = Simulation(scene, arch=arch)
    lanes = lane_indices(scene, task["gaps"])
    v = float(task["speed"])
    warm = []
    drive(sim, task["warm_m"], v, warm)
    build_s = time.perf_counter() - t0
    t_start, steps0, launches0 = sim.time, sim.step_count, sim.launches_total
    chunks, driven = [], 0.0
    t1 = time.perf_counter()
    while True:
        leg = task["min_m"] if driven == 0.0 else task["chunk_m"]
        drive(sim, min(leg, task["max_m"] - driven), v, chunks)
        driven = v * (sim.time - t_start)
        events = np.concatenate(chunks) if chunks else sim.impacts()
        if driven >= task["max_m"] - 1e-6 or _resolved(events, lanes, driven / 1e3, task["enough"],
                                                       task["bound_per_km"]):
            break
    wall = time.perf_counter() - t1
    steps = sim.step_count - steps0
    out = {k: task[k] for k in ("id", "leader", "speed", "wet", "gravel", "flaps")}
    out.update(lanes=lanes, distance_m=driven, events=events, steps=steps, dt=sim.dt, wall_s=wall,
               build_and_warm_s=build_s, ms_per_step=1e3 * wall / max(1, steps), rocks=sim.n_rocks,
               bed_radius=scene.bed.radius, warm_events=int(sum(len(c) for c in warm)),
               launches=sim.launches_total - launches0, dropped=int(sim.impacts_dropped))
    del sim
    return out


def launch_case(task: dict, arch: str) -> dict:
    """The launch study's reference case (V 20, dry gravel) and its bands (bench/launch.py BAND_TARGETS)."""
    rocks, seeds, _, follow_s = launch_study.SIZES_OF_RUN[task["size"]]
    runs = [launch_study.follow_throws(launch_study.throw_scene(20.0, 0.0, launch_study.SIZES["gravel"], rocks,
                                                                seed), 20.0, arch, follow_s)
            for seed in range(1, seeds + 1)]
    stats = launch_study.launch_stats(launch_study._merge(runs))
    bands = [{"target": what, "value": stats[key], "met": launch_study.band_met(stats, key),
              "shown": f"{stats[key]:.4g}"} for what, key, _, _ in launch_study.BAND_TARGETS]
    return {"id": task["id"], "kind": "launch", "bands": bands, "stats": stats, "large": large_releases(
        rocks, arch, follow_s), "source": f"V 20 dry gravel, {rocks} rocks x {seeds} seed(s), measured in this run"}


def large_releases(rocks: int, arch: str, follow_s: float, speed: float = 20.0) -> dict:
    """Which releases lift stones over 20 mm above a car's bonnet line: the launch study's car through the
    study's coarse gravel; per such stone its release angle and radius (the events do not carry the launch)."""
    d = launch_study.follow_throws(launch_study.throw_scene(speed, 0.0, GRAVEL["coarse"], 2 * rocks, 1), speed,
                                   arch, follow_s)
    big = d["radius"] > BIG_RADIUS
    high = big & (d["apex"] > BONNET_Z)
    order = np.argsort(d["alpha"][high])
    return {"speed": speed, "launched": int(big.sum()), "high": int(high.sum()), "z": BONNET_Z,
            "alpha_deg": [round(float(np.degrees(a)), 1) for a in d["alpha"][high][order]],
            "radius_mm": [round(1e3 * float(r), 1) for r in d["radius"][high][order]],
            "apex_m": [round(float(z), 2) for z in d["apex"][high][order]]}


# --------------------------------------------------------------------------------------------- the runs
def plan_runs(cfg: StudyConfig, arch: str) -> list:
    """The tasks: every (leader, speed, wetness, gravel, flaps), then the launch case."""
    base = {k: getattr(cfg, k) for k in ("gaps", "radius", "density", "warm_m", "min_m", "max_m", "chunk_m",
                                          "enough", "bound_per_km")}
    tasks = []
    for gravel in cfg.gravels:
        for leader in cfg.leaders:
            for v in sorted(cfg.speeds, reverse=True):
                for w in cfg.wetness:
                    for flaps in cfg.flaps:
                        rid = f"{leader} {v:g} {'wet' if w else 'dry'} {gravel} flaps {'on' if flaps else 'off'}"
                        tasks.append(dict(base, id=rid, arch=arch, leader=leader, speed=float(v), wet=float(w),
                                          gravel=gravel, flaps=bool(flaps), gaps=list(cfg.gaps)))
    if cfg.launch:
        tasks.append({"id": "launch bands", "kind": "launch", "arch": arch, "size": cfg.launch})
    return tasks


def run_study(cfg: StudyConfig, arch: str, prog=None) -> dict:
    """Every run of the study (through the sweep runner, or in this process with ``workers = 0``); the runs'
    results (with their events) in plan order, the launch case, the runner's placement."""
    prog = prog or (lambda desc: None)
    tasks = plan_runs(cfg, arch)
    got = {}

    def report(o):
        got[o.task["id"]] = o.result if o.result else {"id": o.task["id"], "error": o.error,
                                                       **{k: o.task.get(k) for k in ("kind", "leader", "speed",
                                                                                     "wet", "gravel", "flaps")}}
        prog(f"impacts: {o.task['id']}")

    t0 = time.perf_counter()
    if cfg.workers == 0:
        for t in tasks:
            try:
                report(Outcome(t, run_point(t), None, 1))
            except Exception as exc:  # a run that fails is reported, the others still run
                report(Outcome(t, None, error_line(exc), 1))
        place = {"workers": 0, "threads": None}
    else:
        p = run_tasks(tasks, "taichi_rocks.bench.impacts:run_point", workers=min(cfg.workers, len(tasks)),
                      retries=1, report=report, timeout=cfg.timeout_s)
        place = {"workers": p.workers, "threads": p.threads}
    results = [got[t["id"]] for t in tasks]
    runs = [r for r in results if r.get("kind") != "launch"]
    launch = next((r for r in results if r.get("kind") == "launch" and not r.get("error")), None)
    return {"runs": runs, "launch": launch, "placement": place, "elapsed_s": time.perf_counter() - t0,
            "launch_error": next((r["error"] for r in results if r.get("kind") == "launch" and r.get("error")), None)}


def impacts_section(cfg: StudyConfig, arch: str, prog=None) -> dict:
    """The study's runs and their analysis (impacts_analysis.summary), for the report and results.json."""
    study = run_study(cfg, arch, prog)
    res = summary(study["runs"], study["launch"])
    res.update(config=dataclasses.asdict(cfg), placement=study["placement"], elapsed_s=study["elapsed_s"],
               runs=[{k: v for k, v in r.items() if k != "events"} for r in study["runs"]],
               launch=study["launch"], _runs=study["runs"])
    if study["launch_error"]:
        res["errors"].append(f"launch bands: {study['launch_error']}")
    res["events_total"] = int(sum(len(r["events"]) for r in study["runs"] if "events" in r))
    return res


def count_runs(cfg: StudyConfig) -> int:
    return len(plan_runs(cfg, "cpu"))


# --------------------------------------------------------------------------------------------- --only impacts
def run_impacts_study(out_dir="renders/bench", quick: bool = False, arch: str = "cpu", progress=None,
                      tiny: bool = False, overwrite: bool = False, config: StudyConfig | None = None) -> dict:
    """`taichi-rocks bench --only impacts`: the study alone; writes impacts.md, impacts.json, the events
    (impacts_events.npz) and the plots (impacts_report.OUTPUTS, atomically) to ``out_dir``, which must not hold
    them already unless ``overwrite`` (FileExistsError before anything runs)."""
    cfg = config or make_study_config("tiny" if tiny else ("quick" if quick else "full"))
    out = Path(out_dir)
    check_out_dir(out, OUTPUTS, overwrite)
    with new_folders(out):
        used = init_taichi(arch)
        prog = Progress(count_runs(cfg), progress)
        res = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": machine(used), "mode": cfg.mode,
               "load_average_start": loadavg()}
        res["impacts"] = impacts_section(cfg, used, prog)
        res["load_average_end"] = loadavg()
        res["errors"] = res["impacts"]["errors"]
        written = write_outputs(res, out)
        prog.close()
    res.update(written)
    return res


if __name__ == "__main__":  # one run by hand: python -m taichi_rocks.bench.impacts MODE [INDEX]
    cfg = make_study_config(sys.argv[1] if len(sys.argv) > 1 else "tiny")
    t = plan_runs(cfg, "cpu")[int(sys.argv[2]) if len(sys.argv) > 2 else 0]
    r = run_point(t)
    print({k: v for k, v in r.items() if k != "events"}, len(r.get("events", ())))
