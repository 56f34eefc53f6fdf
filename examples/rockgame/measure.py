"""The game's frame budget, measured: examples/panda3d_game.py offscreen at each resolution, REPEATS times in turn
(960x540, 1280x720, 960x540, ...: a busy machine slows them alike), each run also timing a bare Panda3D frame of the
same point count after each game frame (--bare: the engine alone, in the same process), and once in a window under
a virtual display (Xvfb) where one can be started. Prints each run's JSON line and, per case, the range over the
runs of fps, rocks_ms (the rock system's calls and the mirror's update), draw_ms and the bare frame.

    python examples/rockgame/measure.py [--repeats 3] [--frames 300] [--cores 2]

``--cores N`` runs the game on the first N cores (Linux): the figure for a 2-core machine on a larger one.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

GAME = Path(__file__).resolve().parents[1] / "panda3d_game.py"


def run(args: list, cores: int | None, display: str | None = None) -> dict:
    env = dict(os.environ)
    if display:
        env["DISPLAY"] = display
    pre = (lambda: os.sched_setaffinity(0, range(cores))) if cores else None
    r = subprocess.run([sys.executable, str(GAME), *args], capture_output=True, text=True, env=env, preexec_fn=pre)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(args)}: exit {r.returncode}: {r.stderr.strip().splitlines()[-1:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def window(frames: int, cores: int | None) -> dict | None:
    """One run in a window on a virtual X display (Xvfb), or None where there is none."""
    if not shutil.which("Xvfb"):
        return None
    display = ":%d" % (90 + os.getpid() % 9)
    xvfb = subprocess.Popen(["Xvfb", display, "-screen", "0", "1280x800x24"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        for _ in range(50):  # until the display answers
            if subprocess.run(["xdpyinfo", "-display", display], capture_output=True).returncode == 0:
                break
            if xvfb.poll() is not None:
                return None
            subprocess.run(["sleep", "0.1"])
        # a recorded drive at the wheel: the window's clock is the wall clock, so it drives what a player would see
        return run(["--frames", str(frames), "--resolution", "960x540", "--drive",
                    str(GAME.parent / "rockgame" / "follow.drive")], cores, display)
    finally:
        xvfb.terminate()
        xvfb.wait()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--cores", type=int, help="run on the first N cores only")
    ap.add_argument("--no-window", action="store_true")
    args = ap.parse_args()
    results = {}
    for _ in range(args.repeats):
        for res in ("960x540", "1280x720"):
            out = run(["--offscreen", "--frames", str(args.frames), "--resolution", res, "--bare"], args.cores)
            print(res, json.dumps(out), flush=True)
            results.setdefault(f"offscreen {res}", []).append(out)
    if not args.no_window:
        out = window(args.frames, args.cores)
        if out:
            print("window 960x540", json.dumps(out), flush=True)
            results["window 960x540"] = [out]
    print()
    for case, runs in results.items():
        parts = []
        for key in ("fps", "rocks_ms", "draw_ms", "bare_ms", "bare_fps"):
            vals = [r[key] for r in runs if r.get(key) is not None]
            if vals:
                parts.append(f"{key} {min(vals):.3g}-{max(vals):.3g}" if len(vals) > 1 else f"{key} {vals[0]:.3g}")
        print(f"{case} ({len(runs)} runs): " + ", ".join(parts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
