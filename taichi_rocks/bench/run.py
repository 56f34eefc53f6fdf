"""``run_bench``: the whole benchmark in order, and its outputs (:data:`OUTPUTS`: report.md, results.json,
seven PNG plots, and with the impacts study its plots and events, :func:`outputs`; written atomically, an out
folder holding them is refused unless ``overwrite``).

Order: the lanes scenes (detection, in lockstep), then direct flights on their fields (integrator x dt,
precision); the speed grid; the hash settings (on the grid's default simulation, before anything changes its
state); effects and preset costs (the main scene rebuilt from changed scenes); launch overheads; last the flight
cost with every rock flying (it leaves the main scene's rocks all flying); the cost against activity (its
points in processes of their own); the impacts study (impacts.py, its runs on two processes of their own); then
presets and targets.
"""

from __future__ import annotations

import dataclasses
import sys
import time
import traceback
from pathlib import Path
from typing import Optional

from ..engine.runtime import init_taichi
from ..output.atomic import new_folders
from .config import DRAGS, INTEGRATORS, Config, make_config
from .detection import REFERENCE, lanes
from .flight import flight_cost, integrator_sweep
from .hashing import hash_settings_study
from .machine import Progress, loadavg, machine, pin_sources
from .measure import Built
from .peers import Floor, start_warp
from .activity import activity_section, count_jobs
from .impacts import count_runs, impacts_section, make_study_config
from .impacts_report import FILES as IMPACTS_FILES, section_lines, write_section_files
from .plots import (PNG, plot_activity, plot_detection, plot_hash, plot_integrators, plot_passes, plot_peers,
                    plot_precision)
from .precision import precision_runs
from .presets import choose_presets, preset_costs, validate_presets
from .report import check_out_dir, write_report, write_results
from .scenes import fleet_scene
from .speed import effects_costs, grid_entry, launch_overheads
from .targets import evaluate_targets

PLOTS = (plot_integrators, plot_detection, plot_precision, plot_hash, plot_peers, plot_passes, plot_activity)
OUTPUTS = ("report.md", "results.json") + tuple(PNG.values())


def count_tasks(cfg: Config) -> int:
    """Progress-bar steps of a run of this configuration."""
    n_grid = len(cfg.grid_n) * len(cfg.grid_t)
    acc = (2 if cfg.acc_f64 else 1) * len(DRAGS) * len(INTEGRATORS)  # the accuracy study: drag x integrator
    return (4 + acc + 2 + len(cfg.integ_cost) + n_grid * 5 + len(cfg.hash_settings) - 1 + 6 + 6
            + (3 if cfg.validate_presets else 0) + 3 + count_jobs(cfg)
            + (count_runs(make_study_config(cfg.impacts)) if cfg.impacts else 0))


def outputs(cfg: Config) -> tuple:
    """What a run of this configuration writes: OUTPUTS, and the impacts section's plots and events."""
    return OUTPUTS + (IMPACTS_FILES if cfg.impacts else ())


def _accuracy(res: dict, cfg: Config, arch: str, prog) -> dict:
    """1b, 1a, 1c on the lanes scenes; returns the lanes scene's step costs per detection mode."""
    det, builds, build_s = lanes(cfg, arch, prog)
    res["build_s"].update(build_s)
    acc_sims = {"f32": builds["f32"].sim}
    if cfg.acc_f64:
        acc_sims["f64"] = builds["f64"].sim
    res["accuracy"] = {"detection": {"modes": det, "reference": REFERENCE}}
    res["accuracy"]["integrator_dt"] = integrator_sweep(acc_sims, cfg, prog)
    res["accuracy"]["precision"] = precision_runs({k: b.sim for k, b in builds.items()}, cfg, prog)
    return det


def _speed_grid(res: dict, cfg: Config, arch: str, warp, prog) -> tuple:
    """The speed grid; returns (entries by (N, T), the main scene's Built)."""
    floor = Floor(max(cfg.grid_n))
    grid, by_nt, main = [], {}, None
    for n in cfg.grid_n:
        for t in cfg.grid_t:
            b = Built(fleet_scene(n, t, cfg.bed_radius), arch, f"grid N={n} T={t}")
            e = grid_entry(b, cfg, floor, warp, prog, record_hits=(n == cfg.hash_n or (n, t) == cfg.main))
            res["build_s"][b.label] = e["build_s"]
            grid.append(e)
            by_nt[(n, t)] = e
            if (n, t) == cfg.main:
                main = b
    res["speed"] = {"grid": grid}
    return by_nt, main


def _main_scene_studies(res: dict, cfg: Config, arch: str, main: Built, det: dict, prog) -> None:
    """Effects, preset costs, launch overheads, then the flight cost with every rock flying (last: it leaves
    the main scene's rocks all flying)."""
    bed_only = Built(fleet_scene(*cfg.main, cfg.bed_radius, {"effects.splash": False}), arch, "bed only")
    res["speed"]["effects"] = effects_costs(main, bed_only, cfg, prog)
    res["build_s"]["bed only"] = bed_only.ctor_s + (bed_only.first_step_s or 0.0)
    res["accuracy"]["preset_costs"] = preset_costs(main, cfg, det, prog)
    res["speed"]["overheads"] = launch_overheads(main.sim)
    res["accuracy"]["flight_cost"] = flight_cost(main.sim, cfg.integ_cost, max(3, cfg.reps // 2), prog,
                                                 effects=cfg.effects_all_flying)


def _impacts(res: dict, cfg: Config, arch: str, out: Path, prog) -> None:
    """5. The impacts study (impacts.py), its plots and events beside the report, its section and targets."""
    try:
        imp = res["impacts"] = impacts_section(make_study_config(cfg.impacts), arch, prog)
        plots, errors = write_section_files(imp, out)
        imp["errors"] += errors
        res["errors"] += imp["errors"]
        res["_impacts_md"] = section_lines(imp, plots)
        res["_impacts_targets"] = [{"target": t["target"], "value": t["value"], "limit": None, "met": t["met"],
                                    "detail": t["shown"] + (f"; {t['reason']}" if t["reason"] else ""),
                                    "at": "impacts study"} for t in imp["targets"]]
    except Exception as exc:
        res["errors"].append(f"impacts study: {type(exc).__name__}: {exc}")
        traceback.print_exc()


def _plots(res: dict, out: Path, prog) -> list:
    plots = []
    for fn in PLOTS:
        if fn is plot_activity and "activity" not in res:
            continue
        try:
            plots.append(fn(res, out))
        except Exception as exc:
            res["errors"].append(f"plot {fn.__name__}: {type(exc).__name__}: {exc}")
            plots.append("")
            traceback.print_exc()
        prog("plots")
    return plots


def run_bench(out_dir="renders/bench", quick: bool = False, arch: str = "cpu", progress=True, tiny: bool = False,
              config: "Optional[Config]" = None, overwrite: bool = False, backend: str = "local",
              address=None) -> dict:
    """Run the benchmark and write report.md, results.json and PNG plots to ``out_dir``.

    ``quick``: the CI smoke run (< 2 min on 2 cores); ``tiny``: the smallest sizes (tests); ``config``
    overrides both. ``progress``: True shows a tqdm bar on stderr, None only on a terminal, False never.
    An ``out_dir`` already holding one of :data:`OUTPUTS` is refused before anything runs (FileExistsError)
    unless ``overwrite`` (the files are then replaced as they are written). The missing folders of ``out_dir``
    are created, and removed again if the run fails before writing into them.
    ``backend``, ``address``: where the cost-against-activity section runs its processes (activity.py run_jobs).
    """
    out = Path(out_dir)
    cfg = config or make_config(quick=quick, tiny=tiny)
    check_out_dir(out, outputs(cfg), overwrite)
    with new_folders(out):
        return _run_bench(out, cfg, arch, progress, backend, address)


def _run_bench(out: Path, cfg: "Config", arch: str, progress, backend: str = "local", address=None) -> dict:
    t_start = time.perf_counter()
    used = init_taichi(arch)
    pin_sources()
    prog = Progress(count_tasks(cfg), progress)
    res: dict = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": machine(used),
                 "load_average_start": loadavg(), "config": dataclasses.asdict(cfg), "errors": [], "build_s": {}}
    warp, res["warp"] = start_warp(cfg.use_warp)
    res["machine"]["warp"] = res["warp"].get("version")
    prog("warp")

    det = _accuracy(res, cfg, used, prog)
    grid_by_nt, main = _speed_grid(res, cfg, used, warp, prog)
    res["accuracy"]["hash_settings"] = hash_settings_study(cfg, used, grid_by_nt, prog)
    _main_scene_studies(res, cfg, used, main, det, prog)
    for e in res["speed"]["grid"]:
        for k in ("launched_after_k", "_built"):
            e.pop(k, None)

    if cfg.activity:
        res["activity"] = activity_section(cfg, used, prog, backend, address)
        res["errors"] += res["activity"]["errors"]

    if cfg.impacts:
        _impacts(res, cfg, used, out, prog)

    res["accuracy"]["presets"] = choose_presets(res)
    if cfg.validate_presets:
        try:
            validate_presets(res["accuracy"]["presets"], cfg, used, prog)
        except Exception as exc:
            res["errors"].append(f"preset validation: {type(exc).__name__}: {exc}")
    res["targets"] = evaluate_targets(res, cfg) + res.pop("_impacts_targets", [])

    res["elapsed_s"] = time.perf_counter() - t_start
    res["load_average_end"] = loadavg()
    plots = _plots(res, out, prog)
    res["plots"] = [p for p in plots if p]
    res["elapsed_s"] = time.perf_counter() - t_start
    res["report"] = str(write_report(res, out, plots))
    write_results(res, out)
    prog.close()
    if res["accuracy"]["hash_settings"]["verdict"] != "PASS":
        print("taichi-rocks bench: FAIL: hash settings launched different rocks or failed to build (see report)",
              file=sys.stderr)
    return res
