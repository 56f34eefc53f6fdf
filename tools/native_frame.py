"""Measures the frame of a game's loop in C++ (native/: rocks_run over an x64 module) beside Python's frame of the
same run (the module's twin), in one process, alternating, and prints a table and a JSON line:

    make native && python tools/native_frame.py [--rocks 150000] [--frames 600] [--repeats 3]

The scene: scenes/convoy.toml with the game preset (one step a 60 Hz frame), tumbling and ``--rocks`` rocks (its
impacts on), as `taichi-rocks aot` exports it (app/aot.py). A frame is ``advance_to(f / 60)``, ``impacts()`` and
``changes()``; each side's figures are medians over the frames after the first 30, per repeat; "open" is, for C++,
from the start of rocks_run to the end of its first frame (the runtime, the kernels' compilation from the module,
the buffers' upload, the step of every rock), and for Python the Simulation's construction and its first frame
with its kernels already compiled (a second Simulation of the layout). docs/native.md quotes the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taichi_rocks.app.aot import make_module, twin  # noqa: E402
from taichi_rocks.config.scene import load_scene, scene_with  # noqa: E402
from taichi_rocks.engine.runtime import init_taichi, threads_in_use  # noqa: E402
from taichi_rocks.engine.simulation import Simulation  # noqa: E402

RUN = ROOT / "native" / "build" / "rocks_run"
FPS = 60.0


def python_frames(scene, frames: int) -> dict:
    t0 = time.perf_counter()
    sim = Simulation(scene, tumble=True)
    adv, chg, imp, frame = [], [], [], []
    first = None
    for f in range(1, frames + 1):
        a = time.perf_counter()
        sim.advance_to(f / FPS)
        b = time.perf_counter()
        sim.changes()
        c = time.perf_counter()
        sim.impacts()
        d = time.perf_counter()
        if f == 1:
            first = d - t0
        if f > 30:
            adv.append(b - a), chg.append(c - b), imp.append(d - c), frame.append(d - a)
    ms = lambda v: float(np.median(v) * 1e3)  # noqa: E731
    return {"open_s": first, "frame_ms": ms(frame), "advance_ms": ms(adv), "changes_ms": ms(chg),
            "impacts_ms": ms(imp), "launches": sim.launches_total}


def cpp_frames(module: Path, frames: int) -> dict:
    r = subprocess.run([str(RUN), str(module), "--frames", str(frames)], capture_output=True, text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rocks", type=int, default=150_000)
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    if not RUN.exists():
        print(f"native_frame: {RUN} missing: run make native first", file=sys.stderr)
        return 2
    init_taichi("cpu")
    scene = scene_with(load_scene(ROOT / "scenes" / "convoy.toml"),
                       {"bed.rocks": args.rocks, "sim.accuracy": "game", "effects.tumble": "always"})
    with tempfile.TemporaryDirectory() as tmp:
        module = Path(tmp) / "convoy-x64"
        t = time.perf_counter()
        info = make_module(scene, "x64", module)
        made = time.perf_counter() - t
        tw = twin(scene, module)
        python_frames(tw, 31)  # its kernels compiled once, before any timing
        py, cpp = [], []
        for _ in range(args.repeats):  # alternating, in one run
            py.append(python_frames(tw, args.frames))
            cpp.append(cpp_frames(module, args.frames))
    rows = [("frame (advance + changes + impacts)", "frame_ms"), ("advance_to", "advance_ms"),
            ("changes", "changes_ms"), ("impacts", "impacts_ms")]
    span = lambda runs, key, f="{:.3f}": "-".join(f.format(x) for x in (min(r[key] for r in runs),  # noqa: E731
                                                                      max(r[key] for r in runs)))
    print(f"convoy, {args.rocks:,} rocks, game preset, impacts and tumbling, {args.frames} frames at 60 Hz, "
          f"{args.repeats} repeats alternating; {os.cpu_count()} cores, Taichi's CPU pool {threads_in_use()} "
          f"threads; module made in {made:.1f} s ({info['bytes'] / 1e6:.1f} MB)")
    print("| median, ms | C++ (rocks_run) | Python (Simulation) |\n|---|---|---|")
    for label, key in rows:
        print(f"| {label} | {span(cpp, key)} | {span(py, key)} |")
    print(f"| open + first frame, s | {span(cpp, 'open_s', '{:.2f}')} | {span(py, 'open_s', '{:.2f}')} (kernels "
          f"compiled) |")
    print(json.dumps({"rocks": args.rocks, "frames": args.frames, "cpp": cpp, "python": py}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
