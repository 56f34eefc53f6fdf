"""Headless recording of a simulation into an .npz, streamed through memory-mapped files so that a long run
of many rocks never holds all frames in memory, and written atomically (temporary name, then rename).

Two layouts (README, "Run files"). ``layout="full"``: every rock of every frame, as the engine gives it. Frame
f is the state at time f / fps. Arrays: time (F,), positions (F, N, 3) float64 world metres, velocities
(F, N, 3) float32, phase (F, N) int8 (0 resting, 1 flying, 2 sliding), radii (N,), bed_center (F, 3),
vehicle_positions (F, V, 3), vehicle_headings (F, V), vehicle_names (V,), launches (F,) = rocks launched
since the previous frame, plus fps, dt, seed and scene name. ``layout="light"`` (the default of ``simulate``):
rows of the rocks that changed, positions relative to the floating origin (output/runs.py, which also holds
:func:`~taichi_rocks.output.runs.load_run`, the one loader of both).

The same scene, seed and arch give the same bytes: the zip members are stored (not compressed) in a fixed
order with a fixed time stamp and fixed permissions (see :func:`write_npz`).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np


def _temp_prefix(final: Path) -> str:
    """Temporaries of ``final`` are hidden, next to it, and carry the writer's process id:
    ``.NAME.PID.XXXXXXXX.part`` (files) and ``.NAME.PID.XXXXXXXX`` (work folders)."""
    return f".{final.name}.{os.getpid()}."


def _temp_name(final: Path, suffix: str = "") -> Path:
    """A new temporary name next to ``final`` (same folder, so the rename is atomic). Nothing is created: the
    writer knows the name before the file or folder exists, so a Ctrl-C at any moment can remove it."""
    final = Path(final)
    return final.parent / f"{_temp_prefix(final)}{secrets.token_hex(4)}{suffix}"


@contextlib.contextmanager
def atomic_path(final: Path, suffix: str = ".part"):
    """For writers that open files by name (a library's own writer): yields a new temporary name beside
    ``final`` (same folder; nothing is created), ending in ``suffix`` (a library may pick the format by
    extension). When the body returns, the temporary is renamed over ``final``; on any failure (or Ctrl-C) it
    is removed. Temporaries left by a killed writer are removed by :func:`remove_stale_temporaries`."""
    final = Path(final)
    tmp = _temp_name(final, suffix)
    try:
        yield tmp
        os.replace(tmp, final)
    finally:
        tmp.unlink(missing_ok=True)


def write_atomically(final: Path, write) -> None:
    """Write ``final`` complete or not at all: ``write(f)`` fills a temporary file beside it (binary, the
    usual permissions), which is then renamed over ``final``; on any failure the temporary is removed."""
    with atomic_path(final) as tmp:
        with open(tmp, "xb") as f:
            write(f)


@contextlib.contextmanager
def new_folders(*folders):
    """Create ``folders`` and their missing parents for a writer; if the body raises (an error, Ctrl-C),
    remove again, deepest first, those of them it created that are empty by then, so that a command that
    fails or is interrupted leaves no folder of its own behind. Folders that existed before, and folders
    holding finished output (a render's kept frames), stay. Yields the folders created, parents first."""
    created: list = []
    try:
        for folder in folders:
            missing = []
            path = Path(folder)
            while not path.is_dir():
                missing.append(path)
                path = path.parent
            for path in reversed(missing):
                created.append(path)  # before mkdir: a Ctrl-C right after it must still find it here
                try:
                    path.mkdir()
                except FileExistsError:
                    created.pop()  # made meanwhile by someone else: not ours to remove
                    if not path.is_dir():
                        raise
        yield list(created)
    except BaseException:
        for path in sorted(set(created), key=lambda q: len(q.parts), reverse=True):
            try:
                path.rmdir()  # only when empty
            except OSError:
                pass
        raise


# Zip members written by write_npz: no time stamp (the zip epoch), a regular file rw-r--r-- made on Unix.
ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
_COPY_CHUNK = 1 << 20


def _zip_member(name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=ZIP_EPOCH)
    info.compress_type = zipfile.ZIP_STORED
    info.create_system = 3
    info.external_attr = 0o100644 << 16
    return info


@dataclass(frozen=True)
class Raw:
    """An array kept as bare bytes in a file (C order, no header), e.g. rows appended frame by frame; its
    dtype and shape are known only at the end. write_npz streams it behind an .npy header."""

    path: Path
    dtype: np.dtype
    shape: tuple


def write_npz(f, members: dict) -> None:
    """Write an .npz (what ``np.load`` reads) into the binary file ``f``, the same bytes for the same arrays:
    members ``NAME.npy`` in the order of ``members``, stored, with fixed time stamps and permissions. A
    value is an array, the Path of an .npy file or a :class:`Raw` file; files are streamed (memory stays
    flat)."""
    with zipfile.ZipFile(f, "w", zipfile.ZIP_STORED, allowZip64=True) as z:
        for name, value in members.items():
            with z.open(_zip_member(f"{name}.npy"), "w", force_zip64=True) as dst:
                if isinstance(value, Raw):
                    header = {"descr": np.lib.format.dtype_to_descr(np.dtype(value.dtype)),
                              "fortran_order": False, "shape": tuple(int(n) for n in value.shape)}
                    np.lib.format.write_array_header_1_0(dst, header)
                if isinstance(value, (Path, Raw)):
                    with open(value if isinstance(value, Path) else value.path, "rb") as src:
                        shutil.copyfileobj(src, dst, _COPY_CHUNK)
                else:
                    np.lib.format.write_array(dst, np.asanyarray(value), allow_pickle=False)


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



def frame_states(sim, frames: int, fps: float, guard: bool = True, progress=None):
    """Yield (f, state) for frames f = 0 .. frames - 1: ``sim`` advanced to exactly f / fps, checked by the runtime
    guard with ``guard`` (a HealthError propagates), its ``state()``; ``progress`` ticks once a frame is done."""
    for f in range(frames):
        sim.advance_to(f / fps)
        if guard:
            sim.check_health()
        yield f, sim.state()
        if progress is not None:
            progress.update(1)

def record(sim, out: Path, frames: int, fps: float, progress=None, guard: bool = True, layout: str = "light",
           only: str = "flying", crop=None) -> dict:
    """Run ``sim`` for ``frames`` frames and write ``out`` (its missing folders are created, and removed
    again if the run fails or is interrupted). Returns a small summary.

    ``layout``: "full" (every rock of every frame, float64 world positions) or "light" (output/runs.py; with
    ``only`` "flying" or "all" and ``crop`` a radius in metres or None). With ``guard``, the state is checked
    after every frame (see Simulation.check_health); on failure the HealthError propagates and nothing is
    written under ``out``.
    """
    out = Path(out)
    if layout not in ("full", "light"):
        raise ValueError(f"layout must be full or light, got {layout!r}")
    with new_folders(out.parent):
        remove_stale_temporaries(out)
        work = _temp_name(out)
        try:
            work.mkdir(mode=0o700)
            if layout == "full":
                names = _record_frames(sim, work, frames, fps, progress, guard)
                members = {k: work / f"{k}.npy" for k in names}
            else:
                from .runs import record_light

                members = record_light(sim, work, frames, fps, progress, guard, only=only, crop=crop)
            write_atomically(out, lambda f: write_npz(f, members))
        finally:
            shutil.rmtree(work, ignore_errors=True)
    return {"frames": frames, "rocks": sim.n_rocks, "path": str(out), "bytes": out.stat().st_size,
            "layout": layout}


def _record_frames(sim, work: Path, frames: int, fps: float, progress, guard: bool) -> list:
    """Simulate into memory-mapped ``work/NAME.npy`` files; returns the names, in the order of the .npz."""
    n, v = sim.n_rocks, len(sim.fleet.names)
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
    st = None
    for f, st in frame_states(sim, frames, fps, guard, progress):
        for k in ("time", "positions", "velocities", "phase", "bed_center", "vehicle_positions",
                  "vehicle_headings"):
            arrays[k][f] = st[k]
        arrays["launches"][f] = st["launches_total"] - previous
        previous = st["launches_total"]
    for a in arrays.values():
        a.flush()
    del arrays
    small = {"radii": (st if st is not None else sim.state())["radii"], "vehicle_names": np.array(sim.fleet.names),
             "fps": np.float64(fps), "dt": np.float64(sim.dt), "seed": np.int64(sim.scene.seed),
             "scene": np.array(sim.scene.name)}
    for k, val in small.items():
        np.save(work / f"{k}.npy", val)
    return list(shapes) + list(small)
