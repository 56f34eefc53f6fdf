"""What the native host's tests share: the build of native/ (librocks.so and rocks_run), a module made by the
command line, rocks_run's runs, Python's twin run frame by frame as rocks_run runs the module, and the steering of
a live vehicle both apply (examples/rocks_run.cpp's)."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
NATIVE = ROOT / "native"
SCENE = Path(__file__).resolve().parent / "native.toml"
FRAMES, FPS = 300, 60.0


def _sources() -> list:
    return [p for p in NATIVE.rglob("*") if p.is_file() and "build" not in p.relative_to(NATIVE).parts]


def build(tmp: Path) -> Path:
    """The folder holding librocks.so and rocks_run: native/build when ``make native`` built it after every source
    last changed, else a build of native/ into ``tmp`` (cmake and a C++ compiler; the test is skipped, saying why,
    where either is missing)."""
    made = NATIVE / "build"
    newest = max(p.stat().st_mtime for p in _sources())
    if all((made / n).exists() and (made / n).stat().st_mtime >= newest for n in ("rocks_run", "librocks.so")):
        return made
    missing = [tool for tool in ("cmake", "c++") if shutil.which(tool) is None]
    if missing:
        pytest.skip(f"no {' and no '.join(missing)} on this machine: the native host cannot be built (tools/setup.sh "
                    f"installs cmake and g++)")
    out = tmp / "build"
    for cmd in (["cmake", "-S", str(NATIVE), "-B", str(out), f"-DPYTHON={sys.executable}"],
                ["cmake", "--build", str(out), "-j2"]):
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, f"{' '.join(cmd)}: status {r.returncode}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return out


def aot(scene: Path, arch: str, out: Path, *extra) -> subprocess.CompletedProcess:
    """``taichi-rocks aot`` in a subprocess (Taichi starts on the module's backend there)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "taichi_rocks", "aot", str(scene), "--arch", arch, "--out", str(out),
                           *map(str, extra)], env=env, capture_output=True, text=True, timeout=900)


def run(build_dir: Path, module: Path, dump: Path, frames: int = FRAMES) -> dict:
    """rocks_run over ``module`` for ``frames`` frames at FPS, its final state dumped into ``dump``; returns its last
    line (the JSON of the per-call medians) and what it dumped."""
    dump.mkdir(parents=True, exist_ok=True)
    r = subprocess.run([str(build_dir / "rocks_run"), str(module), "--frames", str(frames), "--fps", str(FPS),
                        "--dump", str(dump)], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, f"rocks_run: status {r.returncode}\n{r.stdout}\n{r.stderr}"
    out = {"summary": json.loads(r.stdout.strip().splitlines()[-1]), "stdout": r.stdout, "stderr": r.stderr}
    for name in ("positions", "phase", "impacts", "orientations"):
        if (dump / f"{name}.npy").exists():
            out[name] = np.load(dump / f"{name}.npy")
    out["counts"] = json.loads((dump / "counts.json").read_text())
    return out


def steer(start, t: float) -> tuple:
    """examples/rocks_run.cpp's steering of a live vehicle at time t from its pose at t = 0 (x, y, heading, speed):
    along the start heading at the start speed (10 m/s if it stood), weaving 4 m either side; (x, y), heading."""
    x0, y0, h0, v = start
    v = v if v != 0.0 else 10.0
    s, side = v * t, 4.0 * math.sin(t)
    c, sn = math.cos(h0), math.sin(h0)
    return (x0 + s * c - side * sn, y0 + s * sn + side * c), h0 + math.atan2(4.0 * math.cos(t), v)


def twin_run(scene, module: Path, frames: int = FRAMES, arch: str = "cpu") -> dict:
    """Python's twin of ``module`` (app/aot.py ``twin``) run as rocks_run runs the module: each frame its live
    vehicles steered (:func:`steer`), ``advance_to(f / FPS)``, ``impacts()``, ``changes()`` into a mirror."""
    from taichi_rocks.app.aot import twin
    from taichi_rocks.engine.simulation import Simulation

    sim = Simulation(twin(scene, module), arch=arch, tumble=True)
    live = [(i, p.name, (p.position[0], p.position[1], p.heading, p.speed))
            for i, p in enumerate(sim.vehicle_poses()) if i in sim.fleet.live]
    n = sim.n_rocks
    mirror, phase = np.zeros((n, 3)), np.zeros(n, np.int8)
    events = []
    for f in range(1, frames + 1):
        t = f / FPS
        for _, name, start in live:
            xy, heading = steer(start, t)
            sim.drive(name, xy, heading)
        sim.advance_to(t)
        events.append(sim.impacts())
        rows = sim.changes()
        mirror[rows.ids] = rows.positions
        phase[rows.ids] = rows.phase
    return {"sim": sim, "state": sim.state(), "mirror": mirror, "phase": phase, "events": np.concatenate(events),
            "live": live}


def event_columns(events) -> np.ndarray:
    """The events as rocks_run's impacts.npy holds them: time, vehicle, part, rock (float64)."""
    return np.column_stack([events["time"], events["vehicle"], events["part"], events["rock"]]).astype(np.float64)
