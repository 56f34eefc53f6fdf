"""``taichi-rocks simulate``: run a scene headless and write its run file (.npz), full or light layout
(output/recording.py, output/runs.py), atomically: a temporary file beside the final name, renamed when
complete; the folders it created are removed again if the run fails or is interrupted. With impacts the run
file holds the run's events (``impacts``, drained every frame), ``--impacts FILE.csv`` writes them as CSV too
(output/runs.py ``impacts_csv``), and the summary counts them."""

from __future__ import annotations

import errno
import os
import shutil
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..engine.events import EVENT_DTYPE
from ..engine.simulation import Simulation
from ..output.atomic import check_place, new_folders, remove_stale_temporaries, temp_name, write_atomically
from ..output.npz import write_npz
from ..output.recording import record_full
from ..output.runs import impacts_csv, record_light
from .frames import frame_count, frame_mirrors, frame_states

__all__ = ["simulate_scene", "record", "WRITE_ERRORS"]

WRITE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES, errno.EIO)


def simulate_scene(scene, out=None, frames=None, fps=None, arch: str = "cpu", seed=None, overwrite: bool = False,
                   layout: str = "light", only=None, crop=None, progress=None, impacts=None) -> dict:
    """Simulate a validated ``scene`` and write its run file to ``out`` (default
    ``renders/<scene>/<scene>.npz``); ``frames`` and ``fps`` as app/frames.py :func:`frame_count`. Refuses
    (ValueError, FileExistsError) before anything runs: ``only``/``crop`` with the full layout, an existing
    ``out`` without ``overwrite``, a folder named ``out``. ``progress``: a tqdm bar on stderr; None shows it
    only on a terminal; ``impacts``: a CSV file for the run's impact events (refused like ``out``). Returns
    :func:`record`'s summary with "launches" (rocks launched in the run)."""
    out = Path(out) if out is not None else Path("renders") / scene.name / f"{scene.name}.npz"
    if layout == "full" and (only or crop):
        raise ValueError("--only and --crop need --layout light (the full layout holds every rock)")
    if out.is_dir():  # before the overwrite check: --overwrite would not help
        raise ValueError(f"{out}: is a directory, expected an .npz file name")
    csv = Path(impacts) if impacts is not None else None
    for path in (out, csv) if csv is not None else (out,):
        if path.is_dir():
            raise ValueError(f"{path}: is a directory, expected a file name")
        check_place(path)
        if path.exists() and not overwrite:
            raise FileExistsError(f"{path}: exists; pass --overwrite to replace it")
    frames, fps = frame_count(scene, frames, fps)
    sim = Simulation(scene, arch=arch, seed=seed)
    with tqdm(total=frames, unit="frame", desc=f"simulate {scene.name}", file=sys.stderr,
              disable=None if progress is None else not progress) as bar:
        info = record(sim, out, frames, fps, progress=bar, layout=layout, only=only or "flying", crop=crop)
    info["launches"] = sim.launches_total
    if csv is not None:
        events = info.get("impacts", np.empty(0, EVENT_DTYPE))
        with new_folders(csv.parent):
            write_atomically(csv, lambda f: impacts_csv(events, f))
    return info


def record(sim, out: Path, frames: int, fps: float, progress=None, guard: bool = True, layout: str = "light",
           only: str = "flying", crop=None) -> dict:
    """Run ``sim`` for ``frames`` frames and write ``out`` (its missing folders are created, and removed
    again if the run fails or is interrupted). The file is written under a temporary name and renamed when
    complete; ``taichi_rocks.load_run`` reads it back (docs/export.md, "Run files").

    Args:
        sim: a Simulation at time 0.
        out: the .npz file to write.
        frames: frames to record; frame f is the state at f / fps.
        fps: frames per second of simulated time.
        progress: a tqdm bar (its ``update(1)`` is called once a frame is done), or None.
        guard: check every rock after every frame (``Simulation.check_health``); on failure the HealthError
            propagates and nothing is written under ``out``.
        layout: "full" (every rock of every frame, float64 world positions) or "light" (the rocks that changed
            in each frame, output/runs.py).
        only: light layout: "flying" (the rocks that changed) or "all" (every rock every frame).
        crop: light layout: keep only the rocks within this many metres of the camera's followed vehicle, or
            None.

    Returns:
        A summary: "frames", "rocks", "path", "bytes", "layout", and with impacts "impacts" (the events, a
        structured array) and "impacts_dropped".

    Raises:
        HealthError: the runtime guard found a rock in an impossible state.
        ValueError: an unknown layout.
    """
    out = Path(out)
    if layout not in ("full", "light"):
        raise ValueError(f"layout must be full or light, got {layout!r}")
    with new_folders(out.parent):
        remove_stale_temporaries(out)
        work = temp_name(out)
        try:
            work.mkdir(mode=0o700)
            chunks = []
            each = frame_states if layout == "full" or not sim.plan.drawn else frame_mirrors
            states = _draining(sim, each(sim, frames, fps, guard, progress), chunks)
            if layout == "full":
                members = record_full(sim, work, frames, fps, states)
            else:
                members = record_light(sim, work, frames, fps, states, only=only, crop=crop)
            if sim.plan.impacts:
                members["impacts"] = np.concatenate(chunks) if chunks else np.empty(0, EVENT_DTYPE)
            write_atomically(out, lambda f: write_npz(f, members))
        except OSError as e:
            if e.errno in WRITE_ERRORS:  # the disk full, ...: one line naming the output, not a temporary
                raise OSError(e.errno, os.strerror(e.errno), str(out)) from None
            raise
        finally:
            shutil.rmtree(work, ignore_errors=True)
    info = {"frames": frames, "rocks": sim.n_rocks, "path": str(out), "bytes": out.stat().st_size,
            "layout": layout}
    if sim.plan.impacts:
        info.update(impacts=members["impacts"], impacts_dropped=sim.impacts_dropped)
    return info


def _draining(sim, states, chunks: list):
    """``states`` passed through, the impact events of each frame's steps appended to ``chunks`` (the host
    holds no more than a frame's events)."""
    for item in states:
        if sim.plan.impacts:
            ev = sim.impacts()
            if len(ev):
                chunks.append(ev)
        yield item
