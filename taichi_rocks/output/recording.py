"""Headless recording of a simulation into an .npz, streamed through memory-mapped files so that a long run
of many rocks never holds all frames in memory, and written atomically (temporary name, then rename).

Frame f is the state at time f / fps. Arrays: time (F,), positions (F, N, 3) float64 world metres,
velocities (F, N, 3) float32, phase (F, N) int8 (0 resting, 1 flying, 2 sliding), radii (N,),
bed_center (F, 3), vehicle_positions (F, V, 3), vehicle_headings (F, V), vehicle_names (V,),
launches (F,) = rocks launched since the previous frame, plus fps, dt, seed and scene name.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import zipfile
from pathlib import Path

import numpy as np


def _temp_prefix(final: Path) -> str:
    """Temporaries of ``final`` are hidden, next to it, and carry the writer's process id:
    ``.NAME.PID.XXXXXXXX.part`` (files) and ``.NAME.PID.XXXXXXXX`` (work folders)."""
    return f".{final.name}.{os.getpid()}."


def atomic_path(final: Path) -> Path:
    """A temporary file name next to ``final`` (same folder, so the rename is atomic)."""
    final = Path(final)
    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(final), suffix=".part", dir=final.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; the final file gets the usual permissions
    return Path(tmp)


def write_atomically(final: Path, write) -> None:
    """Write ``final`` complete or not at all: ``write(f)`` fills a temporary file beside it (binary), which
    is then renamed over ``final``; on any failure the temporary is removed."""
    final = Path(final)
    tmp = atomic_path(final)
    try:
        with open(tmp, "wb") as f:
            write(f)
        os.replace(tmp, final)
    finally:
        tmp.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def remove_stale_temporaries(final: Path) -> list[Path]:
    """Remove the temporaries that writers of ``final`` left behind when they were killed (kill -9, power
    loss): those whose process no longer exists. Temporaries of a running writer are left alone. Returns
    what was removed."""
    final = Path(final)
    removed = []
    if not final.parent.is_dir():
        return removed
    for path in final.parent.glob(f".{final.name}.*"):
        rest = path.name[len(final.name) + 2:]
        pid = rest.split(".", 1)[0]
        if not pid.isdigit() or _alive(int(pid)):
            continue
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


def record(sim, out: Path, frames: int, fps: float, progress=None, guard: bool = True) -> dict:
    """Run ``sim`` for ``frames`` frames and write ``out``. Returns a small summary.

    With ``guard``, the state is checked after every frame (see Simulation.check_health); on failure the
    HealthError propagates and nothing is written under ``out``.
    """
    out = Path(out)
    n, v = sim.n_rocks, len(sim.fleet.names)
    remove_stale_temporaries(out)
    work = Path(tempfile.mkdtemp(prefix=_temp_prefix(out), dir=out.parent))
    try:
        shapes = {
            "time": ((frames,), np.float64),
            "positions": ((frames, n, 3), np.float64),
            "velocities": ((frames, n, 3), sim.world.np_real()),
            "phase": ((frames, n), np.int8),
            "bed_center": ((frames, 3), np.float64),
            "vehicle_positions": ((frames, v, 3), np.float64),
            "vehicle_headings": ((frames, v), np.float64),
            "launches": ((frames,), np.int64),
        }
        arrays = {k: np.lib.format.open_memmap(work / f"{k}.npy", mode="w+", dtype=dt, shape=shape)
                  for k, (shape, dt) in shapes.items()}
        previous = sim.launches_total
        for f in range(frames):
            sim.advance_to(f / fps)
            if guard:
                sim.check_health()
            st = sim.state()
            arrays["time"][f] = st["time"]
            arrays["positions"][f] = st["positions"]
            arrays["velocities"][f] = st["velocities"]
            arrays["phase"][f] = st["phase"]
            arrays["bed_center"][f] = st["bed_center"]
            arrays["vehicle_positions"][f] = st["vehicle_positions"]
            arrays["vehicle_headings"][f] = st["vehicle_headings"]
            arrays["launches"][f] = st["launches_total"] - previous
            previous = st["launches_total"]
            if progress is not None:
                progress.update(1)
        for a in arrays.values():
            a.flush()
        del arrays
        small = {"radii": st["radii"] if frames else sim.state()["radii"],
                 "vehicle_names": np.array(sim.fleet.names), "fps": np.float64(fps), "dt": np.float64(sim.dt),
                 "seed": np.int64(sim.scene.seed), "scene": np.array(sim.scene.name)}
        for k, val in small.items():
            np.save(work / f"{k}.npy", val)
        def write_zip(f):
            with zipfile.ZipFile(f, "w", zipfile.ZIP_STORED, allowZip64=True) as z:
                for k in list(shapes) + list(small):
                    z.write(work / f"{k}.npy", arcname=f"{k}.npy")

        write_atomically(out, write_zip)
        return {"frames": frames, "rocks": n, "path": str(out), "bytes": out.stat().st_size}
    finally:
        shutil.rmtree(work, ignore_errors=True)
