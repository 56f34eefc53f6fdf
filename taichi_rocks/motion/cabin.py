"""The cabin of a vehicle, host side (NumPy-free arithmetic): its windscreen, the driver's eye behind it and a
camera on the bonnet, sized from the vehicle (length L, width W, height H, tire radius R, kind). The camera rig
(motion/camera.py) puts the driver and bonnet views there; render/interior.py draws the windscreen's frame
from the inside.

Body frame: x forward, y left, z up, origin at the body centre on the ground; the body starts 0.8 R above the
ground (z0). The windscreen is the glazed front face of the body as render/bodies.py draws it (tests hold the
two together): a trapezoid from its bottom edge (x = ``base_x``, half width ``base_half``, at the belt line
z = ``belt``) up to its top edge (``top_x``, ``top_half``, at the roof z = ``roof``):

  car    lower body up to z0 + H/2, a cabin sloping in from x = 0.22 L (half width 0.43 W) to 0.06 L (0.39 W)
         at the roof z0 + H, its back from -0.33 L to -0.24 L;
  van    lower body up to z0 + 0.45 H, a windscreen from 0.3 L to 0.2 L (half width 0.485 W), the upper body
         back to the rear;
  truck  a cab-over: the cab's glazed part from z_mid (between the chassis top max(z0 + 0.22 H, 2 R + 4 cm)
         and the cab top z0 + 0.78 H) to the cab top, its windscreen upright at the front, the cab min(2.2 m,
         0.3 L) long.

The driver sits on the left (y = 0.21 W, a seat's centre in a 1.8 m wide car is ~0.37 m off the centre line), with
the eye 0.6 of the way from the belt line up to the roof and d = min(0.22 L, 0.55 s) behind the windscreen
at that height (s: the cabin's length there), i.e. ~1 m in a 4.5 m car. That is roughly where a seated
driver's eye is (the positions vehicle makers design for are SAE J941's eye ellipses); these cabins are boxy
and their windscreens steep, so the eye sits a little further back than in a real car, which keeps the roof's
front edge in a 50 degree view. The bonnet camera stands on the
centre line half way from the windscreen's foot to the front, 0.13 H above the bonnet: the bonnet fills the
bottom fifth of a 50 degree view of a car (a cab-over truck has none: the camera is 5 cm in front of its
windscreen).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["KINDS", "Cabin", "cabin_of", "vehicle_kind", "EYE_SIDE", "EYE_RISE"]

KINDS = ("car", "van", "truck")
GAP = 0.04  # m between a wheel and its well (render/bodies.py)
EPS = 0.01  # m: pieces that touch overlap this much (render/bodies.py)
EYE_SIDE = 0.21  # the driver's eye, left of the centre line, in widths
EYE_RISE = 0.6  # the driver's eye, from the belt line up to the roof
EYE_BACK = (0.22, 0.55)  # behind the windscreen: at most this share of the length, and of the cabin there
BONNET_ALONG = 0.5  # the bonnet camera, from the windscreen's foot to the front
BONNET_RISE = 0.13  # above the bonnet, in heights


def vehicle_kind(spec) -> str:
    """"truck", "van" or "car": the vehicle's ``kind``, or for "auto" (and specs without one) from its
    proportions (the rule of render/bodies.py's ``vehicle_kind``; a test holds them equal)."""
    kind = getattr(spec, "kind", "auto")
    if kind in KINDS:
        return kind
    L, H = float(spec.length), float(spec.height)
    if H >= 2.6 or L >= 6.5:
        return "truck"
    if H >= 1.75:
        return "van"
    return "car"


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
    """The cabin of vehicle ``spec`` (a scene's [[vehicle]]) on ground ``ground_z``."""
    L, W, H, R = float(spec.length), float(spec.width), float(spec.height), float(spec.tire_radius)
    z0 = ground_z + 0.8 * R
    kind = vehicle_kind(spec)
    if kind == "car":
        belt = z0 + 0.5 * H
        return Cabin(kind, L, W, z0, belt, z0 + H, 0.22 * L, 0.43 * W, 0.06 * L, 0.39 * W, -0.33 * L, -0.24 * L,
                     0.39 * W, L / 2, belt)
    if kind == "van":
        belt = z0 + 0.45 * H
        xf1 = L / 2 - 0.2 * L
        return Cabin(kind, L, W, z0, belt, z0 + H, xf1, 0.485 * W, xf1 - 0.1 * L, 0.485 * W, -L / 2, -L / 2,
                     0.485 * W, L / 2, belt)
    chassis_top = max(z0 + 0.22 * H, 2.0 * R + GAP)
    cab_l = min(2.2, 0.3 * L)
    cab_top = z0 + 0.78 * H
    mid = 0.5 * (chassis_top + cab_top)
    front = L / 2 - 0.005
    half = (W - 0.006) / 2
    back = L / 2 - cab_l + 0.005
    return Cabin(kind, L, W, z0, mid, cab_top, front, half, front, half, back, back, half, L / 2, mid)
