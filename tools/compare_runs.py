"""Compare two runs of the same scene, frame by frame: how far the second's rocks are from the first's.

    taichi-rocks simulate scenes/convoy.toml --layout full --frames 300 --out cpu.npz
    taichi-rocks simulate scenes/convoy.toml --layout full --frames 300 --arch cuda --out cuda.npz
    python tools/compare_runs.py cpu.npz cuda.npz            # exit 1 if they differ beyond round-off

For each frame: the launches of each run, and the rocks whose positions differ by more than f32 round-off
(``--tol``, default: one ulp of the scene's largest coordinate per step, as tests/engine/test_backends.py
allows), by more than 1 mm and by more than 1 m, and the rocks whose phase differs. It names the first frame
where the runs part and the rocks that part there, with both states, which is where a search for the cause
starts. Both files must be ``--layout full`` runs (every rock of every frame, in id order) of the same scene,
seed and frame times. A file that cannot be read, or is not such a run, and a bad ``--tol`` are one line and
exit status 2.
"""

from __future__ import annotations

import argparse
import math
import sys
import zipfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from taichi_rocks.cliparse import distance, whole  # noqa: E402

F32_EPS = float(np.finfo(np.float32).eps)
NEED = ("positions", "phase", "launches", "time", "dt")


def load(path: str) -> dict:
    """The arrays of the full run file ``path``; ValueError (one line naming the file) if it cannot be read or
    is not one."""
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
    except (OSError, EOFError, ValueError, zipfile.BadZipFile) as e:  # missing, unreadable, not an .npz
        why = e.strerror if isinstance(e, OSError) and e.strerror else "not an .npz file"
        raise ValueError(f"{path}: cannot be read as a run file ({why})") from None
    missing = [k for k in NEED if k not in data]
    if missing:
        raise ValueError(f"{path}: not a --layout full run file (no {', '.join(missing)})")
    frames = data["time"].shape
    shapes = {"positions": (3,), "phase": (), "launches": None, "time": None}
    for key, tail in shapes.items():
        a = data[key]
        if len(frames) != 1 or a.shape[:1] != frames or (tail is not None and (a.ndim != 2 + len(tail) or
                                                                               a.shape[2:] != tail)):
            raise ValueError(f"{path}: {key} has shape {a.shape}: not a --layout full run file")
    if data["positions"].shape[1] != data["phase"].shape[1]:
        raise ValueError(f"{path}: positions and phase hold different rocks: not a --layout full run file")
    return data


def compare(a: dict, b: dict, tol: float | None = None) -> dict:
    """The frame-by-frame comparison of runs ``a`` and ``b`` (dicts of a full run file's arrays)."""
    if a["positions"].shape != b["positions"].shape or not np.array_equal(a["time"], b["time"]):
        raise ValueError("the runs differ in frames or rocks: not the same scene and frame times")
    steps = max(1, int(round(float(a["time"][-1]) / float(a["dt"])))) if len(a["time"]) else 1
    given = tol is not None
    if tol is None:
        tol = F32_EPS * (float(np.max(np.abs(a["positions"]), initial=0.0)) + 1.0) * steps
    if not (math.isfinite(tol) and tol >= 0):
        raise ValueError(f"--tol must be a finite distance >= 0 m, got {tol}")
    rows, first = [], None
    for f in range(len(a["time"])):
        d = np.linalg.norm(a["positions"][f] - b["positions"][f], axis=1)
        phase = a["phase"][f] != b["phase"][f]
        row = {"frame": f, "launches": (int(a["launches"][f]), int(b["launches"][f])),
               "beyond_tol": int((d > tol).sum()), "over_1mm": int((d > 1e-3).sum()), "over_1m": int((d > 1.0).sum()),
               "phase": int(phase.sum()), "max": float(d.max()) if len(d) else 0.0}
        rows.append(row)
        if first is None and (row["beyond_tol"] or row["phase"] or row["launches"][0] != row["launches"][1]):
            ids = np.flatnonzero((d > tol) | phase)[:10]
            first = {"frame": f, "launches": row["launches"], "beyond_tol": row["beyond_tol"], "phase": row["phase"],
                     "rocks": [(int(i), a["positions"][f, i].tolist(), b["positions"][f, i].tolist(),
                                int(a["phase"][f, i]), int(b["phase"][f, i])) for i in ids]}
    return {"tol": tol, "tol_given": given, "frames": rows, "first": first, "same": first is None}


def report(res: dict, every: int) -> str:
    out = [f"tolerance {res['tol']:.3g} m" + ("" if res.get("tol_given") else " (f32 round-off, one ulp a step)"),
           "frame  launches a/b  beyond tol  > 1 mm  > 1 m  phase  max (m)"]
    for r in res["frames"]:
        if r["frame"] % every == 0 or r["frame"] == len(res["frames"]) - 1:
            la, lb = r["launches"]
            out.append(f"{r['frame']:5d}  {la:5d}/{lb:<5d}  {r['beyond_tol']:10d}  {r['over_1mm']:6d}  {r['over_1m']:5d}  "
                       f"{r['phase']:5d}  {r['max']:.3g}")
    if res["same"]:
        out.append("the runs agree to round-off in every frame")
    else:
        first = res["first"]
        la, lb = first["launches"]
        out.append(f"first frame where they part: {first['frame']} (launches {la}/{lb}, {first['beyond_tol']} rocks "
                   f"beyond the tolerance, {first['phase']} in another phase)")
        for i, pa, pb, fa, fb in first["rocks"]:
            out.append(f"  rock {i}: {np.round(pa, 6).tolist()} phase {fa}  vs  {np.round(pb, 6).tolist()} phase {fb}")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("a", help="the reference run (.npz, --layout full)")
    ap.add_argument("b", help="the run compared with it")
    ap.add_argument("--tol", type=distance, default=None, help="metres (default: f32 round-off, one ulp a step)")
    ap.add_argument("--every", type=whole(1), default=25, help="print every this many frames (default 25)")
    args = ap.parse_args(argv)
    try:
        res = compare(load(args.a), load(args.b), args.tol)
    except ValueError as e:
        print(f"compare_runs: {e}", file=sys.stderr)
        return 2
    print(report(res, args.every))
    return 0 if res["same"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
