"""``taichi-rocks aot SCENE --arch x64|vulkan --out DIR``: a scene's step as an ahead-of-time module that a game
engine runs from C++ with no Python (native/, docs/native.md).

The folder holds (written whole or not at all, output/atomic.py ``atomic_folder``):

* ``module/``: Taichi's files of the step's kernels for the backend (engine/aot.py);
* ``buffers/<group>.npy``: the World's groups as ``Simulation(scene)`` built them (the bed's rocks at rest, the
  parameters, the bodies, the mirror of ``changes()`` with every id listed);
* ``drives/<index>.drive``: each vehicle's poses in the recorded drive format (docs/drives.md), one file per
  vehicle: a scripted or recorded vehicle's pose at every step time t_k (the clock's own sums, t_0 = 0,
  t_k = t_(k-1) + dt) up to the scene's duration, so a host replays them without the path code; a live vehicle's
  pose at t = 0 (the game drives it: ``rocks_drive``);
* ``manifest.json``: the Taichi version, the backend, the scene, every group, field and kernel argument, the
  host side's constants and the vehicles (engine/aot.py ``export``; ``vehicles[i].kind`` and ``.drive`` here).

Python's twin of the module (:func:`twin`): the scene with each scripted or recorded vehicle replaced by its drive
file (``{ kind = "recorded", file = ... }``); it runs the very poses the native host runs, and gives its numbers
(tests/native/).
"""

from __future__ import annotations

import json
from pathlib import Path

from ..config.drivefile import drive_text
from ..config.scene import SceneError, scene_with
from ..engine import aot
from ..engine.runtime import current_arch
from ..engine.simulation import Simulation
from ..motion.live import clock_tolerance
from ..motion.vehicles import Fleet
from ..output.atomic import atomic_folder

__all__ = ["step_times", "drive_rows", "make_module", "twin", "MANIFEST"]

MANIFEST = "manifest.json"


def step_times(scene) -> list:
    """The clock at every step of ``scene`` from 0 up to its duration (the first time at or past it, within the
    clock's tolerance), summed as ``Simulation.step`` sums them."""
    dt, end = float(scene.sim.dt), float(scene.duration)
    times = [0.0]
    while times[-1] < end - clock_tolerance(end):
        times.append(times[-1] + dt)
    return times


def drive_rows(scene) -> list:
    """Per vehicle, its drive's rows (t, x, y, heading, speed, yaw_rate, wheel_spin): the poses of a scripted or
    recorded vehicle at :func:`step_times`, the pose at t = 0 of a live one."""
    fleet = Fleet(scene)
    times = step_times(scene)
    out = []
    for i in range(len(scene.vehicles)):
        if i in fleet.live:  # its keyframe at t = 0 (motion/live.py LivePath.starting)
            out.append([tuple(r) for r in fleet.paths[i].rows().tolist()])
            continue
        rows = []
        for t in times:
            p = fleet.paths[i].pose(t)
            rows.append((t, float(p.position[0]), float(p.position[1]), float(p.heading), float(p.speed),
                         float(p.yaw_rate), float(p.wheel_spin)))
        out.append(rows)
    return out


def _replaced(scene, folder: Path, live: list) -> object:
    """``scene`` with every vehicle not in ``live`` driven by its drive file in ``folder``."""
    over = {f"vehicle[{i}].path": {"kind": "recorded", "file": str((folder / "drives" / f"{i}.drive").resolve())}
            for i in range(len(scene.vehicles)) if i not in live}
    return scene_with(scene, over) if over else scene


def twin(scene, folder) -> object:
    """Python's twin of the module in ``folder`` made from ``scene``: its scripted and recorded vehicles replaced
    by the module's drives (module docstring).

    Raises:
        SceneError: the folder holds no module of this scene (its manifest's scene name or vehicles differ).
    """
    folder = Path(folder)
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
    except (OSError, ValueError) as e:
        raise SceneError([f"{folder}: not a module folder ({MANIFEST}: {e})"]) from None
    names = [v["name"] for v in manifest.get("vehicles", [])]
    if manifest.get("scene", {}).get("name") != scene.name or names != [v.name for v in scene.vehicles]:
        raise SceneError([f"{folder}: a module of another scene ({manifest.get('scene', {}).get('name')!r})"])
    live = [i for i, v in enumerate(manifest["vehicles"]) if v["kind"] == "live"]
    return _replaced(scene, folder, live)


def make_module(scene, arch: str, out, overwrite: bool = False, tumble: bool = False) -> dict:
    """Write the module of ``scene`` for ``arch`` into the folder ``out`` (module docstring). Taichi must run on
    the backend of ``arch`` (x64: "cpu"). Returns a summary (path, kernels, bytes, steps recorded).

    Raises:
        SceneError: what a module cannot carry (engine/aot.py ``problem``), one line naming the key; nothing is
            written.
        FileExistsError: ``out`` exists and ``overwrite`` is False.
        ValueError: Taichi runs on another backend than ``arch`` needs.
    """
    problem = aot.problem(scene, arch, tumble)
    if problem:
        raise SceneError([problem])
    want = {"x64": "cpu", "vulkan": "vulkan"}[arch]
    if current_arch() != want:
        raise ValueError(f"--arch {arch}: needs Taichi on {want}, it runs on {current_arch()} here "
                         f"(no {want} device found)")
    rows = drive_rows(scene)
    fleet = Fleet(scene)
    with atomic_folder(out, overwrite) as tmp:
        (tmp / "drives").mkdir()
        for i, r in enumerate(rows):
            kind = "live" if i in fleet.live else "sampled from its path"
            (tmp / "drives" / f"{i}.drive").write_text(drive_text(r, (f"vehicle {scene.vehicles[i].name!r}: {kind}",)))
        sim = Simulation(_replaced(scene, tmp, fleet.live), arch=want, tumble=tumble)
        manifest = aot.export(sim, arch, tmp)
        manifest["scene"] = {"name": scene.name, "source": str(scene.source), "seed": int(scene.seed),
                             "dt": float(scene.sim.dt), "duration": float(scene.duration),
                             "rocks": int(scene.bed.rocks), "steps_recorded": len(rows[0]) - 1 if rows else 0}
        for i, v in enumerate(manifest["vehicles"]):
            v["kind"] = "live" if i in fleet.live else "recorded"
            v["drive"] = f"drives/{i}.drive"
        (tmp / MANIFEST).write_text(aot.dumps(manifest))
        size = sum(p.stat().st_size for p in tmp.rglob("*") if p.is_file())
    return {"path": Path(out), "kernels": len(manifest["kernels"]), "bytes": size, "rocks": int(scene.bed.rocks),
            "steps": manifest["scene"]["steps_recorded"], "arch": arch}
