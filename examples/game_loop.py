"""A game's frame with taichi_rocks: step to the frame's time, take the impacts, read what changed.

    python examples/game_loop.py [SCENE] [--frames N] [--accuracy game|custom]

Keeps a mirror of the bed (what a game would draw: positions and phases by rock id), updates it from
``Simulation.changes()`` each frame, and prints the per-frame cost of each call (median and 95th percentile).
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taichi_rocks import Simulation  # noqa: E402
from taichi_rocks.config.scene import load_scene, scene_with, shipped_scene  # noqa: E402


def frame_count(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if n < 2:  # the first frame compiles the kernels: its cost is left out, so at least one more is measured
        raise argparse.ArgumentTypeError(f"must be >= 2 (the first frame compiles and is not timed), got {n}")
    return n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", default=str(shipped_scene("convoy")))
    ap.add_argument("--frames", type=frame_count, default=300)
    ap.add_argument("--accuracy", default="game", help='"game": one step per 60 Hz frame; "custom": the scene\'s dt')
    args = ap.parse_args()

    scene = load_scene(args.scene)
    if args.accuracy != "custom":  # as [sim] accuracy = "game" in the file: dt = 1/60 s, one step per frame
        scene = scene_with(scene, {"sim.accuracy": args.accuracy})
    sim = Simulation(scene)

    positions = np.zeros((sim.n_rocks, 3))  # the game's mirror of the bed
    phase = np.zeros(sim.n_rocks, np.int8)
    costs = {"advance_to": [], "impacts": [], "changes": []}
    hits = rows = 0
    for f in range(args.frames):
        t0 = time.perf_counter()
        sim.advance_to(f / 60)  # the simulation at the frame's time
        t1 = time.perf_counter()
        events = sim.impacts()  # stones that hit a vehicle since the last frame
        t2 = time.perf_counter()
        changed = sim.changes()  # the rocks whose drawn state changed since the last frame
        t3 = time.perf_counter()
        positions[changed["ids"]] = changed["positions"]
        phase[changed["ids"]] = changed["phase"]
        hits += len(events)
        if f:  # the first frame compiles the kernels and reads every rock
            rows += len(changed["ids"])
            for k, dt in zip(costs, (t1 - t0, t2 - t1, t3 - t2)):
                costs[k].append(1e3 * dt)

    frame = np.sum([costs[k] for k in costs], axis=0)
    print(f"{sim.scene.name}: {sim.n_rocks:,} rocks, dt = {sim.dt:.4g} s, {args.frames} frames at 60 Hz, "
          f"{rows / max(1, args.frames - 1):,.0f} rows a frame, {hits} impacts")
    for k, v in list(costs.items()) + [("frame", frame)]:
        print(f"  {k:>10}: median {np.median(v):.3f} ms, p95 {np.percentile(v, 95):.3f} ms")
    assert np.array_equal(positions, sim.state()["positions"])  # the mirror is the bed
    print("  the mirror matches state() exactly")
    return 0


if __name__ == "__main__":
    sys.exit(main())
