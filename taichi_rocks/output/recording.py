"""The full layout of a run file (.npz), streamed through memory-mapped files so that a long run of many rocks
never holds all frames in memory; ``simulate`` (app/simulate.py ``record``) runs the frames and writes the
file atomically (temporary name, then rename).

Two layouts (docs/export.md, "Run files"). ``layout="full"``: every rock of every frame, as the engine gives it. Frame
f is the state at time f / fps. Arrays: time (F,), positions (F, N, 3) float64 world metres, velocities
(F, N, 3) float32, phase (F, N) int8 (0 resting, 1 flying, 2 sliding), radii (N,), bed_center (F, 3),
vehicle_positions (F, V, 3), vehicle_headings (F, V), vehicle_names (V,), launches (F,) = rocks launched
since the previous frame, plus fps, dt, seed and scene name. ``layout="light"`` (the default of ``simulate``):
rows of the rocks that changed, positions relative to the floating origin (output/runs.py, which also holds
:func:`~taichi_rocks.output.runs.load_run`, the one loader of both).

The same scene, seed and arch give the same bytes: the zip members are stored (not compressed) in a fixed
order with a fixed time stamp and fixed permissions (output/npz.py :func:`write_npz`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# The atomic-write helpers moved to output/atomic.py and write_npz to output/npz.py; imported here too for
# the code that reaches them through this module.
from .atomic import atomic_path, new_folders, remove_stale_temporaries, temp_name, write_atomically  # noqa: F401
from .npz import ZIP_EPOCH, Raw, reserved_memmap, write_npz  # noqa: F401


__all__ = ["record_full"]


def record_full(sim, work: Path, frames: int, fps: float, states) -> dict:
    """Write the frames ``states`` yields ((f, ``sim.state()``) for f = 0 .. frames - 1, app/frames.py
    ``frame_states``) into memory-mapped ``work/NAME.npy`` files; returns the members of the full .npz, in its
    order."""
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
    arrays = {k: reserved_memmap(work / f"{k}.npy", dt, shape) for k, (shape, dt) in shapes.items()}
    previous = sim.launches_total
    st = None
    for f, st in states:
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
    return {k: work / f"{k}.npy" for k in list(shapes) + list(small)}
