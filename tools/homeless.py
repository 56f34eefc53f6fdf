"""Where the rocks are over a long run of active stepping: rocks in the active list, and of them the resting
ones left there because their tile was full ("homeless"), and the tiles that are full.

    python tools/homeless.py                       # every shipped scene, 10 simulated minutes, and a stop-and-go
    python tools/homeless.py convoy stopgo --minutes 2 --every 1

Each scene's paths are made long enough for the run (straight paths extended along their direction, the
slalom's weave repeated, circles as they are); "stopgo" is the convoy stopping every 60 m for 2.5 s (0.02 m/s
over 5 cm), pulling away to 20 m/s and braking again. Prints one line per sample and a summary per scene (the
largest and the last figures); no file is written.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taichi_rocks.config.scene import load_scene, scene_with  # noqa: E402
from taichi_rocks.engine.probes import activity  # noqa: E402
from taichi_rocks.engine.simulation import Simulation  # noqa: E402

SHIPPED = ("minimal", "convoy", "circle", "slalom")


def long_scene(name: str, seconds: float):
    """A shipped scene whose paths last ``seconds`` at their speed."""
    sc = load_scene(ROOT / "scenes" / f"{name}.toml")
    over = {"duration": seconds}
    for i, v in enumerate(sc.vehicles):
        p = v.path
        if p.kind != "waypoints":
            continue
        speed = max(p.speed) if isinstance(p.speed, tuple) else p.speed
        pts = np.array(p.points, np.float64)
        length = speed * seconds + 100.0
        if name == "slalom":  # the weave: +-3 m every 15 m after a straight start
            xs, ys = [pts[0, 0], pts[0, 0] + 15.0], [0.0, 0.0]
            while xs[-1] < pts[0, 0] + length:
                ys.append(3.0 if len(xs) % 2 == 0 else -3.0)
                xs.append(xs[-1] + 15.0)
            over[f"vehicle[{i}].path.points"] = [[x, y] for x, y in zip(xs, ys)]
        else:
            d = (pts[-1] - pts[0]) / np.linalg.norm(pts[-1] - pts[0])
            over[f"vehicle[{i}].path.points"] = [list(pts[0]), list(pts[0] + d * length)]
    return scene_with(sc, over)


def stop_and_go(seconds: float):
    """The convoy stopping every 60 m (2.5 s at 0.02 m/s over 5 cm), pulling away to 20 m/s 30 m later and
    braking to the next stop (constant acceleration between points: about 8.5 s per 60 m)."""
    sc = load_scene(ROOT / "scenes" / "convoy.toml")
    over = {"duration": seconds}
    for i, v in enumerate(sc.vehicles):
        x0 = v.path.points[0][0]
        pts, speeds = [], []
        for k in range(int(seconds / 8.0) + 2):
            x = x0 + 60.0 * k
            pts += [[x, 0.0], [x + 0.05, 0.0], [x + 30.0, 0.0]]
            speeds += [0.02, 0.02, 20.0]
        over[f"vehicle[{i}].path.points"] = pts
        over[f"vehicle[{i}].path.speed"] = speeds
    return scene_with(sc, over)


def run(name: str, seconds: float, every: float) -> dict:
    sc = stop_and_go(seconds) if name == "stopgo" else long_scene(name, seconds)
    sim = Simulation(scene_with(sc, {"sim.stepping": "active"}))
    t0, t, rows = time.perf_counter(), 0.0, []
    print(f"# {name}: {sim.n_rocks} rocks, {seconds:g} s", flush=True)
    while t < seconds - 1e-9:
        t = min(seconds, t + every)
        sim.advance_to(t)
        a = activity(sim)
        rows.append(a)
        print(f"t {t:7.1f} s  active {a['active']:6d}  flying {a['flying']:5d}  sliding {a['sliding']:5d}  "
              f"homeless {a['homeless']:5d}  full tiles {a['full_tiles']:4d}  stored {a['stored']:7d}  "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    out = {k: max(r[k] for r in rows) for k in ("active", "homeless", "full_tiles")}
    out.update(last_homeless=rows[-1]["homeless"], samples=len(rows))
    print(f"# {name}: largest active {out['active']}, homeless {out['homeless']} (last {out['last_homeless']}), "
          f"full tiles {out['full_tiles']}, {out['samples']} samples", flush=True)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=[*SHIPPED, "stopgo"])
    ap.add_argument("--minutes", type=float, default=10.0, help="simulated minutes per scene")
    ap.add_argument("--every", type=float, default=1.0, help="simulated seconds between samples")
    args = ap.parse_args()
    for name in args.scenes:
        run(name, 60.0 * args.minutes, args.every)


if __name__ == "__main__":
    main()
