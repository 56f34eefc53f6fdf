"""One sweep run, in a worker process: plain data in, plain data out.

``run_one(task)``: the task names the run (``id``), its scene (the dict of a validated scene, so that a
worker on another machine needs no file), the metrics and the run's folder. The worker writes
``worker.json`` there first (its process id and host: which process runs what), builds the Simulation (the
process's one Taichi runtime, started by the first run; later runs of the same layout reuse its fields and
kernels), steps the scene's duration, with the runtime guard after every 1/30 s simulated, and returns the
metrics' columns. A HealthError or any other exception propagates: the runner makes it the run's error line.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import socket
import time
from dataclasses import dataclass
from pathlib import Path

from ...bench.measure import timed_call
from ...config.scene import Scene, parse_scene
from ...engine.simulation import Simulation
from ...output.atomic import write_atomically
from .metrics import EVERY_STEP, METRICS

GUARD_EVERY = 1.0 / 30.0  # s simulated between runtime guard checks (a frame at 30 fps, as simulate does)


@dataclass
class Clock:
    """Seconds spent building and stepping (timed by the driver, not counting what metrics read)."""
    build_s: float = 0.0
    first_step_s: float = 0.0
    later_s: float = 0.0
    steps: int = 0


@dataclass
class Run:
    """What a metric sees: the simulation, its scene, the run's folder (absolute and relative to the
    sweep's), the arch and the driver's clock."""
    sim: Simulation
    scene: Scene
    out: Path
    rel: Path
    arch: str
    clock: Clock


def _step(sim, clock: Clock, n: int) -> None:
    if n <= 0:
        return
    if clock.steps == 0:
        clock.first_step_s = timed_call(lambda: sim.step(1))
        clock.steps, n = 1, n - 1
    if n:
        clock.later_s += timed_call(lambda: sim.step(n))
        clock.steps += n


def _drive(sim, scene, clock: Clock, every_step: list) -> None:
    """Step to the scene's duration: one step at a time when a metric follows every step, else in blocks
    of GUARD_EVERY; the runtime guard between blocks and at the end; a last shorter step if dt does not
    divide the duration."""
    total = int(math.floor(scene.duration / sim.dt + 1e-9))
    block = max(1, int(round(GUARD_EVERY / sim.dt)))
    done = 0
    while done < total:
        n = 1 if every_step else min(block, total - done)
        _step(sim, clock, n)
        done += n
        for g in every_step:
            g.send(True)
        if done % block == 0 or done == total:
            sim.check_health()
    if scene.duration - sim.time > 1e-9 * max(1.0, scene.duration):
        t = time.perf_counter()
        sim.advance_to(scene.duration)
        clock.later_s += time.perf_counter() - t
        clock.steps += 1
        for g in every_step:
            g.send(True)
        sim.check_health()


def run_one(task: dict) -> dict:
    """Run one task of a sweep (see the module docstring); returns {"seconds": wall time of the run,
    "metrics": {metric name: its columns}}."""
    started = time.perf_counter()
    out = Path(task["out"])
    if out.exists():  # what an interrupted or killed attempt left
        shutil.rmtree(out)
    out.mkdir(parents=True)
    info = {"pid": os.getpid(), "host": socket.gethostname(), "run": task["id"]}
    write_atomically(out / "worker.json", lambda f: f.write(json.dumps(info).encode()))
    scene = parse_scene(task["scene"], task["source"], task["name"])
    clock = Clock()
    t0 = time.perf_counter()
    sim = Simulation(scene, arch=task.get("arch", "cpu"))
    clock.build_s = time.perf_counter() - t0
    run = Run(sim, scene, out, Path(task["rel"]), sim.arch, clock)
    gens, every = [], []
    for name in task["metrics"]:
        g = METRICS[name](run)
        if next(g) == EVERY_STEP:
            every.append(g)
        gens.append(g)
    _drive(sim, scene, clock, every)
    measured = {}
    for name, g in zip(task["metrics"], gens):
        try:
            g.send(False)
        except StopIteration as stop:
            measured[name] = dict(stop.value or {})
        else:
            raise RuntimeError(f"metric {name} yielded again at the end of the run")
    return {"seconds": time.perf_counter() - started, "metrics": measured}
