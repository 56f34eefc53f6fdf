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

from dataclasses import dataclass

import numpy as np

from ..config.records import Record, entry
from ..motion.camera import scene_camera
from .instances import RockTracker, VehicleTracker
from .looks import nearest_tint, rock_tints, tint_palette
from .runs import crop_mask, crop_vehicle

__all__ = ["ExportFrames", "ExportFrame"]


@dataclass(kw_only=True, eq=False)
class ExportFrame(Record):
    """One exported frame, what every writer of output/formats.py gets: M rocks chosen (``--only``, ``--crop``),
    V vehicles."""

    frame: int = entry("", "the frame's index")
    time: float = entry("s", "the simulation's clock at the frame")
    origin: np.ndarray = entry("m", "(3,) float64: the engine's floating origin, world coordinates")
    world: np.ndarray = entry("m", "(M, 3) float64: each rock's centre, world coordinates")
    local: np.ndarray = entry("m", "(M, 3) float32: world - origin")
    velocities: np.ndarray = entry("m/s", "(M, 3): each rock's velocity")
    radii: np.ndarray = entry("m", "(M,): each rock's radius")
    ids: np.ndarray = entry("", "(M,) int64: the instance's id (a new one after each recycle: output/instances.py)")
    proto: np.ndarray = entry("", "(M,): the rock's shape, an index of the prototypes")
    orientations: np.ndarray = entry("-", "(M, 4): unit quaternions (x, y, z, w)")
    tints: np.ndarray = entry("-", "(M, 3): the renderer's resting colour of each rock (RGB)")
    tint: np.ndarray = entry("", "(M,): the nearest entry of the stage's tint palette (output/looks.py)")
    angular_velocities: np.ndarray = entry("rad/s", "(M, 3): each rock's spin")
    vehicles: dict = entry("", "positions (V, 3) m, unwrapped headings (V,) rad, wheel angles front and rear "
                               "(V,) rad")
    camera: tuple = entry("m", "(eye, target): the scene camera's points, world coordinates")
    cut: bool = entry("-", "a shot of the camera starts at this frame")
    state: Record = entry("", "the engine's whole state of the frame (Simulation.state(): engine/records.py)")
    impacts: dict = entry("", "with impacts, the frame's hit events: events, world points and normals "
                              "(app/export.py impact_frame)", optional=True)
    effects: dict = entry("", "the optional effects' arrays by their export names (config/effects/: dust), "
                              "entries of the dict", optional=True)

    _holder = "effects"


class ExportFrames:
    """The frames of one export, in order: :meth:`frame` turns frame f's state into an :class:`ExportFrame`."""

    def __init__(self, scene, n_rocks: int, fps: float, only: str, crop):
        self.camera = scene_camera(scene)  # the renderer's camera: the same shots in the stage
        self.rocks = RockTracker(n_rocks, scene.world.gravity, fps)
        self.vehicles = VehicleTracker(scene.vehicles)
        self.only, self.crop, self.crop_around = only, crop, crop_vehicle(scene)
        self.tints = rock_tints(np.arange(int(n_rocks)))  # the renderer's colour of each rock (output/looks.py)
        self.palette = tint_palette()
        self.tint = nearest_tint(self.tints, self.palette)

    def frame(self, f: int, st, origin) -> ExportFrame:
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
        return ExportFrame(frame=f, time=float(st["time"]), origin=origin, world=world,
                           local=(world - origin).astype(np.float32), velocities=st["velocities"][idx],
                           radii=st["radii"][idx], ids=r["ids"][idx], proto=r["proto"][idx],
                           orientations=r["orientations"][idx], tints=self.tints[idx], tint=self.tint[idx],
                           angular_velocities=r["angular_velocities"][idx], vehicles=v, camera=eye_target, cut=cut,
                           state=st)
