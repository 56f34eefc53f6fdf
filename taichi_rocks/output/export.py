"""``taichi-rocks export``: a run written for the tools artists use, frame by frame while simulating.

* ``fmt="usd"``: one .usdc stage (output/usd.py): the rocks as a PointInstancer, vehicles, ground and the
  follow camera, every frame a time sample, saved as it is simulated (memory stays flat).
* ``fmt="ply"``: a folder of binary PLY point files, one per frame (output/ply.py).

What goes in: ``only="all"`` every rock; ``only="flying"`` the rocks in the air or sliding plus those that
moved since the previous frame (landed, recycled); the resting rest of the bed is left out. ``crop=R`` keeps
the rocks within R metres (horizontally) of the camera's followed vehicle. Ids, tumble and wheel spin:
output/instances.py. The camera: motion/camera.py's camera_of, the renderer's own rig ([camera] view, offset,
look_ahead, fov, smoothing) computed here from the scene, since output/ does not import render/.

Files are written under a temporary name beside the final one and renamed when complete (a .usdc file; for
PLY the whole folder); an existing output is replaced only with ``overwrite`` (checked by
:func:`check_target` before anything is simulated).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np

from .instances import RockTracker, VehicleTracker
from .recording import _temp_name, atomic_path, frame_states, new_folders, remove_stale_temporaries
from .runs import check_selection, crop_mask
from ..motion.camera import camera_of

__all__ = ["export_run", "check_target", "require_pxr", "FORMATS", "USD_SUFFIXES"]

FORMATS = ("usd", "ply")
USD_SUFFIXES = (".usdc", ".usd")  # crate files: saving again appends, so a long export streams


def require_pxr() -> None:
    """Raise ValueError (one line) when usd-core is not installed."""
    try:
        from pxr import Usd, UsdGeom  # noqa: F401
    except ImportError:
        raise ValueError("--format usd needs the usd-core package: pip install usd-core "
                         "(or pip install 'taichi-rocks[usd]')") from None


def check_target(out, fmt: str, overwrite: bool) -> None:
    """Refuse (ValueError, FileExistsError; one line each) an output that cannot or must not be written."""
    out = Path(out)
    if fmt not in FORMATS:
        raise ValueError(f"format must be usd or ply, got {fmt!r}")
    if fmt == "usd":
        if out.suffix.lower() not in USD_SUFFIXES:
            raise ValueError(f"{out}: expected a .usdc (or .usd) file name")
        if out.is_dir():
            raise ValueError(f"{out}: is a directory, expected a .usdc file name")
        if out.exists() and not overwrite:
            raise FileExistsError(f"{out}: exists; pass --overwrite to replace it")
        return
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: is a file, expected a folder for the PLY frames")
    if out.is_dir():
        entries = list(out.iterdir())
        other = [p.name for p in entries if not (p.name.startswith("frame_") and p.suffix == ".ply")]
        if other:
            raise ValueError(f"{out}: holds other files ({other[0]}); export PLY frames into a new or empty folder")
        if entries and not overwrite:
            raise FileExistsError(f"{out}: holds PLY frames; pass --overwrite to replace them")


def export_run(sim, out, frames: int, fps: float, fmt: str = "usd", only: str = "all", crop=None,
               progress=None, guard: bool = True) -> dict:
    """Simulate ``frames`` frames of ``sim`` and write them to ``out`` (see the module docstring). The
    missing folders of ``out`` are created, and removed again if the run fails or is interrupted. Returns a
    summary: path, bytes, rocks per frame (mean, max)."""
    check_selection(only, crop)
    out = Path(out)
    with new_folders(out.parent):
        remove_stale_temporaries(out)
        if fmt == "usd":
            stats = _export_usd(sim, out, frames, fps, only, crop, progress, guard)
            size = out.stat().st_size
        else:
            stats = _export_ply(sim, out, frames, fps, only, crop, progress, guard)
            size = sum(p.stat().st_size for p in out.iterdir())
    counts = np.asarray(stats, np.int64)
    return {"path": str(out), "frames": frames, "bytes": size, "rocks_per_frame": counts,
            "rocks_mean": float(counts.mean()) if len(counts) else 0.0,
            "rocks_max": int(counts.max()) if len(counts) else 0}


def _export_usd(sim, out: Path, frames, fps, only, crop, progress, guard) -> list:
    from .usd import UsdWriter

    scene = sim.scene
    info = {"scene": scene.name, "seed": int(scene.seed), "fps": float(fps), "dt": float(sim.dt),
            "frames": int(frames), "only": only, "crop": float(crop) if crop is not None else 0.0}
    with atomic_path(out, suffix=".part.usdc") as tmp:
        writer = UsdWriter(tmp, scene, fps, frames, _ground_extent(sim, frames, fps), info)
        try:
            counts = _run(sim, writer, frames, fps, only, crop, progress, guard)
            writer.close()
        finally:
            writer = None  # releases the stage and its layer
    return counts


def _export_ply(sim, out: Path, frames, fps, only, crop, progress, guard) -> list:
    from .ply import PlyWriter

    work = _temp_name(out)
    old = None
    try:
        work.mkdir(mode=0o755)
        counts = _run(sim, PlyWriter(work, sim.scene.name), frames, fps, only, crop, progress, guard)
        if out.is_dir() and any(out.iterdir()):  # --overwrite of earlier frames (check_target allowed it)
            old = _temp_name(out)
            os.rename(out, old)
        os.replace(work, out)
    finally:
        shutil.rmtree(work, ignore_errors=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    return counts


def _ground_extent(sim, frames: int, fps: float):
    """(centre XY, half sides) of a ground rectangle around every vehicle's path over the export, with room
    for the bed and the view around it."""
    pts = np.array([p.position[:2] for f in range(max(frames, 1)) for p in sim.fleet.poses(f / fps)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = float(sim.scene.bed.radius) + float(sim.scene.render.draw_distance)
    return (lo + hi) / 2.0, (hi - lo) / 2.0 + margin


def _run(sim, writer, frames: int, fps: float, only: str, crop, progress, guard: bool) -> list:
    """The frame loop: simulate, choose the rocks, hand each frame to ``writer``; returns rocks per frame."""
    scene = sim.scene
    camera, rides, target = camera_of(scene)  # the renderer's rig: the same shot in the imported stage
    rocks = RockTracker(sim.n_rocks, scene.world.gravity, fps)
    vehicles = VehicleTracker(scene.vehicles)
    counts = []
    for f, st in frame_states(sim, frames, fps, guard, progress):
        origin = np.asarray(sim.origin, np.float64)
        r = rocks.update(st)
        keep = crop_mask(st, target, crop)
        if only == "flying":
            keep &= r["active"]
        idx = np.flatnonzero(keep)
        world = st["positions"][idx]
        v = vehicles.update(st["vehicle_positions"], st["vehicle_headings"])
        pos, head = st["vehicle_positions"], st["vehicle_headings"]
        looked_at = None if target == rides else (pos[target], float(head[target]))
        eye_target = camera.update(pos[rides], float(head[rides]), float(st["time"]), looked_at)[:2]
        writer.write({"frame": f, "time": float(st["time"]), "origin": origin, "world": world,
                      "local": (world - origin).astype(np.float32), "velocities": st["velocities"][idx],
                      "radii": st["radii"][idx], "ids": r["ids"][idx], "proto": r["proto"][idx],
                      "orientations": r["orientations"][idx],
                      "angular_velocities": r["angular_velocities"][idx], "vehicles": v, "camera": eye_target})
        counts.append(len(idx))
    return counts
