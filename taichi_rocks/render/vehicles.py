"""The vehicles of a frame and the marks their hits leave, host side: one merged mesh of every vehicle's body and
wheels (render/bodies.py, render/meshes.py), posed on the host each frame (the wheels turned by the odometer:
render/wheels.py), with the windscreen's frame of a vehicle whose cabin a shot looks out of
(render/interior.py), and the impacts' flashes and marks (render/hits.py).

Why on the host: GGUI 1.7.4's ``mesh_instance`` lights the *untransformed* mesh (Mesh_vk.vert forwards the
model-space position and normal to the lighting), so a yawed vehicle would keep the shading of an unrotated
one: the vertices and normals are transformed here and drawn with one explicit identity model matrix (a plain
``scene.mesh`` now and then vanishes from a frame: see render/renderer.py). They go straight into GGUI's vertex
buffer with the colours, and the triangles drawn (from outside, or from a cabin) into its index buffer
(render/vbo.py), made once a mesh: no Taichi fields, none of the wrapper's per-frame copies.
:meth:`VehicleLayer.lost` is the safety net that finds a frame where GGUI lost the mesh anyway.
"""

from __future__ import annotations

import math

import numpy as np

from .bodies import scene_meshes
from .hits import HitLayer
from .interior import interior_of
from .looks import KEY
from .meshes import merge, pose_mesh
from .vbo import VBO_STRIDE, declare_mesh, host_buffer
from .wheels import Odometer, wheel_angles

__all__ = ["LOST_COVERAGE", "VehicleLayer"]

LOST_COVERAGE = 0.15  # a vehicle in view drawing less than this share of its screen box was lost


class VehicleLayer:
    """The vehicles of ``scene`` (and ``hits``: their flashes and marks, :class:`.hits.HitLayer`) as GGUI
    draws them. :meth:`build` makes the mesh for the cabins a camera looks out of; ``meshes`` (per vehicle: its
    mesh, with the windscreen's frame where it has an interior), ``sizes`` (their vertex counts), ``layouts``
    (the merged mesh's triangles drawn from outside, key None, and from the cabin of vehicle i, key i; int32)
    and ``frame`` (the last frame's vertices, local frame)."""

    def __init__(self, scene):
        self.hits = HitLayer(scene)
        self.identity = host_buffer((1, 4, 4), "vehicles")  # an explicit identity model matrix: see above
        self.identity[0] = np.eye(4, dtype=np.float32)

    def build(self, scene, paths, inside_needed) -> None:
        """The vehicles of ``scene`` (driving ``paths``): one merged mesh, with the windscreen's frame of the
        vehicles in ``inside_needed`` (their cabins are looked out of: :mod:`.interior`)."""
        self.specs = scene.vehicles
        self.meshes = scene_meshes(scene)
        self.interiors = {}
        for i in sorted(inside_needed):
            self.interiors[i] = interior_of(scene.vehicles[i], self.meshes[i])
            self.meshes[i] = self.interiors[i].mesh
        self.sizes = [len(m.verts) for m in self.meshes]
        _, _, cs, _ = merge([m[:4] for m in self.meshes])
        self.colours = cs.astype(np.float32)
        self.layouts = {None: self._triangles(None)}
        self.layouts.update({i: self._triangles(i) for i in self.interiors})
        self.frame = None  # this frame's vertices (local frame), for the lost-mesh check
        self.odometer = Odometer(paths)

    def covers(self, inside_needed) -> bool:
        """True if the mesh holds the interiors of every vehicle in ``inside_needed``."""
        return set(inside_needed) <= set(self.interiors)

    def _triangles(self, inside) -> np.ndarray:
        """The merged mesh's indices drawn from outside (``inside`` None) or from the cabin of vehicle
        ``inside`` (its own triangles first, nearest first: the depth test then rejects what they hide before
        GGUI shades it)."""
        out, start = [], np.cumsum([0] + self.sizes)
        for i, m in enumerate(self.meshes):
            tri = self.interiors[i].triangles(i == inside) if i in self.interiors else m.idx
            out.append(np.asarray(tri, np.int64) + start[i])
        if inside is not None:
            out.insert(0, out.pop(inside))
        return np.concatenate(out).astype(np.int32)

    def wheel_angles(self, t: float) -> list:
        """Per vehicle, its wheels' angles (rad) at time ``t``: distance driven / tire radius (rear wheels:
        times 1 + slip; :mod:`.wheels`)."""
        dist = self.odometer.at(t)
        return [wheel_angles(v, d, m.rear) for v, d, m in zip(self.specs, dist, self.meshes)]

    def posed(self, poses, origin, t: float) -> list:
        """Per vehicle, its (vertices, normals) in the local frame at time ``t`` (float64); with ``meshes``
        (triangles, owners) this is what GGUI draws."""
        return [pose_mesh(m, np.asarray(p.position, np.float64) - origin, p.heading, a)
                for m, p, a in zip(self.meshes, poses, self.wheel_angles(t))]

    def declare(self, scene, poses, origin, t: float, inside, wireframe: bool) -> None:
        """Declare the vehicles at ``poses`` (time ``t``) in GGUI ``scene``, seen from the cabin of vehicle
        ``inside`` (or None: from outside), as wireframes if ``wireframe``."""
        posed = self.posed(poses, origin, t)
        out_v = np.concatenate([v for v, _ in posed])
        self.frame = out_v
        vbo = host_buffer((len(out_v), VBO_STRIDE), "vehicles")
        vbo[:, :3] = out_v
        vbo[:, 3:6] = np.concatenate([n for _, n in posed])
        vbo[:, 8:11] = self.colours
        vbo[:, 11] = 1.0
        tri = self.layouts[inside]
        idx = host_buffer((len(tri),), "vehicles", np.int32)
        idx[:] = tri
        declare_mesh(scene, vbo, self.identity, idx, wireframe)

    def lost(self, raw, eye, fwd, right, up, views, settings) -> bool:
        """True if a vehicle in full view (in front of the camera, its screen box at least 3 x 3 pixels and
        inside the image) has almost no pixel drawn by GGUI inside its screen box in ``raw`` (GGUI's read-back):
        its mesh was lost. (A vehicle covers most of its box; flying rocks in front of it only a few pixels:
        below LOST_COVERAGE of the box counts as lost.)"""
        if self.frame is None or settings.wireframe():  # see-through: nothing to measure
            return False
        W, H = settings.resolution
        key = np.array(KEY, np.float32) / 255.0
        start = 0
        for nv in self.sizes:
            d = self.frame[start:start + nv].astype(np.float64) - eye
            start += nv
            z = d @ fwd
            if z.min() < 0.5 or z.min() > settings.draw_distance:
                continue
            sx = (d @ right / (z * views.tan_x) + 1.0) * 0.5 * W
            sy = (d @ up / (z * views.tan_y) + 1.0) * 0.5 * H  # rows of the read-back: 0 = bottom
            x0, x1, y0, y1 = (int(math.floor(v)) for v in (sx.min(), sx.max(), sy.min(), sy.max()))
            if x0 < 0 or y0 < 0 or x1 >= W or y1 >= H or x1 - x0 < 3 or y1 - y0 < 3:
                continue
            box = raw[x0 + 1:x1, y0 + 1:y1, :3]
            drawn = np.any(np.abs(box - key) >= 0.5 / 255.0, axis=2)
            if drawn.mean() < LOST_COVERAGE:
                return True
        return False
