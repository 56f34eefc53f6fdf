"""A renderer's settings and views, host side: its options (from the arguments or the scene's [render] table) and
the camera it frames the scene with (the scene's shots or one view preset: motion/camera.py), with its lens and
the sun.

The lens of a vertical field of view ``fov`` on W x H pixels: half-extents of the image plane at 1 m depth
tan_y = tan(fov / 2), tan_x = tan_y W / H, and pixels per radian (per metre at 1 m) H / (2 tan_y)
(render/camera.py ``Lens``). What the kernels take of it is :func:`frustum` and :func:`camera_basis`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import taichi as ti

from ..config.resolution import check_resolution
from ..motion.camera import view_of
from . import kernels as K
from .camera import NEAR, Lens, View, look_at_time, scene_camera, sun_direction
from .looks import horizon_color, rgb

__all__ = ["DEFAULT_LOD_PIXELS", "ROCK_MODES", "WINDOW_EVERY", "SHOTS", "Settings", "Views",
           "check_rocks", "camera_basis", "vec"]

DEFAULT_LOD_PIXELS = 0.7  # resting rocks whose projected radius is below this many pixels are thinned
ROCK_MODES = ("splat", "particles")
WINDOW_EVERY = 100  # frames between window re-creations (lavapipe leaks ~0.3 MB per captured frame)
SHOTS = "shots"  # the name of the scene's own camera when it has [[camera.shot]] tables (set_view)


def check_rocks(rocks: str) -> str:
    """The rock drawing mode, or ValueError."""
    if rocks not in ROCK_MODES:
        raise ValueError(f"rocks must be one of {', '.join(ROCK_MODES)}, got {rocks!r}")
    return rocks


def vec(a):
    """A Taichi vector of the floats of ``a`` (a kernel argument)."""
    return ti.Vector([float(x) for x in a])


def camera_basis(eye, fwd, right, up) -> K.CameraBasis:
    """The camera as the kernels see it (:class:`.kernels.CameraBasis`)."""
    return K.CameraBasis(eye=vec(eye), fwd=vec(fwd), right=vec(right), up=vec(up))


@dataclass
class Settings:
    """A renderer's options (see :class:`.renderer.Renderer`): ``resolution`` (even sides), ``fps``, the sky's
    colours (``background``, ``horizon``), ``draw_distance`` (m), the ground's ``tile`` (m), the ``rocks`` mode,
    ``lod_pixels``, ``window_every`` (frames), ``shadows`` and the overlays' ``flags`` (they may change between
    frames)."""

    resolution: tuple
    fps: float
    background: tuple
    horizon: tuple
    draw_distance: float
    tile: float
    rocks: str
    lod_pixels: float
    window_every: int
    shadows: bool
    flags: SimpleNamespace

    @classmethod
    def of(cls, scene, resolution, fps, rocks, lod_pixels, window_every, shadows) -> Settings:
        """The options given, the scene's [render] table's where None; ValueError on a bad one."""
        rs = scene.render
        resolution = check_resolution(resolution if resolution is not None else rs.resolution)
        fps_ = float(fps if fps is not None else rs.fps)
        if not fps_ > 0:
            raise ValueError(f"fps must be > 0, got {fps!r}")
        background = rgb(rs.background)
        flags = SimpleNamespace(bed_edge=bool(rs.bed_edge), tire_rays=bool(rs.tire_rays),
                                hash_cells=bool(rs.hash_cells), tread_patch=False)
        return cls(resolution, fps_, background, horizon_color(background), float(rs.draw_distance),
                   float(rs.ground_tile), check_rocks(rocks), float(lod_pixels), int(window_every),
                   bool(rs.shadows if shadows is None else shadows), flags)

    def wireframe(self) -> bool:
        """Vehicles are drawn as wireframes while an overlay of what is under them is on: the tire rays, the
        hash cells, the tread patches (which lie inside the tires: a solid tire hides them entirely)."""
        f = self.flags
        return bool(f.tire_rays or f.hash_cells or f.tread_patch)


class Views:
    """The camera a renderer frames the scene with: the scene's own (its shots, motion/camera.py) or a view
    preset (:meth:`set_view`), its lens for ``resolution`` and the scene's field of view, and the sun. ``rig``
    (the camera: its state carries over frames and window re-creations) and ``view_name`` (the preset's name,
    or SHOTS)."""

    def __init__(self, scene, resolution):
        self.rig = scene_camera(scene)
        self.view_name = SHOTS if scene.camera.shots else scene.camera.view
        self.fov = float(scene.camera.fov)
        self.tan_x, self.tan_y, self.px_per_rad = Lens.of(self.fov, *resolution)
        self.ground_z = float(scene.world.ground_z)
        self.sun = (scene.render.sun, scene.render.sun_frame)

    def set_view(self, scene, name: str) -> None:
        """Frame ``scene`` with another view preset, or with its own camera and its shots (``SHOTS``)."""
        self.rig = scene_camera(scene, None if name == SHOTS else name)
        self.view_name = name

    def inside_needed(self) -> set:
        """The vehicles a shot of the camera looks out of (a view from inside a cabin, motion/camera.py
        VIEW_TABLE ``inside``): their interiors are drawn."""
        return {s.rides for s in self.rig.shots if view_of(s.view).inside}

    def inside_now(self):
        """The vehicle whose cabin the shot of the last update looks out of, or None."""
        shot = self.rig.shot
        return shot.rides if view_of(shot.view).inside else None

    def view(self, sim) -> View:
        """Advance the camera to ``sim.time``; the view in local f32 coordinates."""
        return look_at_time(self.rig, sim.vehicle_poses(), sim.time, sim.origin)

    def sun_direction(self, heading: float) -> np.ndarray:
        """Unit vector towards the sun (:func:`.camera.sun_direction`; ``heading``: the rig's)."""
        return sun_direction(heading, *self.sun)

    def frustum(self, draw_distance: float) -> K.Frustum:
        """The view volume as the kernels see it (:class:`.kernels.Frustum`), out to ``draw_distance`` (m)."""
        return K.Frustum(tan_x=self.tan_x, tan_y=self.tan_y, sec_x=math.sqrt(1 + self.tan_x ** 2),
                         sec_y=math.sqrt(1 + self.tan_y ** 2), near=NEAR, far=draw_distance,
                         px_per_rad=self.px_per_rad)
