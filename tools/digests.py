"""Digests of what the shipped scenes produce, to prove that a refactor changed no behaviour.

    python tools/digests.py > before.json      # on the old code
    python tools/digests.py > after.json       # on the new code
    diff before.json after.json                # identical: same arrays, same frames

Runs the command line (the stable interface) on every scene in scenes/: ``simulate`` for a few frames
(SHA-256 of every array of the .npz, in the full layout: every rock of every frame as the engine gives it) and ``render`` of a few PNG frames (SHA-256 of the decoded pixels).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _run(*args) -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-m", "taichi_rocks", *map(str, args)], env=env, capture_output=True,
                       text=True)
    if r.returncode:
        raise SystemExit(f"digests: taichi-rocks {' '.join(map(str, args))} failed:\n{r.stderr}")


def _sha(a: np.ndarray) -> str:
    a = np.ascontiguousarray(a)
    return hashlib.sha256(str(a.dtype).encode() + str(a.shape).encode() + a.tobytes()).hexdigest()[:16]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=20, help="frames simulated per scene")
    ap.add_argument("--render-frames", type=int, default=3, help="frames rendered per scene (0: none)")
    ap.add_argument("--scenes", nargs="*", type=Path, default=sorted((ROOT / "scenes").glob("*.toml")))
    args = ap.parse_args()
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in args.scenes:
            npz = Path(tmp) / f"{scene.stem}.npz"
            _run("simulate", scene, "--frames", args.frames, "--layout", "full", "--out", npz)
            with np.load(npz) as d:
                out[f"{scene.stem}.npz"] = {k: _sha(d[k]) for k in sorted(d.files)}
            if args.render_frames:
                import imageio.v3 as iio

                frames = Path(tmp) / f"{scene.stem}_frames"
                _run("render", scene, "--frames", args.render_frames, "--resolution", "320x180", "--format", "png",
                     "--out", frames)
                out[f"{scene.stem}.png"] = [_sha(iio.imread(p)) for p in sorted(frames.rglob("frame_*.png"))]
    json.dump(out, sys.stdout, indent=1, sort_keys=True)
    print()


if __name__ == "__main__":
    main()
