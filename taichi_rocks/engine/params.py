"""The kernels' parameters: every number of ``World.par`` and ``World.ipar``, declared once.

Each row of :data:`TABLE` (``World.par``, in the World's precision) and :data:`INT_TABLE` (``World.ipar``,
int32) is a parameter: its name (``Par.NAME``, its index, is its place in the table; a [min, max] pair takes
two), where its value comes from (a dotted scene key times the factor from the scene's unit to the kernels',
or a derivation from the scene), and whether the view's panel may change it while the simulation runs
(``runtime``: True, or a :class:`Slider` with the slider's label and range in scene units, which must lie
within the key's range in the scene schema). Everything else comes from the table:

* ``Par`` and ``IPar``: the indices the kernels read (``w.par[Par.GRAVITY]``);
* the packing of a scene (engine/setup.py ``scene_params``) and of explicit values (:func:`pack`, tests);
* :data:`RUNTIME_KEYS` (engine/tuning.py: what ``set_runtime`` may change, and how ``runtime_values`` reads
  it back) and :data:`SLIDERS` (render/panel.py: the sliders, in table order).

A new runtime parameter is one row here plus the physics that reads it.

Derived constants (the scene's units are SI):
    LINEAR_DRAG = 9 mu_air / (2 rho)          Stokes drag of a sphere: a = -LINEAR_DRAG / r^2 v
    QUAD_DRAG   = 3 rho_air C_d / (8 rho)     quadratic drag: a = -QUAD_DRAG / r |v| v
    GROUND_Z    the ground's height in the kernels' local frame (ground_z - the origin's z)
    CELL        the hash cell edge (config/plan.py ``cell_size``); MARGIN the reach of a tire's query beyond
                its ray (engine/setup.py ``tire_reach``); DILATE the cells a centre-insert query is dilated by
    PATCH_TOL   1e-4 m + 64 f32 spacings at the ground's height: a resting rock's bottom is the ground up to
                rounding
    MASS_PER_R3 4/3 pi rho: a stone's mass is MASS_PER_R3 r^3 (from the host: a float literal in a kernel is
                float32 even in a float64 run)
    CHIP, CRACK the damage thresholds in the unit of [impacts] damage_by (J or N s); DAMAGE_MOMENTUM 1 when
                that is the normal momentum, 0 for the normal energy
    CONTACT_SLOP how far beyond its radius a stone is put from the body it hit: 4 spacings of the precision
                at 256 m + R, the reach of the kernels' coordinates (the floating origin stays within 2 x
                128 m of the bed), so that rounding the body frame back to the local one leaves it outside
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Optional, Union

import numpy as np

from ..config.keys import scene_value

__all__ = ["Param", "Slider", "Source", "TABLE", "INT_TABLE", "Par", "IPar", "RUNTIME_KEYS", "SLIDERS", "pack",
           "drag_coefficients", "dilation_cells"]

DEG = math.pi / 180.0  # the scene's degrees to the kernels' radians


@dataclass(frozen=True)
class Slider:
    """A slider of the view's panel: its label and range (scene units)."""

    label: str
    lo: float
    hi: float


@dataclass(frozen=True)
class Source:
    """What a parameter's value is derived from: the scene, its Plan, its hash sizing (engine/setup.py
    ``HashSizing``) and the ground's height in the kernels' local frame."""

    scene: Any
    plan: Any
    sizing: Any
    ground_z: float


@dataclass(frozen=True)
class Param:
    """One row of the table: ``names`` (one index each), and either ``key`` (a dotted scene key; the value is
    the key's times ``factor``) or ``derive`` (Source -> value); ``runtime``: False, True (``set_runtime``
    may change it) or a Slider (and the panel shows it)."""

    names: Union[str, tuple]
    key: Optional[str] = None
    factor: float = 1.0
    derive: Optional[Callable[[Source], Any]] = None
    runtime: Union[bool, Slider] = False
    what: str = ""

    def __post_init__(self):
        if isinstance(self.names, str):
            object.__setattr__(self, "names", (self.names,))
        if (self.key is None) == (self.derive is None):
            raise ValueError(f"parameter {self.names}: give a scene key or a derivation, not both")
        if self.runtime and self.key is None:
            raise ValueError(f"parameter {self.names}: only a scene key can change at run time")

    def value(self, src: Source) -> np.ndarray:
        """The value(s) of this row in the kernels' units, float64, one per name."""
        v = scene_value(src.scene, self.key) if self.key is not None else self.derive(src)
        out = np.asarray(v, np.float64).reshape(-1)
        if self.factor != 1.0:
            out = out * self.factor
        if len(out) != len(self.names):
            raise ValueError(f"parameter {self.names}: {len(out)} values for {len(self.names)} names")
        return out


def drag_coefficients(scene) -> tuple[float, float]:
    """(LINEAR_DRAG, QUAD_DRAG) of the scene's rocks; see the module docstring."""
    wd, bed = scene.world, scene.bed
    return 4.5 * wd.air_viscosity / bed.density, 3.0 * wd.air_density * bed.drag_coefficient / (8.0 * bed.density)


def dilation_cells(r_max: float, cell: float) -> int:
    """Cells to dilate a centre-insert query by: a rock whose centre is within r_max of a point lies in a
    cell at most floor(r_max / cell) + 1 away per axis (the + 1 covers floor() on both sides and
    rounding when r_max / cell is an integer)."""
    return int(math.floor(r_max / cell * (1.0 + 1e-6))) + 1 if r_max > 0 else 1


def _patch_tolerance(src: Source) -> float:
    return 1e-4 + 64.0 * float(np.finfo(np.float32).eps) * abs(src.scene.world.ground_z)


def _contact_slop(src: Source) -> float:
    eps = float(np.finfo(np.float64 if src.scene.sim.precision == "f64" else np.float32).eps)
    return 4.0 * eps * (256.0 + src.scene.bed.radius)


def _dilate(src: Source) -> int:
    return dilation_cells(float(src.scene.bed.rock_radius[1]), src.plan.cell_size) if src.plan.center else 0


# World.par. The rows with sliders come in the order the panel shows them.
TABLE = (
    Param("WETNESS", "world.wetness", runtime=Slider("wetness", 0.0, 1.0), what="ground wetness (the tread model)"),
    Param("GRAVITY", "world.gravity", runtime=Slider("gravity", 0.0, 20.0), what="m/s^2"),
    Param(("ANGLE_MIN", "ANGLE_MAX"), "launch.release_angle", DEG, runtime=Slider("angle", 0.0, 90.0),
          what="rad: the uniform model's release angles ('angle min', 'angle max')"),
    Param("SPREAD", "launch.spread", DEG, runtime=Slider("spread", 0.0, 90.0), what="rad: lateral scatter"),
    Param("GROOVE", "launch.groove", runtime=True, what="m: the stone size the tread's grooves hold"),
    Param("GRIP", "launch.grip", runtime=Slider("grip", 0.0, 1.0e6), what="Pa: clamp stress"),
    Param("GRIP_RELAX", "launch.grip_relax", DEG, runtime=True, what="rad: relaxation angle of the clamp"),
    Param("GRIP_SPREAD", "launch.grip_spread", runtime=True, what="log-spread of the clamp"),
    Param("ADHESION", "launch.adhesion", runtime=Slider("adhesion", 0.0, 2.0e5), what="Pa: a soaked film's"),
    Param("TRANSFER", "launch.transfer", runtime=Slider("transfer", 0.0, 2.0), what="launch velocity factor"),
    Param("RESTITUTION", "world.restitution", runtime=Slider("bounce", 0.0, 1.0), what="ground bounce"),
    Param("GROUND_FRICTION", "world.ground_friction", runtime=Slider("friction", 0.0, 2.0), what="rock-ground"),
    Param("REST_SPEED", "world.rest_speed", runtime=True, what="m/s: slower on the ground is at rest"),
    Param("DENSITY", "bed.density", what="kg/m^3: the rocks' (the tread model's centrifugal pull)"),
    Param("BED_RADIUS", "bed.radius", what="m"),
    Param("R_MAX", derive=lambda s: s.scene.bed.rock_radius[1], what="m: the largest rock radius"),
    Param("GROUND_Z", derive=lambda s: s.ground_z, what="m: the ground's height in the local frame"),
    Param("CELL", derive=lambda s: s.plan.cell_size, what="m: the hash cell edge"),
    Param(("LINEAR_DRAG", "QUAD_DRAG"), derive=lambda s: drag_coefficients(s.scene), what="module docstring"),
    Param("TIE_EPS", derive=lambda s: 1e-5, what="relative tie tolerance of the geometric tests"),
    Param("MARGIN", derive=lambda s: s.sizing.margin, what="m: a tire query's reach beyond its ray (XY)"),
    Param("PATCH_TOL", derive=_patch_tolerance, what="m: how far above the tire's bottom a run-over rock's "
                                                     "bottom may be"),
    # impacts (engine/impact_pass.py): stones against the vehicles' bodies
    Param("BODY_RESTITUTION", "impacts.restitution", runtime=True, what="normal restitution of a stone on a body"),
    Param("BODY_FRICTION", "impacts.friction", runtime=True, what="Coulomb friction of a stone on a body"),
    Param("MIN_SPEED", "impacts.min_speed", runtime=True, what="m/s: slower contacts are not recorded"),
    Param(("CHIP", "CRACK"), derive=lambda s: s.scene.impacts.thresholds(), what="damage thresholds (docstring)"),
    Param("DAMAGE_MOMENTUM", derive=lambda s: float(s.scene.impacts.damage_by == "momentum"),
          what="1: damage classes by normal momentum, 0: by normal energy"),
    Param("MASS_PER_R3", derive=lambda s: 4.0 / 3.0 * math.pi * s.scene.bed.density, what="kg/m^3 (docstring)"),
    Param("CONTACT_SLOP", derive=_contact_slop, what="m (docstring)"),
    Param("SPIN_SPREAD", "launch.spin_spread", runtime=True, what="a launched stone's spin scatter, a share of "
                                                                  "its rolling spin (engine/tumble.py)"),
)

# World.ipar (int32).
INT_TABLE = (
    Param("SEED", derive=lambda s: s.scene.seed & 0x7FFFFFFF, what="the random streams' seed"),
    Param("DILATE", derive=_dilate, what="cells a centre-insert query is dilated by (0: AABB insert)"),
    Param("N_ROCKS", "bed.rocks", what="rocks in the rock arrays (active stepping: the active list, kept by "
                                       "the steps)"),
    Param("TABLE", derive=lambda s: s.sizing.table, what="hash slots in use (active stepping: set by the steps)"),
)


def _index_class(name: str, table: tuple, doc: str) -> type:
    """A class whose attribute NAME is the index of NAME in ``table``, and COUNT their number."""
    names = [n for p in table for n in p.names]
    if len(set(names)) != len(names):
        raise ValueError(f"{name}: a name declared twice")
    return type(name, (), {"__doc__": doc, **{n: i for i, n in enumerate(names)}, "COUNT": len(names)})


Par = _index_class("Par", TABLE, "Indices of the physics parameters in ``World.par`` (engine/params.py TABLE).")
IPar = _index_class("IPar", INT_TABLE, "Indices of the integer parameters in ``World.ipar`` (engine/params.py "
                                       "INT_TABLE).")


def _place(p: Param, cls: type):
    """The index of a row (an int), or of a pair (a tuple)."""
    idx = tuple(getattr(cls, n) for n in p.names)
    return idx if len(idx) > 1 else idx[0]


# scene key -> (Par index, or pair of indices; factor from the scene's unit to the kernels')
RUNTIME_KEYS = {p.key: (_place(p, Par), p.factor) for p in TABLE if p.runtime}
# scene key -> (label, min, max) of the panel's sliders, in table order (a pair: "label min", "label max")
SLIDERS = {p.key: (p.runtime.label, p.runtime.lo, p.runtime.hi) for p in TABLE if isinstance(p.runtime, Slider)}


def pack_source(src: Source) -> tuple[np.ndarray, np.ndarray]:
    """``World.par`` (float64) and ``World.ipar`` (int64) of a scene, from the table."""
    par, ipar = np.zeros(Par.COUNT), np.zeros(IPar.COUNT, dtype=np.int64)
    for out, table, cls in ((par, TABLE, Par), (ipar, INT_TABLE, IPar)):
        for p in table:
            for name, v in zip(p.names, p.value(src)):
                out[getattr(cls, name)] = v
    return par, ipar


def pack(values: dict) -> tuple[np.ndarray, np.ndarray]:
    """``World.par`` and ``World.ipar`` from explicit values by name (kernels' units; others 0): kernels driven
    without a scene (tests)."""
    par, ipar = np.zeros(Par.COUNT), np.zeros(IPar.COUNT, dtype=np.int64)
    for name, v in values.items():
        if hasattr(Par, name):
            par[getattr(Par, name)] = v
        elif hasattr(IPar, name):
            ipar[getattr(IPar, name)] = v
        else:
            raise KeyError(f"no parameter {name!r} (engine/params.py)")
    return par, ipar
