"""Debug overlays drawn as GGUI lines: the bed's edge (``render.bed_edge``), the rear tires' rays
(``render.tire_rays``), the spatial-hash cells the tires queried (``render.hash_cells``) and the rear tires'
contact patches on the ground (``tread_patch``: a rectangle of tire_width x contact_length under each
splashing rear tire, turned with the vehicle; the view's overlay).

The flags may change between frames (the view's check boxes): a line buffer is allocated the first time its
overlay is drawn."""

import numpy as np
import taichi as ti

from ..engine.trees import FieldTrees
from .looks import BED_EDGE_COLOR, CELL_COLOR, PATCH_COLOR, RAY_COLOR

__all__ = ["MAX_RAYS", "MAX_CELLS", "Overlays"]

MAX_RAYS = 256
MAX_CELLS = 4096
LIFT = 0.02  # m: the bed's edge and the contact patches are drawn this high above the ground
_RING = 128  # segments of the bed's edge
_SIZES = {"bed_edge": 2 * _RING, "tire_rays": 2 * MAX_RAYS, "hash_cells": 24 * MAX_CELLS,
          "tread_patch": 8 * MAX_RAYS}


class Overlays:
    """The line buffers of the overlays ``flags`` (bed_edge, tire_rays, hash_cells, tread_patch) asks for."""

    def __init__(self, flags, trees: FieldTrees = None):
        self.flags = flags
        self._trees = FieldTrees.given(trees, self)
        self._lines = {}
        for name in _SIZES:
            if getattr(flags, name, False):
                self._buffer(name)

    def _buffer(self, name: str):
        if name not in self._lines:
            self._lines[name] = self._trees.vector(3, ti.f32, _SIZES[name])
        return self._lines[name]

    def draw(self, scene, sim, origin, ground_z: float) -> None:
        """Declare the overlays of ``sim``'s current state in ``scene`` (origin: the local frame's, world)."""
        f = self.flags
        if f.bed_edge:
            self._bed_edge(scene, sim, origin, ground_z)
        if f.tire_rays:
            self._tire_rays(scene, sim, origin)
        if f.hash_cells:
            self._hash_cells(scene, sim)
        if getattr(f, "tread_patch", False):
            self._tread_patch(scene, sim, origin)

    def _bed_edge(self, scene, sim, origin, ground_z: float) -> None:
        c = np.asarray(sim.bed_center, np.float64) - origin
        th = np.linspace(0, 2 * np.pi, _RING + 1)
        rad = float(sim.scene.bed.radius)
        ring = np.stack([c[0] + rad * np.cos(th), c[1] + rad * np.sin(th),
                         np.full(_RING + 1, ground_z - origin[2] + LIFT)], 1)
        lines = self._buffer("bed_edge")
        lines.from_numpy(np.stack([ring[:-1], ring[1:]], 1).reshape(-1, 3).astype(np.float32))
        scene.lines(lines, 3.0, color=BED_EDGE_COLOR)

    def _tire_rays(self, scene, sim, origin) -> None:
        rays = np.asarray(sim.tire_rays(), np.float64).reshape(-1, 2, 3)[:MAX_RAYS]
        if len(rays):
            buf = np.zeros((2 * MAX_RAYS, 3), np.float32)
            buf[:2 * len(rays)] = (rays - origin).reshape(-1, 3)
            lines = self._buffer("tire_rays")
            lines.from_numpy(buf)
            scene.lines(lines, 4.0, color=RAY_COLOR, vertex_count=2 * len(rays))

    def _hash_cells(self, scene, sim) -> None:
        cells = np.asarray(sim.queried_cells(), np.int64).reshape(-1, 3)[:MAX_CELLS]
        if len(cells):
            size = float(sim.cell_size)
            corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], np.float64)
            edges = np.array([(a, b) for a in range(8) for b in range(a + 1, 8)
                              if bin(a ^ b).count("1") == 1]).reshape(-1)
            pts = (cells[:, None, :].astype(np.float64) + corners[edges][None]) * size  # (K, 24, 3) local
            buf = np.zeros((24 * MAX_CELLS, 3), np.float32)
            buf[:24 * len(cells)] = pts.reshape(-1, 3)
            lines = self._buffer("hash_cells")
            lines.from_numpy(buf)
            scene.lines(lines, 1.5, color=CELL_COLOR, vertex_count=24 * len(cells))

    def _tread_patch(self, scene, sim, origin) -> None:
        tires = sim.fleet.rear_tires(sim.vehicle_poses())  # world frame
        n = min(len(tires.spin), MAX_RAYS)
        if not n:
            return
        corners = patch_corners(tires.bottom[:n], tires.forward[:n], tires.half_length[:n],
                                tires.half_width[:n]) - origin  # (n, 4, 3)
        corners[:, :, 2] += LIFT
        seg = np.stack([corners, np.roll(corners, -1, axis=1)], axis=2).reshape(-1, 3)  # 4 edges per patch
        buf = np.zeros((8 * MAX_RAYS, 3), np.float32)
        buf[:len(seg)] = seg
        lines = self._buffer("tread_patch")
        lines.from_numpy(buf)
        scene.lines(lines, 3.0, color=PATCH_COLOR, vertex_count=len(seg))


def patch_corners(bottom, forward, half_length, half_width) -> np.ndarray:
    """The four corners (n, 4, 3) of contact patches centred on ``bottom`` (n, 3), ``half_length`` along the
    unit ``forward`` (n, 2) and ``half_width`` across, in order round the rectangle."""
    f = np.zeros((len(bottom), 3))
    f[:, :2] = forward
    side = np.stack([-f[:, 1], f[:, 0], np.zeros(len(f))], 1)
    signs = np.array([(1, 1), (1, -1), (-1, -1), (-1, 1)], np.float64)
    return (np.asarray(bottom, np.float64)[:, None, :] + signs[None, :, 0:1] * (half_length[:, None, None] * f[:, None])
            + signs[None, :, 1:2] * (half_width[:, None, None] * side[:, None]))
