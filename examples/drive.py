"""A game drives the player: the default scene's player made live and steered, frame by frame, off the scripted
road into the open and back (a swerve 12 m to the left and back at 20 m/s), with ``changes()`` and ``impacts()``
read as a game reads them.

    python examples/drive.py [--frames N] [--record FILE] [--rocks N]

Each frame the game works out where its car is (here a function of time: the game's own physics, in a real
game) and tells the simulation with ``Simulation.drive``, which takes it as the pose at the end of the next
``advance_to``; the speed and heading are given, the yaw rate left to the engine (derived from the motion). Prints,
once a second, the player's distance from the road, how far the bed's centre is from the player (the bed
follows it off the road), the rocks recycled to the bed's leading edge and launched so far, the hits, and the
frame's cost (drive + advance_to + impacts + changes). ``--record FILE`` writes the drive (docs/drives.md): a
scene's ``path = { kind = "recorded", file = FILE }`` replays it (examples/swerve.drive is this drive).
"""

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from taichi_rocks import Simulation  # noqa: E402
from taichi_rocks.config.drivefile import drive_text  # noqa: E402
from taichi_rocks.config.scene import load_scene, scene_with  # noqa: E402

SPEED = 20.0  # m/s along the road (+x)
SWERVE = 12.0  # m to the left of the road at the widest


def offset(t: float) -> tuple:
    """The game's car: its distance left of the road (m) and how fast that changes (m/s) at time t: out between
    1 s and 3 s, back between 5 s and 7 s (a smooth step each way)."""
    def step(a, b):  # 0 before a, 1 after b, C1 in between; and its derivative
        s = min(max((t - a) / (b - a), 0.0), 1.0)
        return s * s * (3.0 - 2.0 * s), 6.0 * s * (1.0 - s) / (b - a)
    out, d_out = step(1.0, 3.0)
    back, d_back = step(5.0, 7.0)
    return SWERVE * (out - back), SWERVE * (d_out - d_back)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=480, help="frames at 60 Hz (default: 8 s)")
    ap.add_argument("--record", type=Path, metavar="FILE", help="write the drive to FILE (docs/drives.md)")
    ap.add_argument("--rocks", type=int, help="rocks in the bed (default: the scene's 200,000)")
    args = ap.parse_args()

    scene = load_scene(ROOT / "scenes" / "convoy.toml")
    scene = scene_with(scene, {"sim.accuracy": "game",  # one step a 60 Hz frame
                               "vehicle[0].path": {"kind": "live", "start": [0.0, 0.0], "speed": SPEED},
                               **({"bed.rocks": args.rocks} if args.rocks else {})})
    sim = Simulation(scene)
    positions = np.zeros((sim.n_rocks, 3))  # the game's mirror of the bed
    positions[...] = sim.changes().positions  # the first call: every rock
    hits, costs, worst = 0, [], 0.0
    for f in range(1, args.frames + 1):
        t = f / 60
        y, vy = offset(t)
        t0 = time.perf_counter()
        sim.drive("player", (SPEED * t, y), math.atan2(vy, SPEED), speed=math.hypot(SPEED, vy))
        sim.advance_to(t)
        events = sim.impacts()
        rows = sim.changes()
        costs.append(time.perf_counter() - t0)
        positions[rows.ids] = rows.positions
        hits += len(events)
        player = sim.vehicle_poses()[0].position
        worst = max(worst, float(np.hypot(*(sim.bed_center - player)[:2])))
        if f % 60 == 0:
            print(f"t {t:4.1f} s: player {player[1]:5.2f} m off the road, bed centre {worst:.3g} m from it "
                  f"(at most, so far), {sim.recycles_total:7,} rocks recycled, {sim.launches_total:6,} launched, "
                  f"{hits} hits, frame {1e3 * np.median(costs[-60:]):.2f} ms (median of the second)")
    assert np.array_equal(positions, sim.state().positions)  # the mirror is the bed
    if args.record:
        args.record.write_text(drive_text(sim.drive_track("player"), ["the player of scenes/convoy.toml swerving "
                                                                      "12 m off the road and back (examples/drive.py)"]))
        print(f"wrote {args.record}: {len(sim.drive_track('player'))} poses")
    return 0


if __name__ == "__main__":
    sys.exit(main())
