"""Run files (.npz): the light layout, and :func:`load_run`, the one loader of both layouts.

The full layout (output/recording.py) holds every rock of every frame: positions (F, N, 3) float64 world
metres, velocities, phase. For the default scene (200,000 rocks, 10 s at 30 fps) that is 2.2 GB, although
in a frame only ~2 % of the rocks change: those in the air, sliding, landing or recycled to the bed's edge.

The light layout writes, per frame, only the rows of rocks whose state changed since the previous frame
(``only="flying"``: the rocks in the air or sliding plus those that moved; frame 0 holds every rock) or of
every rock (``only="all"``), positions relative to the engine's floating origin:

* ``layout``: the string ``LIGHT``; ``only``, ``crop`` (metres, NaN for none): how it was written;
* ``time``, ``bed_center``, ``vehicle_positions``, ``vehicle_headings``, ``launches``, ``radii``,
  ``vehicle_names``, ``fps``, ``dt``, ``seed``, ``scene``: as in the full layout;
* ``origin`` (F, 3) float64: the floating origin of each frame (anchor + whole multiples of 64 m);
* ``frame_rows`` (F + 1,) int64: the rows of frame f are ``frame_rows[f]:frame_rows[f + 1]``;
* ``row_rock`` (M,) int32, ``row_local`` (M, 3), ``row_velocity`` (M, 3) (both in the engine's precision,
  float32 unless ``precision = "f64"``), ``row_phase`` (M,) int8: a rock's state from that frame on, its
  world position ``origin[f] + row_local``.

With impacts (``[effects] impacts``), both layouts also hold ``impacts``: the run's impact events, a structured
array of engine/events.py ``EVENT_DTYPE`` in (step, rock, vehicle) order (``load_run`` returns it as it is; a
run without impacts has none). :func:`impacts_csv` writes them as CSV, :func:`impacts_summary` counts them.

A rock without a row in a frame is unchanged since the previous frame (its simulated position, velocity and
phase are the same bits), so ``only="flying"`` loses nothing. The engine keeps rock positions in its own
precision relative to that origin and computes world = float64(local) + origin: a row stores the engine's
own value, and :func:`load_run` gives back the full layout's float64 positions (identical where tested; at
worst one float64 rounding, 1e-11 m at 100 km). With ``crop = R`` only rocks within R metres (horizontally)
of the camera's followed vehicle are kept; a rock leaving that circle gets one row with ``row_phase``
``MISSING`` (-1) and NaN position and velocity, which is what :func:`load_run` returns for it until it is
back inside.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..config.impacts import DAMAGE_CLASSES
from ..motion.bodies import LABELS
from .npz import Raw, reserved_memmap

__all__ = ["LIGHT", "MISSING", "RUN_KEYS", "load_run", "record_light", "RowChanges", "crop_mask", "crop_vehicle",
           "check_selection", "impacts_csv", "impacts_summary"]

LIGHT = "taichi-rocks run, light layout 1"
MISSING = -1  # row_phase of a rock outside the crop: NaN position and velocity until it is back inside

# the arrays of a run as the full layout holds them, in its order: what load_run returns for either layout
RUN_KEYS = ("time", "positions", "velocities", "phase", "bed_center", "vehicle_positions", "vehicle_headings",
            "launches", "radii", "vehicle_names", "fps", "dt", "seed", "scene")


class RowChanges:
    """Which rocks changed since the previous frame: position (float64 world bits), velocity or phase."""

    def __init__(self):
        self.prev = None

    def update(self, st: dict) -> np.ndarray:
        """A boolean (N,) mask of the rocks whose state differs from the last call's (all, the first time)."""
        n = len(st["radii"])
        cur = (st["positions"], st["velocities"], st["phase"])
        if self.prev is None:
            changed = np.ones(n, bool)
        else:
            p, v, ph = self.prev
            changed = (cur[0] != p).any(axis=1) | (cur[1] != v).any(axis=1) | (cur[2] != ph)
        self.prev = tuple(np.array(a, copy=True) for a in cur)
        return changed


def crop_vehicle(scene) -> int:
    """The vehicle ``--crop`` keeps the rocks around (run files and exports alike): the camera's followed
    vehicle, ``camera.follow`` (default bed.follow), also when the camera looks at another (``camera.target``)."""
    return scene.vehicle_index(scene.camera.follow)


def crop_mask(st: dict, follow: int, crop) -> np.ndarray:
    """The rocks within ``crop`` metres (horizontal distance) of vehicle ``follow``; all for ``crop`` None."""
    n = len(st["radii"])
    if crop is None:
        return np.ones(n, bool)
    c = np.asarray(st["vehicle_positions"][follow], np.float64)
    d2 = (st["positions"][:, 0] - c[0]) ** 2 + (st["positions"][:, 1] - c[1]) ** 2
    return d2 <= float(crop) ** 2


def check_selection(only: str, crop) -> None:
    if only not in ("flying", "all"):
        raise ValueError(f"--only must be flying or all, got {only!r}")
    if crop is not None and not (math.isfinite(crop) and crop > 0):
        raise ValueError(f"--crop must be a finite radius > 0 m, got {crop}")


def record_light(sim, work: Path, frames: int, fps: float, states, only: str = "flying", crop=None) -> dict:
    """Write the frames ``states`` yields ((f, ``sim.state()``), app/frames.py ``frame_states``, or ``frame_mirrors``
    whose states say which rocks "changed") into ``work``
    (memory-mapped .npy files and row files appended frame by frame); returns the members of the light .npz
    (see the module docstring), in its order."""
    check_selection(only, crop)
    n, v, real = sim.n_rocks, len(sim.fleet.names), np.dtype(sim.world.np_real())
    shapes = {"time": ((frames,), np.float64), "origin": ((frames, 3), np.float64),
              "bed_center": ((frames, 3), np.float64), "vehicle_positions": ((frames, v, 3), np.float64),
              "vehicle_headings": ((frames, v), np.float64), "launches": ((frames,), np.int64),
              "frame_rows": ((frames + 1,), np.int64)}
    arrays = {k: reserved_memmap(work / f"{k}.npy", dt, shape) for k, (shape, dt) in shapes.items()}
    rows = {"row_rock": np.int32, "row_local": real, "row_velocity": real, "row_phase": np.int8}
    files = {k: open(work / f"{k}.raw", "wb") for k in rows}
    follow = crop_vehicle(sim.scene)
    changes, present, total = RowChanges(), None, 0
    previous, st = sim.launches_total, None
    try:
        arrays["frame_rows"][0] = 0
        for f, st in states:
            origin = np.asarray(sim.origin, np.float64)
            for k in ("time", "bed_center", "vehicle_positions", "vehicle_headings"):
                arrays[k][f] = st[k]
            arrays["origin"][f] = origin
            arrays["launches"][f] = st["launches_total"] - previous
            previous = st["launches_total"]
            inside = crop_mask(st, follow, crop)
            if "changed" in st:  # the rows of Simulation.changes() (app/frames.py frame_mirrors)
                changed = np.zeros(n, bool)
                changed[st["changed"]] = True
            else:
                changed = changes.update(st)
            entered = np.ones(n, bool) if present is None else inside != present
            keep = entered | (inside & (changed if only == "flying" else True))
            present = inside
            total += _write_rows(files, np.flatnonzero(keep), st, origin, inside, real)
            arrays["frame_rows"][f + 1] = total
    finally:
        for fh in files.values():
            fh.close()
    for a in arrays.values():
        a.flush()
    del arrays
    members = {"layout": np.array(LIGHT), "only": np.array(only),
               "crop": np.float64(np.nan if crop is None else crop)}
    for k in shapes:
        members[k] = work / f"{k}.npy"
    for k, dt in rows.items():
        members[k] = Raw(work / f"{k}.raw", np.dtype(dt), (total, 3) if k in ("row_local", "row_velocity")
                         else (total,))
    st = st if st is not None else sim.state()
    members.update(radii=st["radii"], vehicle_names=np.array(sim.fleet.names), fps=np.float64(fps),
                   dt=np.float64(sim.dt), seed=np.int64(sim.scene.seed), scene=np.array(sim.scene.name))
    return members


def _write_rows(files: dict, idx: np.ndarray, st: dict, origin: np.ndarray, inside: np.ndarray, real) -> int:
    """Append the rows of rocks ``idx``: their state, or MISSING for those outside the crop. Returns len(idx)."""
    local = (st["positions"][idx] - origin).astype(real)
    vel = np.asarray(st["velocities"][idx], real)
    phase = np.asarray(st["phase"][idx], np.int8)
    out = ~inside[idx]
    if out.any():
        local[out] = np.nan
        vel[out] = np.nan
        phase = phase.copy()
        phase[out] = MISSING
    files["row_rock"].write(idx.astype(np.int32).tobytes())
    files["row_local"].write(np.ascontiguousarray(local).tobytes())
    files["row_velocity"].write(np.ascontiguousarray(vel).tobytes())
    files["row_phase"].write(phase.tobytes())
    return len(idx)


def load_run(path) -> dict:
    """The arrays of a run file under the full layout's names, from either layout: code written against full
    files reads light ones through it (docs/export.md, "Run files").

    Args:
        path: a run file written by ``taichi-rocks simulate`` or ``record``.

    Returns:
        A dict: "positions" (F, N, 3) float64 world metres, "velocities" (F, N, 3), "phase" (F, N) (0 resting,
        1 flying, 2 sliding; -1 outside a crop), "radii" (N,), "bed_center" (F, 3), "vehicle_positions"
        (F, V, 3), "vehicle_headings" (F, V), "vehicle_names" (V,), "launches" (F,), "time" (F,), "fps", "dt",
        "seed", "scene", and "impacts" when the run recorded them.
    """
    with np.load(path) as z:
        if "layout" not in z.files:
            return {k: z[k] for k in z.files}
        if str(z["layout"]) != LIGHT:
            raise ValueError(f"{path}: unknown run layout {str(z['layout'])!r}")
        data = {k: z[k] for k in z.files}
    return _expand(data)


def _expand(d: dict) -> dict:
    """Full arrays from the rows of a light file: each frame starts from the previous one and takes its rows."""
    frames, n = len(d["time"]), len(d["radii"])
    real = d["row_velocity"].dtype
    pos = np.empty((frames, n, 3))
    vel = np.empty((frames, n, 3), real)
    phase = np.empty((frames, n), np.int8)
    cur_p, cur_v, cur_ph = np.full((n, 3), np.nan), np.full((n, 3), np.nan, real), np.full(n, MISSING, np.int8)
    rows = d["frame_rows"]
    for f in range(frames):
        a, b = int(rows[f]), int(rows[f + 1])
        idx = d["row_rock"][a:b]
        cur_p[idx] = d["row_local"][a:b].astype(np.float64) + d["origin"][f]
        cur_v[idx] = d["row_velocity"][a:b]
        cur_ph[idx] = d["row_phase"][a:b]
        pos[f], vel[f], phase[f] = cur_p, cur_v, cur_ph
    out = {"positions": pos, "velocities": vel, "phase": phase}
    keys = RUN_KEYS + (("impacts",) if "impacts" in d else ())
    return {k: out[k] if k in out else d[k] for k in keys}


def impacts_csv(events: np.ndarray, f) -> None:
    """Write ``events`` (engine/events.py EVENT_DTYPE) to the binary file ``f`` as CSV: a header of the field
    names in the dtype's order (vectors as name_x, name_y, name_z), one row per event, ``part`` and ``damage``
    as names, floats in full precision (repr: they read back to the same bits)."""
    header, cols = [], []
    for name in events.dtype.names:
        if events.dtype[name].shape:
            header += [f"{name}_{a}" for a in "xyz"]
            cols += [(name, j) for j in range(3)]
        else:
            header.append(name)
            cols.append((name, None))
    lines = [",".join(header)]
    for ev in events:
        row = []
        for name, j in cols:
            v = ev[name] if j is None else ev[name][j]
            if name == "part":
                row.append(LABELS[int(v)])
            elif name == "damage":
                row.append(DAMAGE_CLASSES[int(v)])
            elif np.issubdtype(np.asarray(v).dtype, np.integer):
                row.append(str(int(v)))
            else:
                row.append(repr(float(v)))
        lines.append(",".join(row))
    f.write(("\n".join(lines) + "\n").encode("ascii"))


def impacts_summary(events: np.ndarray, names) -> str:
    """One line: the hits per vehicle and part, e.g. ``impacts: 12 hits (player 9: windscreen 4, bonnet 5;
    truck 3: rear 3)``; vehicles without hits are left out."""
    if len(events) == 0:
        return "impacts: no hits"
    parts = []
    for v in np.unique(events["vehicle"]):
        mine = events[events["vehicle"] == v]
        labels, counts = np.unique(mine["part"], return_counts=True)
        detail = ", ".join(f"{LABELS[int(p)]} {int(c)}" for p, c in zip(labels, counts))
        parts.append(f"{names[int(v)]} {len(mine)}: {detail}")
    return f"impacts: {len(events)} hit{'s' if len(events) != 1 else ''} (" + "; ".join(parts) + ")"
