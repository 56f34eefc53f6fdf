"""Dust in the export ([effects] dust; config/effects/dust.py EXPORTS): an exported frame's ``dust`` is
``{"positions": (K, 3) world m, "opacity": (K,)}`` (``Simulation.effect_arrays()``); the USD writer puts it in a
``UsdGeom.Points`` prim ``/World/Bed/Dust`` (under the bed's Xform, which carries the floating origin: points in
its local frame, f32), ``widths`` the particle's drawn diameter and the ``displayOpacity`` primvar its opacity,
``displayColor`` the dust colour. Particles are not tracked from frame to frame (no ids): each time code holds
that frame's particles. The PLY writer (output/ply.py) writes each frame's particles beside its rocks, as
``dust_00000.ply``: vertices of :data:`DUST_VERTEX` from :func:`dust_rows` (world metres in doubles, the width and
the opacity as in the USD).
"""

from __future__ import annotations

import numpy as np

from .looks import linear

try:  # usd-core is optional (the usd extra)
    from pxr import Sdf, UsdGeom, Vt
except ImportError:  # pragma: no cover - the USD writer refuses to start without it
    Sdf = UsdGeom = Vt = None

__all__ = ["DUST_PRIM", "DUST_VERTEX", "dust_rows", "dust_widths", "write_dust"]

DUST_PRIM = "/World/Bed/Dust"
DUST_VERTEX = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("width", "<f4"), ("opacity", "<f4")])


def dust_widths(alpha, table) -> np.ndarray:
    """The drawn diameter (m, f32) of particles of opacity ``alpha``: 2 size (0.4 + 0.6 alpha), as the viewer's
    particles (render/dust.py ``dust_looks``)."""
    return (2.0 * table.size * (0.4 + 0.6 * np.asarray(alpha, np.float32))).astype(np.float32)


def dust_rows(dust: dict, table) -> np.ndarray:
    """A frame's particles as PLY vertices (:data:`DUST_VERTEX`): world positions, widths, opacities."""
    pos = np.asarray(dust["positions"], np.float64).reshape(-1, 3)
    rows = np.empty(len(pos), DUST_VERTEX)
    for axis, key in enumerate("xyz"):
        rows[key] = pos[:, axis]
    rows["opacity"] = np.asarray(dust["opacity"], np.float32).reshape(-1)
    rows["width"] = dust_widths(rows["opacity"], table)
    return rows


def write_dust(stage, attrs, dust: dict, origin, t: float, table) -> dict:
    """Frame ``t``'s dust samples on ``stage`` (``attrs``: the prim's attributes from the frame before, None the
    first time); returns them for the next frame."""
    if attrs is None:
        pts = UsdGeom.Points.Define(stage, DUST_PRIM)
        api = UsdGeom.PrimvarsAPI(pts)
        color = api.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.constant)
        color.Set(Vt.Vec3fArray.FromNumpy(np.asarray([linear(table.color)], np.float32)))
        attrs = {"points": pts.CreatePointsAttr(), "widths": pts.CreateWidthsAttr(),
                 "opacity": api.CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex)}
    local = (np.asarray(dust["positions"], np.float64).reshape(-1, 3) - np.asarray(origin, np.float64))
    alpha = np.array(dust["opacity"], np.float32, copy=True).reshape(-1)
    attrs["points"].Set(Vt.Vec3fArray.FromNumpy(local.astype(np.float32)), t)
    attrs["widths"].Set(Vt.FloatArray.FromNumpy(dust_widths(alpha, table)), t)
    attrs["opacity"].Set(Vt.FloatArray.FromNumpy(alpha), t)
    return attrs
