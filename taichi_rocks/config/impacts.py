"""The scene's [impacts] table: how flying stones respond to the vehicle bodies they hit, and the damage classes
of the recorded hits (no Taichi, no NumPy).

Response (engine/impacts.py): the normal part of the stone's velocity relative to the body's contact point
reflects with ``restitution``; the tangential part loses a Coulomb impulse ``friction`` (1 + e) |u_n|. Defaults:
e = 0.5 and mu = 0.3, tunables. Spheres bouncing off plates lose more of their normal energy the thinner the
plate is (Sondergaard, Chaney & Brennen 1990, "Measurements of solid spheres bouncing off flat plates", ASME J.
Appl. Mech. 57, 694-699); a body's panels and glass are thin plates, so e sits well below the ~0.9 of a stone
on a thick steel block. mu = 0.3: a rough stone sliding on glass or paint.

Damage classes from the hit's normal component, by normal kinetic energy 1/2 m u_n^2 (``damage_by = "energy"``)
or normal momentum m |u_n| (``"momentum"``, the measure of Gruen, Schoenberger & Schulz, FISITA 2010,
F2010-C-098): "mark" below the chip threshold, "chip" below the crack threshold, "crack" above. The defaults
are proxies, not measured thresholds of stones on windscreens:
  * Ball & McKenzie 1994 ("On the low velocity impact behaviour of glass plates", J. Phys. IV 04, C8-783): a
    3 mm hardened steel ball (0.111 g) at 10-50 m/s (5.5 mJ-0.14 J; 1.1e-3-5.5e-3 N s) on float glass plates
    of 3-12 mm fractures them, from Hertzian ring and cone cracks to crushed zones with median, radial and
    lateral cracks and, in some cases, star cracks from the rear face. The defaults put "chip" (a cone crack,
    a windscreen's bullseye) at the low end of that range and "crack" at its high end.
  * SAE J400 (chip resistance of coatings): water-worn gravel of 9.5-16 mm, 1.2-5.7 g, which at 30 m/s carries
    0.5-2.6 J, chips paint. Such a stone hitting square on classes as "crack" here: the classes are scaled for
    glass, and on painted parts they are a coarser proxy.
A stone is softer and lighter than steel: at equal energy it loads the glass less (Hertz: the peak force grows
with the stiffness of both bodies), so these thresholds err towards damage.

Recorded: a contact closing faster than ``min_speed`` (normal relative speed). Slower contacts still bounce the
stone but are not events: a stone resting or sliding on a bonnet touches it every step at about g dt.
Events wait on the device between drains in a buffer of ``capacity`` events ("auto": sized from the scene,
engine/impact_pass.py ``event_capacity``); more are counted as dropped, never lost silently.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .values import Float, TableSize, _raise_problems, _Table

__all__ = ["DAMAGE_CLASSES", "DAMAGE_MEASURES", "Impacts"]

DAMAGE_CLASSES = ("mark", "chip", "crack")
DAMAGE_MEASURES = ("energy", "momentum")


class Impacts(_Table):
    """How flying stones bounce off the vehicles' bodies, and the damage classes of their hits."""

    restitution: Float = Field(0.5, description="normal restitution of a stone on a body, in [0, 1]", ge=0, le=1)
    friction: Float = Field(0.3, description="Coulomb friction of a stone on a body (tangential impulse <= "
                                             "friction x normal impulse)", ge=0)
    damage_by: Literal[DAMAGE_MEASURES] = Field("energy", description="damage classes by the normal kinetic "
                                                                      "energy or the normal momentum of a hit")
    chip_energy: Float = Field(0.0055, description="J, > 0: normal energy from which a hit chips (a 3 mm steel "
                                                   "ball at 10 m/s cone-cracks float glass)", gt=0)
    crack_energy: Float = Field(0.14, description="J, > chip_energy: normal energy from which a hit cracks (the "
                                                  "ball at 50 m/s: radial and star cracks)", gt=0)
    chip_momentum: Float = Field(0.0011, description="N s, > 0: normal momentum from which a hit chips", gt=0)
    crack_momentum: Float = Field(0.0055, description="N s, > chip_momentum: normal momentum from which a hit "
                                                      "cracks", gt=0)
    min_speed: Float = Field(0.5, description="m/s, >= 0: contacts closing slower than this (normal relative "
                                              "speed) bounce but are not recorded (a stone resting or sliding on "
                                              "a body)", ge=0)
    capacity: TableSize = Field("auto", description='"auto" or the events kept on the device between drains '
                                                    "(int >= 1); more are counted as dropped")

    @model_validator(mode="after")
    def _ordered(self) -> Impacts:
        _raise_problems([((f"crack_{m}",), f"must be > chip_{m} ({getattr(self, 'chip_' + m):g}), got "
                                          f"{getattr(self, 'crack_' + m):g}")
                         for m in DAMAGE_MEASURES if getattr(self, f"crack_{m}") <= getattr(self, f"chip_{m}")])
        return self

    def thresholds(self) -> tuple[float, float]:
        """(chip, crack) in the unit of ``damage_by`` (J or N s)."""
        return getattr(self, f"chip_{self.damage_by}"), getattr(self, f"crack_{self.damage_by}")
