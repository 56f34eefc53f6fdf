"""The game's scene: examples/rockgame/road.toml (a truck on a 1.24 km loop of gravel road, the player's car
live behind it), with the game's options applied, and the road it draws: the truck's scripted path sampled once
round the loop (motion/paths.py), so the road runs exactly where the truck drives.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from taichi_rocks.config.scene import load_scene, scene_with
from taichi_rocks.motion.paths import path_from_spec

HERE = Path(__file__).resolve().parent
SCENE = HERE / "road.toml"
FOLLOW_DRIVE = HERE / "follow.drive"  # the offscreen mode's scripted input (autopilot.py wrote it)
PLAYER, TRUCK = "player", "truck"


def game_scene(rocks: int | None = None, truck_splash: bool = True, seed: int | None = None):
    """The game's Scene: road.toml, with ``rocks`` in the bed (None: the file's 50,000, keeping its density: the
    bed's radius grows as sqrt(rocks)), the truck's tires throwing or not (``truck_splash``; the test's
    comparison turns them off) and another seed."""
    scene = load_scene(SCENE)
    over = {}
    if rocks is not None:
        over["bed.rocks"] = int(rocks)
        over["bed.radius"] = float(scene.bed.radius) * float(np.sqrt(int(rocks) / scene.bed.rocks)) if rocks else 1.0
    if not truck_splash:
        over[f"vehicle[{scene.vehicle_index(TRUCK)}].splash"] = False
    if seed is not None:
        over["seed"] = int(seed)
    return scene_with(scene, over) if over else scene


def truck_path(scene):
    """The truck's scripted path (motion/paths.py), to sample where the road runs."""
    data = scene.vehicles[scene.vehicle_index(TRUCK)].path.model_dump()
    return path_from_spec(data.pop("kind"), **data)


def road_centre(scene, spacing: float = 2.0) -> np.ndarray:
    """(K, 2) world m: the truck's path once round its loop, a point every ``spacing`` m."""
    path = truck_path(scene)
    speed = float(scene.vehicles[scene.vehicle_index(TRUCK)].path.speed)
    times = np.arange(0.0, path.duration, spacing / speed)
    return np.array([path.pose(t).position for t in times])
