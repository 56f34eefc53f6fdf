"""Setting a simulation up from a Scene: the derived physics constants and parameter packing.

Drag of a sphere of radius r and density rho in air (viscosity mu_air, density rho_air, drag coefficient C_d):
    Stokes (linear):  a = -(9 mu_air / (2 rho r^2)) v        -> LINEAR_DRAG = 4.5 mu_air / rho   (a = -k v / r^2)
    quadratic:        a = -(3 rho_air C_d / (8 rho r)) |v| v -> QUAD_DRAG = 3 rho_air C_d / (8 rho) (a = -k |v| v / r)
"""

from __future__ import annotations


def drag_coefficients(scene) -> tuple[float, float]:
    """(LINEAR_DRAG, QUAD_DRAG) of the scene's rocks; see the module docstring. The one place they are derived."""
    wd, bed = scene.world, scene.bed
    return 4.5 * wd.air_viscosity / bed.density, 3.0 * wd.air_density * bed.drag_coefficient / (8.0 * bed.density)
