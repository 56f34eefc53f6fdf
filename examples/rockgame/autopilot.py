"""The recorded drive the game replays offscreen (follow.drive): the game's own car model (car.py) driven by a
simple driver behind the truck for DURATION seconds at 60 Hz, written as a recorded drive (docs/drives.md).

    python examples/rockgame/autopilot.py [--out FILE]

The driver: pure pursuit (Coulter 1992, "Implementation of the Pure Pursuit Path Tracking Algorithm", CMU-RI-TR-
92-01) of the road (the truck's path, from where the truck was) LOOKAHEAD m ahead, offset sideways by a weave;
steering delta = atan(2 L sin(alpha) / l_d) (L the wheelbase, alpha the angle to the target point, l_d its
distance), as a fraction of the car's steering limit; the pedal a PD law on the gap to the truck's rear,
u = K_GAP (gap - want) + K_SPEED (v_truck - v), clipped to [-1, 1]. What it plays: a close run (7 m, then 4 m:
the stones hit), dropping back to 12 m, weaving between the truck's wheel tracks, then close again.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from taichi_rocks.config.drivefile import drive_text  # noqa: E402

from rockgame.car import STEER_MAX, GRIP, Car  # noqa: E402
from rockgame.scene import FOLLOW_DRIVE, PLAYER, TRUCK, game_scene, truck_path  # noqa: E402

DURATION = 30.0  # s
RATE = 60.0  # poses a second
LOOKAHEAD = 9.0  # m
K_GAP, K_SPEED = 0.35, 0.6


def want(t: float) -> tuple:
    """The gap to keep (m, bumper to bumper) and the sideways offset from the road's centre (m, left) at time t."""
    if t < 4.0:
        gap = 7.0
    elif t < 9.0:
        gap = 4.0
    elif t < 14.0:
        gap = 12.0
    elif t < 22.0:
        gap = 6.0
    else:
        gap = 3.5
    side = 0.9 * math.sin(2 * math.pi * (t - 14.0) / 4.0) if 14.0 <= t < 22.0 else 0.0
    return gap, side


def drive(scene) -> list:
    """The poses, one every 1 / RATE s from t = 0: (t, x, y, heading, speed, yaw_rate, NaN)."""
    player = scene.vehicles[scene.vehicle_index(PLAYER)]
    truck = scene.vehicles[scene.vehicle_index(TRUCK)]
    path = truck_path(scene)
    v_truck = float(truck.path.speed)
    start = player.path
    car = Car(start.start[0], start.start[1], math.radians(start.heading), start.speed, wheelbase=player.wheelbase)
    half = 0.5 * (truck.length + player.length)
    rows = [(0.0, car.x, car.y, car.heading, car.speed, 0.0, math.nan)]
    dt = 1.0 / RATE
    for k in range(1, int(round(DURATION * RATE)) + 1):
        t = k * dt
        tp = path.pose(t - dt)  # what the driver sees: the truck at the frame's start
        dist = math.hypot(tp.position[0] - car.x, tp.position[1] - car.y)
        gap, side = want(t)
        back = max(dist - LOOKAHEAD, 0.0) / v_truck  # the road LOOKAHEAD m ahead: where the truck was then
        rp = path.pose(max(t - dt - back, 0.0))
        left = np.array([-math.sin(rp.heading), math.cos(rp.heading)])
        aim = np.asarray(rp.position) + side * left
        alpha = math.remainder(math.atan2(aim[1] - car.y, aim[0] - car.x) - car.heading, 2 * math.pi)
        l_d = max(math.hypot(aim[0] - car.x, aim[1] - car.y), 1.0)
        delta = math.atan(2.0 * car.wheelbase * math.sin(alpha) / l_d)
        limit = STEER_MAX / (1.0 + (car.speed / GRIP) ** 2)
        steering = float(np.clip(delta / limit, -1.0, 1.0))
        pedal = float(np.clip(K_GAP * (dist - half - gap) + K_SPEED * (v_truck - car.speed), -1.0, 1.0))
        (x, y), h, v, w = car.step(dt, pedal, steering)
        rows.append((t, x, y, h, v, w, math.nan))
    return rows


def rounded(rows) -> list:
    """Rows with 0.1 mm and 1 microradian: the file stays small, and a replay takes these numbers as they are."""
    return [(round(t, 9), round(x, 4), round(y, 4), round(h, 6), round(v, 4), round(w, 6), s)
            for t, x, y, h, v, w, s in rows]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=FOLLOW_DRIVE)
    args = ap.parse_args()
    rows = rounded(drive(game_scene()))
    tmp = args.out.with_name(args.out.name + ".part")
    tmp.write_text(drive_text(rows, [f"the player of examples/rockgame/road.toml following the truck for {DURATION:g} s "
                                     "(examples/rockgame/autopilot.py)"]))
    os.replace(tmp, args.out)
    print(f"wrote {args.out}: {len(rows)} poses")
    return 0


if __name__ == "__main__":
    sys.exit(main())
