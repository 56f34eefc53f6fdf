"""``taichi-rocks export``: what an exported frame holds, made from the engine's state of the frame (the writers
of output/formats.py get it; app/export.py runs the frames).

What goes in: ``only="all"`` every rock; ``only="flying"`` the rocks in the air or sliding plus those that
moved since the previous frame (landed, recycled); the resting rest of the bed is left out. ``crop=R`` keeps
the rocks within R metres (horizontally) of the camera's followed vehicle. Ids, tumble and wheel spin:
output/instances.py. The camera: motion/camera.py's scene_camera, the renderer's own ([camera] view, offset,
look_ahead, fov, smoothing and the [[camera.shot]] cuts) computed here from the scene, since output/ does not
import render/; ``cut``: a shot starts at this frame (the writer holds the camera of the shot before up to it).
Colours (output/looks.py): each rock's tint (the renderer's resting colour of it) and the entry of the tint
palette nearest to it.
"""

from __future__ import annotations

import numpy as np

from ..motion.camera import scene_camera
from .instances import RockTracker, VehicleTracker
from .looks import nearest_tint, rock_tints, tint_palette
from .runs import crop_mask, crop_vehicle

__all__ = ["ExportFrames"]


class ExportFrames:
    """The frames of one export, in order: :meth:`frame` turns frame f's state into the dict of
    output/formats.py."""

    def __init__(self, scene, n_rocks: int, fps: float, only: str, crop):
        self.camera = scene_camera(scene)  # the renderer's camera: the same shots in the stage
        self.rocks = RockTracker(n_rocks, scene.world.gravity, fps)
        self.vehicles = VehicleTracker(scene.vehicles)
        self.only, self.crop, self.crop_around = only, crop, crop_vehicle(scene)
        self.tints = rock_tints(np.arange(int(n_rocks)))  # the renderer's colour of each rock (output/looks.py)
        self.palette = tint_palette()
        self.tint = nearest_tint(self.tints, self.palette)

    def frame(self, f: int, st: dict, origin) -> dict:
        """Frame ``f``: ``st`` = ``Simulation.state()`` at f / fps, ``origin`` the engine's floating origin."""
        origin = np.asarray(origin, np.float64)
        r = self.rocks.update(st)
        keep = crop_mask(st, self.crop_around, self.crop)
        if self.only == "flying":
            keep &= r["active"]
        idx = np.flatnonzero(keep)
        world = st["positions"][idx]
        v = self.vehicles.update(st["vehicle_positions"], st["vehicle_headings"])
        cam, t = self.camera, float(st["time"])
        cut = cam.t is not None and cam.index_at(cam.t) != cam.index_at(t)
        eye_target = cam.update(st["vehicle_positions"], st["vehicle_headings"], t)[:2]
        return {"frame": f, "time": float(st["time"]), "origin": origin, "world": world,
                "local": (world - origin).astype(np.float32), "velocities": st["velocities"][idx],
                "radii": st["radii"][idx], "ids": r["ids"][idx], "proto": r["proto"][idx],
                "orientations": r["orientations"][idx], "tints": self.tints[idx], "tint": self.tint[idx],
                "angular_velocities": r["angular_velocities"][idx], "vehicles": v, "camera": eye_target,
                "cut": cut, "state": st}
