"""``taichi-rocks export``: a run written for the tools artists use, frame by frame while simulating.

The format is a writer of the registry (output/formats.py: USD, PLY, ...); this runs the frames (app/frames.py),
makes each exported frame (output/export.py), adds the frame's impacts when the simulation records them
(``frame["impacts"]``, :func:`impact_frame`) and hands it to the writer, which writes under a temporary name
beside the output and renames it when complete. An existing output is replaced only with ``overwrite``
(checked by the writer before anything is simulated); the missing folders of the output are created, and
removed again if the export fails or is interrupted.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..engine.simulation import Simulation
from ..output.atomic import new_folders, remove_stale_temporaries
from ..output.export import ExportFrames
from ..output.formats import ExportRun, writer_class
from ..output.runs import check_selection
from ..render.marks import body_to_local, to_body_frame
from .frames import frame_count, frame_states
from .simulate import WRITE_ERRORS

__all__ = ["export_scene", "export_run", "default_out", "impact_frame"]


def default_out(scene, fmt: str) -> Path:
    """Where ``export --format fmt`` writes without ``--out``: under ``renders/<scene>/``."""
    return Path("renders") / scene.name / writer_class(fmt).default_name.format(scene=scene.name)


def export_scene(scene, out=None, fmt: str = "usd", frames=None, fps=None, arch: str = "cpu", seed=None,
                 overwrite: bool = False, only=None, crop=None, progress=None) -> dict:
    """Simulate a validated ``scene`` and export it as ``fmt`` to ``out`` (default :func:`default_out`);
    ``frames`` and ``fps`` as app/frames.py :func:`frame_count`, ``only`` default "all". Refuses a bad or
    existing output (ValueError, FileExistsError) before anything runs. ``progress``: a tqdm bar on stderr;
    None shows it only on a terminal. Returns :func:`export_run`'s summary."""
    writer = writer_class(fmt)
    out = Path(out) if out is not None else default_out(scene, fmt)
    writer.check_target(out, overwrite)
    frames, fps = frame_count(scene, frames, fps)
    # the instances' orientations are the engine's; every frame's whole state is exported (no changes() mirror)
    sim = Simulation(scene, arch=arch, seed=seed, tumble=True, track_changes=False)
    with tqdm(total=frames, unit="frame", desc=f"export {scene.name}", file=sys.stderr,
              disable=None if progress is None else not progress) as bar:
        return export_run(sim, out, frames, fps, fmt=fmt, only=only or "all", crop=crop, progress=bar)


def export_run(sim, out, frames: int, fps: float, fmt: str = "usd", only: str = "all", crop=None,
               progress=None, guard: bool = True) -> dict:
    """Simulate ``frames`` frames of ``sim`` (built with ``tumble=True``: the instances' orientations and
    angular velocities are its rocks') and write them to ``out`` as ``fmt`` (see the module docstring).
    Returns a summary: path, frames, bytes, rocks per frame (all, mean, max)."""
    check_selection(only, crop)
    if sim.n_rocks and not sim.plan.spin:
        raise ValueError("export needs the rocks' orientations: build the Simulation with tumble=True")
    cls = writer_class(fmt)
    out = Path(out)
    run = ExportRun(scene=sim.scene, fps=float(fps), frames=int(frames), dt=float(sim.dt), only=only, crop=crop,
                    fleet=sim.fleet)
    counts = []
    with new_folders(out.parent):
        remove_stale_temporaries(out)
        make = ExportFrames(sim.scene, sim.n_rocks, fps, only, crop)
        writer = None
        try:
            writer = cls(out, run)
            for f, st in frame_states(sim, frames, fps, guard, progress):
                frame = make.frame(f, st, sim.origin)
                if sim.plan.impacts:
                    frame.impacts = impact_frame(sim, sim.impacts())
                frame.effects = sim.effect_arrays()  # the optional effects' arrays (dust: output/dust.py)
                writer.write(frame)
                counts.append(len(frame["ids"]))
            size = writer.close()
        except BaseException as e:
            if writer is not None:
                writer.abort()
            if isinstance(e, OSError) and e.errno in WRITE_ERRORS and e.filename != str(out):
                raise OSError(e.errno, e.strerror, str(out)) from None  # the output named, not a temporary
            raise
    counts = np.asarray(counts, np.int64)
    return {"path": str(out), "frames": frames, "bytes": size, "rocks_per_frame": counts,
            "rocks_mean": float(counts.mean()) if len(counts) else 0.0,
            "rocks_max": int(counts.max()) if len(counts) else 0}


def impact_frame(sim, events) -> dict:
    """The impacts of one exported frame (``events``: ``sim.impacts()`` since the frame before, engine/events.py
    EVENT_DTYPE): ``events`` with their points and normals in the body frame on the ground (render/marks.py
    to_body_frame), and ``world`` (K, 3) float64 contact points and ``normals`` (K, 3), placed with each hit
    vehicle's pose at the time of its hit (motion/vehicles.py Fleet.poses)."""
    ev = to_body_frame(events, float(sim.scene.world.ground_z) - float(sim.origin[2]))
    world, normals = np.empty((len(ev), 3)), np.empty((len(ev), 3))
    for t in np.unique(ev["time"]):
        sel = np.flatnonzero(ev["time"] == t)
        poses = sim.fleet.poses(float(t))
        pos = np.array([poses[v].position for v in ev["vehicle"][sel]], np.float64)
        head = np.array([poses[v].heading for v in ev["vehicle"][sel]], np.float64)
        world[sel] = body_to_local(ev["point"][sel], pos, head)
        normals[sel] = body_to_local(ev["normal"][sel], np.zeros_like(pos), head)
    return {"events": ev, "world": world, "normals": normals}
