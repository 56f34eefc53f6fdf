"""The cabin of a vehicle, host side: its windscreen, the driver's eye behind it and a camera on the bonnet,
sized from the vehicle's body (motion/bodies.py: its kind's parts, from length L, width W, height H, tire
radius R). The camera rig (motion/camera.py) puts the driver and bonnet views there; render/interior.py draws
the windscreen's frame from the inside.

Body frame: x forward, y left, z up, origin at the body centre on the ground. The windscreen is the glazed front
face of the body: a trapezoid from its bottom edge (x = ``base_x``, half width ``base_half``, at the belt line
z = ``belt``, the top of the body below the glass) up to its top edge (``top_x``, ``top_half``, at the roof
z = ``roof``):

  car    the front face of the "cabin" frustum, sloping in from x = 0.22 L (half width 0.43 W) to 0.06 L
         (0.39 W), above the "lower" body (up to z0 + H/2);
  van    the front face of the "glazed" frustum, from 0.3 L to 0.2 L (half width 0.485 W), above the "lower"
         body (up to z0 + 0.45 H);
  truck  the front of the "cab_glass" box, upright, above the "cab" (a cab-over: no bonnet).

The driver sits on the left (y = 0.21 W; a seat's centre in a 1.8 m wide car is ~0.37 m off the centre line),
with the eye 0.6 of the way from the belt line up to the roof and d = min(0.22 L, 0.55 s) behind the
windscreen at that height (s: the cabin's length there), i.e. ~1 m in a 4.5 m car. That is roughly where a
seated driver's eye is (the positions vehicle makers design for are SAE J941's eye ellipses); these cabins are
boxy and their windscreens steep, so the eye sits a little further back than in a real car, which keeps the
roof's front edge in a 50 degree view. The bonnet camera stands on the centre line half way from the
windscreen's foot to the front, 0.13 H above the bonnet: the bonnet fills the bottom fifth of a 50 degree view
of a car (a cab-over truck has none: the camera is 5 cm in front of its windscreen).
"""

from __future__ import annotations

from dataclasses import dataclass

from .bodies import body_parts

__all__ = ["Cabin", "cabin_of", "EYE_SIDE", "EYE_RISE"]

EYE_SIDE = 0.21  # the driver's eye, left of the centre line, in widths
EYE_RISE = 0.6  # the driver's eye, from the belt line up to the roof
EYE_BACK = (0.22, 0.55)  # behind the windscreen: at most this share of the length, and of the cabin there
BONNET_ALONG = 0.5  # the bonnet camera, from the windscreen's foot to the front
BONNET_RISE = 0.13  # above the bonnet, in heights


@dataclass(frozen=True)
class Cabin:
    """A vehicle's cabin in its body frame (m): the windscreen's bottom edge (``base_x``, ``base_half`` at z =
    ``belt``) and top edge (``top_x``, ``top_half`` at ``roof``); the cabin's back at the belt and at the roof
    (``back_x``, ``back_top_x``) and its half width inside; the body's front (``front_x``) and the top of the
    bonnet (``bonnet_z``; the belt for a car and a van); the driver's eye and the bonnet camera."""

    kind: str
    length: float
    width: float
    floor: float  # z0: the body's underside
    belt: float
    roof: float
    base_x: float
    base_half: float
    top_x: float
    top_half: float
    back_x: float
    back_top_x: float
    half_inside: float
    front_x: float
    bonnet_z: float

    def windscreen_x(self, z: float) -> float:
        """The windscreen's x at height ``z`` (between the belt and the roof)."""
        u = (z - self.belt) / (self.roof - self.belt)
        return self.base_x + u * (self.top_x - self.base_x)

    def back_at(self, z: float) -> float:
        u = (z - self.belt) / (self.roof - self.belt)
        return self.back_x + u * (self.back_top_x - self.back_x)

    @property
    def eye(self) -> tuple:
        """The driver's eye (see the module docstring)."""
        z = self.belt + EYE_RISE * (self.roof - self.belt)
        ws = self.windscreen_x(z)
        back = min(EYE_BACK[0] * self.length, EYE_BACK[1] * (ws - self.back_at(z)))
        return (ws - back, EYE_SIDE * self.width, z)

    @property
    def bonnet_eye(self) -> tuple:
        """The camera on the bonnet (see the module docstring)."""
        x = max(self.base_x + BONNET_ALONG * (self.front_x - self.base_x), self.base_x + 0.05)
        return (x, 0.0, self.bonnet_z + BONNET_RISE * (self.roof - self.floor))


def cabin_of(spec, ground_z: float = 0.0) -> Cabin:
    """The cabin of vehicle ``spec`` (a scene's [[vehicle]]) on ground ``ground_z``, from its body's parts."""
    body = body_parts(spec, ground_z)
    L, W = float(spec.length), float(spec.width)
    if body.kind in ("car", "van"):
        x_lo, x_hi, _, _, belt = body.part("lower").bounds
        glass = body.part("cabin" if body.kind == "car" else "glazed")
        (c0, c1, half), (r0, r1, top_half), _, roof = glass.dims
        back, back_top = (c0, r0) if body.kind == "car" else (body.part("upper").bounds[0],) * 2
        return Cabin(body.kind, L, W, body.floor, belt, roof, c1, half, r1, top_half, back, back_top, top_half,
                     x_hi, belt)
    x0, x1, half, _, roof = body.part("cab_glass").bounds
    belt, front = body.part("cab").bounds[4], body.part("cab").bounds[1]
    return Cabin(body.kind, L, W, body.floor, belt, roof, x1, half, x1, half, x0, x0, half, front, belt)
