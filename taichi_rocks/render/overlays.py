"""Debug overlays drawn as GGUI lines: the bed's edge (``render.bed_edge``), the rear tires' rays
(``render.tire_rays``) and the spatial-hash cells the tires queried (``render.hash_cells``)."""

import numpy as np
import taichi as ti

from .looks import BED_EDGE_COLOR, CELL_COLOR, RAY_COLOR

__all__ = ["MAX_RAYS", "MAX_CELLS", "Overlays"]

MAX_RAYS = 256
MAX_CELLS = 4096
LIFT = 0.02  # m: the bed's edge is drawn this high above the ground
_RING = 128  # segments of the bed's edge


class Overlays:
    """The line buffers of the overlays ``flags`` (bed_edge, tire_rays, hash_cells) asks for."""

    def __init__(self, flags):
        self._bed_lines = self._ray_lines = self._cell_lines = None
        if flags.bed_edge:
            self._bed_lines = ti.Vector.field(3, ti.f32, 2 * _RING)
        if flags.tire_rays:
            self._ray_lines = ti.Vector.field(3, ti.f32, 2 * MAX_RAYS)
        if flags.hash_cells:
            self._cell_lines = ti.Vector.field(3, ti.f32, 24 * MAX_CELLS)

    def draw(self, scene, sim, origin, ground_z: float) -> None:
        """Declare the overlays of ``sim``'s current state in ``scene`` (origin: the local frame's, world)."""
        if self._bed_lines is not None:
            self._bed_edge(scene, sim, origin, ground_z)
        if self._ray_lines is not None:
            self._tire_rays(scene, sim, origin)
        if self._cell_lines is not None:
            self._hash_cells(scene, sim)

    def _bed_edge(self, scene, sim, origin, ground_z: float) -> None:
        c = np.asarray(sim.bed_center, np.float64) - origin
        th = np.linspace(0, 2 * np.pi, _RING + 1)
        rad = float(sim.scene.bed.radius)
        ring = np.stack([c[0] + rad * np.cos(th), c[1] + rad * np.sin(th),
                         np.full(_RING + 1, ground_z - origin[2] + LIFT)], 1)
        self._bed_lines.from_numpy(np.stack([ring[:-1], ring[1:]], 1).reshape(-1, 3).astype(np.float32))
        scene.lines(self._bed_lines, 3.0, color=BED_EDGE_COLOR)

    def _tire_rays(self, scene, sim, origin) -> None:
        rays = np.asarray(sim.tire_rays(), np.float64).reshape(-1, 2, 3)[:MAX_RAYS]
        if len(rays):
            buf = np.zeros((2 * MAX_RAYS, 3), np.float32)
            buf[:2 * len(rays)] = (rays - origin).reshape(-1, 3)
            self._ray_lines.from_numpy(buf)
            scene.lines(self._ray_lines, 4.0, color=RAY_COLOR, vertex_count=2 * len(rays))

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
            self._cell_lines.from_numpy(buf)
            scene.lines(self._cell_lines, 1.5, color=CELL_COLOR, vertex_count=24 * len(cells))
