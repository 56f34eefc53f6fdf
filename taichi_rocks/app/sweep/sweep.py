"""``taichi-rocks sweep`` / ``run_sweep``: every run of a sweep file, on local processes or a Ray cluster, and
its results (docs/sweeps.md).

    DIR/sweep.json          the sweep file (text and values), its fingerprint, the versions, the machine,
                            where it ran (backend, workers x threads)
    DIR/runs/<id>/          each run's folder: worker.json (which process ran it), result.json (its row), and
                            what its metrics wrote (render: render/<scene>.mp4)
    DIR/results.csv         one row per finished run, in run order: id, the grid values, seed, status (ok /
                            failed), error (one line), attempts, seconds, then a column per metric value
    DIR/plots/              per metric, its columns against each swept key (and the launch bands per run)

A run's row is its result.json, written atomically when the run ends; results.csv is rewritten from the rows
(atomically) after each. ``resume`` runs only the runs without a row (a sweep file or base scene changed since
is refused); existing results are replaced only with ``overwrite``. Nothing is written for a sweep file that
does not validate.
"""

from __future__ import annotations

import csv
import io
import json
import math
import shutil
import sys
import time
from pathlib import Path

from tqdm import tqdm

from ... import __version__
from ...bench.machine import machine
from ...config.scene import scene_to_dict
from ...config.limits import MAX_SWEEP_RUNS, STEP_PACE_S, duration_text
from ...config.sweep import SweepError, load_sweep, sweep_fingerprint, sweep_runs, sweep_size
from ...output.atomic import check_place, new_folders, write_atomically
from .metrics import METRICS
from .plots import plot_sweep
from ...runner.tasks import Outcome, plan_placement, run_tasks

WORKER = "taichi_rocks.app.sweep.worker:run_one"
FIXED = ("id", "seed", "status", "error", "attempts", "seconds")
OURS = ("sweep.json", "results.csv", "runs", "plots")


class SweepOutputError(FileExistsError):
    """The output folder holds results that may not be replaced or continued (one line)."""


def _dump(obj) -> bytes:
    return json.dumps(obj, indent=1, default=lambda x: x.item() if hasattr(x, "item") else str(x)).encode()


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else "nan"
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v)
    return str(v)


def results_csv(rows: list, keys: list, metrics: list) -> str:
    """The table as CSV text: FIXED columns with the grid keys after the id, then every metric column in
    metric order (a column appears once a row has it)."""
    cols = ["id", *keys, *FIXED[1:]]
    for name in metrics:
        for row in rows:
            for k in row["metrics"].get(name, {}):
                if k not in cols:
                    cols.append(k)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for flat in table(rows):
        w.writerow([_cell(flat.get(c)) for c in cols])
    return buf.getvalue()


def table(rows: list) -> list[dict]:
    """The rows as flat dicts (the Python API's table): id, grid values, seed, status, error, attempts,
    seconds, metric columns."""
    out = []
    for r in rows:
        flat = {"id": r["id"], **r["values"], **{k: r.get(k) for k in FIXED[1:]}}
        for cols in r["metrics"].values():
            flat.update(cols)
        out.append(flat)
    return out


def _check_out(out: Path, fingerprint: str, resume: bool, overwrite: bool, remove: bool = True) -> None:
    """Refuse to touch results that are not ours to replace; with overwrite (and ``remove``), remove the old
    ones."""
    if out.exists() and not out.is_dir():
        raise SweepOutputError(f"{out}: exists and is not a folder")
    try:
        check_place(out, folder=True)
    except ValueError as e:
        raise SweepOutputError(str(e)) from None
    if not out.exists():
        return
    found = [n for n in OURS if (out / n).exists()]
    if overwrite:
        if not remove:
            return
        for n in found:
            p = out / n
            shutil.rmtree(p) if p.is_dir() else p.unlink()
        return
    if not found:
        return
    if not resume:
        raise SweepOutputError(f"{out}: holds a sweep's results; pass --resume to continue it or --overwrite to "
                               f"start again")
    try:
        old = json.loads((out / "sweep.json").read_text())["fingerprint"]
    except (OSError, ValueError, KeyError):
        old = None
    if old != fingerprint:
        raise SweepOutputError(f"{out}: holds the results of another sweep (the sweep file or its base scene "
                               f"changed); pass --overwrite to start again")


def _check_placement(backend: str, tasks: int, workers, threads, address) -> None:
    """The refusals of runner/tasks.py ``run_tasks`` about where the runs go, made before anything is written
    (ValueError, one line)."""
    if backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ValueError("the ray backend needs the ray package: pip install 'taichi-rocks[ray]'") from None
        return
    if address:
        raise ValueError("--address is for the ray backend")
    place = plan_placement("local", tasks, workers, threads)
    if place.workers * place.threads > place.cores:
        raise ValueError(f"{place.workers} workers x {place.threads} threads is more than the {place.cores} "
                         f"cores here")


def _done_rows(out: Path, ids: set) -> dict:
    rows = {}
    for rid in ids:
        p = out / "runs" / rid / "result.json"
        if p.is_file():
            try:
                rows[rid] = json.loads(p.read_text())
            except ValueError:  # not ours: written atomically, so never half a row
                continue
    return rows


def _versions() -> dict:
    v = {"taichi_rocks": __version__}
    try:
        import ray

        v["ray"] = ray.__version__
    except ImportError:
        v["ray"] = None
    return v


def _tasks(runs, out: Path, metrics, arch: str) -> list:
    return [{"id": r.id, "scene": scene_to_dict(r.scene), "source": r.scene.source, "name": r.scene.name,
             "metrics": list(metrics), "out": str((out / "runs" / r.id).resolve()),
             "rel": str(Path("runs") / r.id), "arch": arch} for r in runs]


def _bar(total: int, initial: int, progress):
    return tqdm(total=total, initial=initial, unit="run", desc="sweep", file=sys.stderr, dynamic_ncols=True,
                disable=None if progress is None else not progress)


def sweep_estimate(sweep, base, n: int) -> str:
    """One line: the runs, their steps and the least time their stepping takes (config/limits.py's pace)."""
    duration = sweep.duration if sweep.duration is not None else base.duration
    dts = [v for v in sweep.grid.get("sim.dt", ()) if isinstance(v, (int, float)) and v > 0] or [base.sim.dt]
    steps = duration / min(dts)
    return (f"{n} runs of up to {steps:.3g} steps: at least {duration_text(n * steps * STEP_PACE_S)} of stepping "
            f"at {STEP_PACE_S * 1e3:g} ms a step, shared by the workers")


def _checked_runs(path: Path, out: Path, backend, workers, threads, address, resume, overwrite, yes, announce):
    """Every check of run_sweep before anything is written or removed (the file, the run count, the results
    folder, the placement), then the runs: (sweep, base scene, runs, fingerprint, rows kept by ``resume``)."""
    sweep, base = load_sweep(path, METRICS)
    n = sweep_size(sweep)
    if n > MAX_SWEEP_RUNS and not yes:
        raise SweepError([f"{path}: grid: {sweep_estimate(sweep, base, n)}; more than {MAX_SWEEP_RUNS} runs: pass "
                          f"--yes to run them"])
    fingerprint = sweep_fingerprint(sweep, base)
    ids = {f"r{i:04d}" for i in range(n)}  # sweep_runs's ids, known before the runs are built
    _check_out(out, fingerprint, resume, overwrite, remove=False)  # nothing removed or written before every check
    kept = _done_rows(out, ids) if resume and out.is_dir() else {}
    _check_placement(backend, n - len(kept), workers, threads, address)
    runs = sweep_runs(sweep, base, str(path),
                      checked=None if announce is None else lambda: announce(f"sweep: {sweep_estimate(sweep, base, n)}"))
    _check_out(out, fingerprint, resume, overwrite)
    return sweep, base, runs, fingerprint, kept


def run_sweep(path, out, backend: str = "local", workers=None, threads=None, address=None, resume: bool = False,
              overwrite: bool = False, arch: str = "cpu", progress=None, retries: int = 2, yes: bool = False,
              announce=None) -> list[dict]:
    """Run the sweep file ``path`` into the folder ``out`` (module docstring; docs/sweeps.md).

    Args:
        path: the sweep file (TOML).
        out: the results folder (results.csv, sweep.json, runs/, plots/).
        backend: "local" (worker processes of this machine) or "ray" (actors on a Ray cluster).
        workers: worker processes or actors (default: one per core, at most one per run).
        threads: Taichi threads per worker (default: cores / workers).
        address: the Ray cluster to join (host:port); with the ray backend and no address, a local cluster is
            started for the run.
        resume: run only the runs without a row in ``out`` (the sweep file and base scene must be unchanged).
        overwrite: replace the results in ``out``.
        arch: the Taichi backend of the runs.
        progress: a tqdm bar on stderr (None: only on a terminal).
        retries: times a run whose worker was killed is tried again on another worker.
        yes: run a sweep of more than MAX_SWEEP_RUNS runs (else refused).
        announce: ``announce(line)`` is told the run count and estimate (:func:`sweep_estimate`) once the values
            are checked, before the runs are built.

    Returns:
        The table, one dict per run in run order (the columns of results.csv; "status" "ok" or "failed").

    Raises:
        SweepError: a bad sweep file (a SceneError), or more than MAX_SWEEP_RUNS runs without ``yes``, before
            anything is written.
        SweepOutputError: results in ``out`` that may not be touched, before anything is written.
    """
    path, out = Path(path), Path(out)
    sweep, base, runs, fingerprint, kept = _checked_runs(path, out, backend, workers, threads, address, resume,
                                                         overwrite, yes, announce)
    by_id = {r.id: r for r in runs}
    keys, metrics = list(sweep.grid), list(sweep.measure.metrics)
    with new_folders(out / "runs"):
        rows = kept
        meta = {"sweep_file": str(path), "sweep_text": path.read_text(), "sweep": sweep.model_dump(mode="json"),
                "base_scene": scene_to_dict(base), "fingerprint": fingerprint, "runs": len(runs),
                "versions": _versions(), "machine": machine(arch), "backend": backend, "address": address,
                "started": time.strftime("%Y-%m-%d %H:%M:%S")}
        write_atomically(out / "sweep.json", lambda f: f.write(_dump(meta)))
        todo = [r for r in runs if r.id not in rows]
        bar = _bar(len(runs), len(runs) - len(todo), progress)

        def report(o: Outcome) -> None:
            r = by_id[o.task["id"]]
            res = o.result or {}
            row = {"id": r.id, "values": r.values, "seed": r.seed, "status": "ok" if o.error is None else "failed",
                   "error": o.error, "attempts": o.attempts, "seconds": res.get("seconds"), "worker": o.worker,
                   "metrics": res.get("metrics", {})}
            write_atomically(out / "runs" / r.id / "result.json", lambda f: f.write(_dump(row)))
            rows[r.id] = row
            done = [rows[i] for i in by_id if i in rows]
            text = results_csv(done, keys, metrics)
            write_atomically(out / "results.csv", lambda f: f.write(text.encode()))
            if o.error is not None:
                bar.write(f"sweep: run {r.id} ({_label(r)}) failed: {o.error}", file=sys.stderr)
            bar.update(1)

        try:
            place = run_tasks(_tasks(todo, out, metrics, arch), WORKER, backend=backend, workers=workers,
                              threads=threads, address=address, retries=retries, report=report)
        finally:
            bar.close()
        ordered = [rows[i] for i in by_id if i in rows]
        if not todo:
            text = results_csv(ordered, keys, metrics)
            write_atomically(out / "results.csv", lambda f: f.write(text.encode()))
        meta.update(finished=time.strftime("%Y-%m-%d %H:%M:%S"), workers=place.workers, threads=place.threads,
                    cores=place.cores, failed=sum(r["status"] != "ok" for r in ordered))
        meta["machine"]["taichi_threads"] = place.threads  # each worker's, not this process's
        write_atomically(out / "sweep.json", lambda f: f.write(_dump(meta)))
        plot_sweep(ordered, keys, metrics, out / "plots")
    return table(ordered)


def _label(run) -> str:
    return ", ".join(f"{k} = {v}" for k, v in run.values.items()) + f", seed {run.seed}"
