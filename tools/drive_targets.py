"""Measures the live vehicles' targets (docs/drives.md) and prints them, a line each:

    python tools/drive_targets.py [--seeds N]

* the bed on a live player off the road: the default scene's player (game preset) driven through
  examples/drive.py's swerve, 12 m off the road and back: the largest distance of the bed's centre from the
  player at any frame (the target: within one step's travel, v dt), the rocks recycled, and the share of the
  recycled rocks put down ahead of the player (in its direction of travel);
* the launches of a straight run: scenes/minimal.toml (one car, 10 m/s, its dt) over N seeds, scripted and live
  (driven at 60 Hz with the poses its path has at the frame times): the launch counts' mean, spread and range
  of each;
* the throw of a wheel spinning at twice its rolling rate against rolling: the same live car at 10 m/s, the mean
  top height (z + vz^2 / 2g) of the rocks it throws in 0.5 s, per seed.
"""

from __future__ import annotations

import argparse
import math
import runpy
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taichi_rocks.config.scene import load_scene, scene_with  # noqa: E402
from taichi_rocks.engine.simulation import Simulation  # noqa: E402
from taichi_rocks.motion.paths import WaypointPath  # noqa: E402

FPS = 60.0


def bed_follows() -> str:
    swerve = runpy.run_path(str(ROOT / "examples" / "drive.py"))  # its offset(t), not its main
    sc = scene_with(load_scene(ROOT / "scenes" / "convoy.toml"), {
        "sim.accuracy": "game", "vehicle[0].path": {"kind": "live", "start": [0.0, 0.0], "speed": 20.0}})
    sim = Simulation(sc)
    worst, ahead, total = 0.0, 0, 0
    prev = sim.state().positions
    for f in range(1, 481):
        t = f / FPS
        y, vy = swerve["offset"](t)
        sim.drive("player", (20.0 * t, y), math.atan2(vy, 20.0), speed=math.hypot(20.0, vy))
        sim.advance_to(t)
        st = sim.state()
        p = st.vehicle_positions[0]
        worst = max(worst, float(np.hypot(*(st.bed_center - p)[:2])))
        moved = np.linalg.norm((st.positions - prev)[:, :2], axis=1) > 0.5 * sc.bed.radius  # recycled
        h = st.vehicle_headings[0]
        rel = (st.positions[moved] - p)[:, :2] @ np.array([math.cos(h), math.sin(h)])
        ahead, total = ahead + int((rel > 0).sum()), total + int(moved.sum())
        prev = st.positions
    return (f"bed on a live player off the road: bed centre at most {worst:.3g} m from the player over 480 frames "
            f"(one step's travel: {20.0 * sim.dt:.3g} m), {sim.recycles_total:,} rocks recycled, "
            f"{ahead / max(total, 1):.4f} of those seen moving across the bed put down ahead of the player")


def launches(seeds: int) -> str:
    base = load_scene(ROOT / "scenes" / "minimal.toml")
    path = base.vehicles[0].path
    twin = WaypointPath(path.points, path.speed)
    counts = {"scripted": [], "live": []}
    for seed in range(1, seeds + 1):
        sc = scene_with(base, {"seed": seed})
        live = scene_with(sc, {"vehicle[0].path": {"kind": "live", "start": list(path.points[0]),
                                                   "speed": float(path.speed)}})
        for name, scene in (("scripted", sc), ("live", live)):
            sim = Simulation(scene)
            for f in range(1, int(2.0 * FPS) + 1):
                if name == "live":
                    p = twin.pose(f / FPS)
                    sim.drive("car", p.position, p.heading, speed=p.speed, yaw_rate=p.yaw_rate)
                sim.advance_to(f / FPS)
            counts[name].append(sim.launches_total)
    s, v = (np.array(counts[k], float) for k in ("scripted", "live"))
    return (f"launches of a straight run (minimal.toml, 2 s, dt {base.sim.dt:g} s, {seeds} seeds): scripted "
            f"{s.mean():.1f} +- {s.std(ddof=1):.1f} (range {s.min():.0f}-{s.max():.0f}), live {v.mean():.1f} +- "
            f"{v.std(ddof=1):.1f} (range {v.min():.0f}-{v.max():.0f}); difference of the means "
            f"{v.mean() - s.mean():+.1f} ({(v.mean() - s.mean()) / (s.std(ddof=1) / math.sqrt(seeds)):+.2f} "
            f"standard errors)")


def burnout(seeds: int) -> str:
    base = load_scene(ROOT / "scenes" / "minimal.toml")
    out = []
    for seed in range(1, seeds + 1):
        tops = {}
        for factor in (1.0, 2.0):
            sc = scene_with(base, {"seed": seed, "vehicle[0].path": {"kind": "live", "speed": 10.0}})
            sim = Simulation(sc)
            R, g = sc.vehicles[0].tire_radius, sc.world.gravity
            heights = []
            for f in range(1, 31):
                sim.drive("car", (10.0 * f / FPS, 0.0), 0.0, speed=10.0, yaw_rate=0.0,
                          wheel_spin=factor * 10.0 / R)
                sim.advance_to(f / FPS)
                st = sim.state()
                fly = (st.phase == 1) & (st.velocities[:, 2] > 0)
                heights += list(st.positions[fly, 2] + st.velocities[fly, 2] ** 2 / (2 * g))
            tops[factor] = float(np.mean(heights))
        out.append(f"{tops[2.0] / tops[1.0]:.2f}x ({tops[1.0]:.3f} -> {tops[2.0]:.3f} m)")
    return "a wheel at twice its rolling rate against rolling, mean top height of the rocks thrown: " + ", ".join(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    args = ap.parse_args()
    print(bed_follows(), flush=True)
    print(launches(args.seeds), flush=True)
    print(burnout(min(args.seeds, 4)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
