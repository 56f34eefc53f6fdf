"""Vehicle bodies, host side (NumPy, no Taichi): a car, a van or a truck of a few boxes each, on four wheels.

The vehicle's ``kind`` (scene key; "auto": from its proportions, :func:`vehicle_kind`) picks the body: a car
has a lower body with wheel wells, a glazed cabin and a roof; a van a tall body glazed at the front behind a
short bonnet; a truck a chassis, a cab and a cargo box. Around each wheel the body is cut back to an inner
part (inside the wheels) below a fender, so the wheels show. The player's vehicle (the one the bed follows)
wears white stripes over its top and a white band along its sides.
"""

import numpy as np

from ..config.keys import choices
from .looks import BUMPER_COLOR, GLASS_COLOR, HEADLIGHT_COLOR, PLAYER_MARK_COLOR, TAIL_LIGHT_COLOR, TIRE_COLOR
from .meshes import VehicleMesh, box, frustum, merge, wheel

__all__ = ["KINDS", "vehicle_kind", "vehicle_mesh", "scene_meshes"]

KINDS = tuple(k for k in choices("vehicle.kind") if k != "auto")  # the bodies drawn
GAP = 0.04  # m between a wheel and its well
EPS = 0.01  # m: pieces that touch overlap this much (their touching faces hidden inside)
PROUD = 0.004  # m: lights, stripes and bands stand this far off the surface they are on


def vehicle_kind(spec) -> str:
    """"truck", "van" or "car": the vehicle's ``kind``, or for "auto" (and specs without one) from its
    proportions."""
    kind = getattr(spec, "kind", "auto")
    if kind in KINDS:
        return kind
    L, H = float(spec.length), float(spec.height)
    if H >= 2.6 or L >= 6.5:
        return "truck"
    if H >= 1.75:
        return "van"
    return "car"


def _span(x0, x1, y, z0, z1, colors, width=None):
    """A box from x0 to x1 and z0 to z1, ``width`` wide (default 2 y) and centred on y = 0."""
    w = 2.0 * y if width is None else width
    return box(((x0 + x1) / 2, 0.0, (z0 + z1) / 2), (x1 - x0, w, z1 - z0), colors)


def _lower_body(spec, z_bot, z_top, color):
    """The body from z_bot to z_top, full width, with a well round each wheel: there an inner part (inside the
    wheels) up to a fender that starts just above the wheel."""
    L, W, R = float(spec.length), float(spec.width), float(spec.tire_radius)
    inner = max(float(spec.track) - float(spec.tire_width) - 0.06, 0.3 * W)
    wells = sorted((max(x - R - GAP, -L / 2), min(x + R + GAP, L / 2))
                   for x in (0.5 * float(spec.wheelbase), -0.5 * float(spec.wheelbase)))
    parts, cur = [], -L / 2
    for a, b in wells:
        if a > cur:
            parts.append(_span(cur, a, W / 2, z_bot, z_top, color))
        cur = max(cur, b)
    if cur < L / 2:
        parts.append(_span(cur, L / 2, W / 2, z_bot, z_top, color))
    fender = 2.0 * R + GAP
    for a, b in wells:
        a, b = max(a - EPS, -L / 2), min(b + EPS, L / 2)
        parts.append(_span(a, b, 0.0, z_bot + 0.005, min(fender + EPS, z_top - 0.005), color, width=inner))
        if fender < z_top - 0.01:
            parts.append(_span(a, b, 0.0, fender, z_top - 0.005, color, width=W - 0.006))
    return parts


def _car(spec, z0, col):
    """Lower body and a glazed cabin; the top surfaces (x0, x1, z), the side band's z range and x range."""
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    top = z0 + 0.5 * H
    glass = np.array(GLASS_COLOR)
    parts = _lower_body(spec, z0, top, col)
    # the cabin: windows sloping in to a roof in the body colour
    parts.append(frustum((-0.33 * L, 0.22 * L, 0.43 * W), (-0.24 * L, 0.06 * L, 0.39 * W), top - EPS, z0 + H,
                         {"front": glass, "back": glass, "left": glass, "right": glass, "top": col * 0.95}))
    tops = [(0.22 * L, L / 2, top), (-0.24 * L, 0.06 * L, z0 + H), (-L / 2, -0.33 * L, top)]
    return parts, tops, (top - 0.16 * H, top - 0.08 * H), (-L / 2, L / 2)


def _van(spec, z0, col):
    """Lower body, a tall upper body glazed at the front behind a short bonnet."""
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    top = z0 + 0.45 * H
    glass = np.array(GLASS_COLOR)
    parts = _lower_body(spec, z0, top, col)
    xf1 = L / 2 - 0.2 * L  # the upper body: glazed front part [xf0, xf1], closed rear part [-L/2, xf0]
    xf0 = xf1 - 0.25 * L
    upper = col * 0.95
    parts.append(frustum((xf0, xf1, 0.485 * W), (xf0, xf1 - 0.1 * L, 0.485 * W), top - EPS, z0 + H,
                         {"front": glass, "left": glass, "right": glass, "top": upper}))  # a sloping windscreen
    parts.append(_span(-L / 2, xf0, 0.0, top - EPS, z0 + H, {"-x": glass, "+y": upper, "-y": upper, "+z": upper},
                       width=0.97 * W))
    tops = [(xf1, L / 2, top), (-L / 2, xf1, z0 + H)]
    return parts, tops, (top - 0.16 * H, top - 0.08 * H), (-L / 2, L / 2)


def _truck(spec, z0, col):
    """Chassis, cab at the front (glazed above), cargo box behind with a door line at its back."""
    L, W, H, R = float(spec.length), float(spec.width), float(spec.height), float(spec.tire_radius)
    inner = max(float(spec.track) - float(spec.tire_width) - 0.06, 0.3 * W)
    glass = np.array(GLASS_COLOR)
    chassis_top = max(z0 + 0.22 * H, 2.0 * R + GAP)
    parts = [_span(-L / 2, L / 2, 0.0, z0, chassis_top, np.array(TIRE_COLOR) * 2, width=inner)]
    cab_l = min(2.2, 0.3 * L)
    cab_top = z0 + 0.78 * H
    mid = 0.5 * (chassis_top + cab_top)
    parts.append(_span(L / 2 - cab_l, L / 2, W / 2, chassis_top - EPS, mid, col))
    parts.append(_span(L / 2 - cab_l + 0.005, L / 2 - 0.005, W / 2, mid - EPS, cab_top,
                       {"+x": glass, "+y": glass, "-y": glass, "-x": col, "+z": col}, width=W - 0.006))
    box_x1 = L / 2 - cab_l - 0.15
    cargo = np.clip(col * 1.08 + 0.04, 0, 1)
    parts.append(_span(-L / 2, box_x1, W / 2, chassis_top - EPS, z0 + H, {**{k: cargo for k in
                       ("+x", "+y", "-y", "+z")}, "-x": col * 0.8}))
    parts.append(box((-L / 2 - PROUD, 0.0, 0.5 * (chassis_top + z0 + H)), (0.008, 0.03, 0.9 * (z0 + H - chassis_top)),
                     np.array(BUMPER_COLOR)))
    tops = [(L / 2 - cab_l, L / 2, cab_top), (-L / 2, box_x1, z0 + H)]
    return parts, tops, (z0 + 0.55 * H, z0 + 0.63 * H), (-L / 2, box_x1)


def _trim(spec, z0):
    """Bumpers, head and tail lights, proud of the body."""
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    bump_h = min(0.18, 0.12 * H)
    parts = [box((sx * (L / 2 + 0.02), 0.0, z0 - 0.01 + bump_h / 2), (0.08, 1.02 * W, bump_h),
                 np.array(BUMPER_COLOR)) for sx in (1.0, -1.0)]
    lz = z0 + bump_h + 0.06 * H
    for side in (1.0, -1.0):
        parts.append(box((-L / 2 - 0.02, side * 0.38 * W, lz), (0.03, 0.16 * W, 0.07 * H), np.array(TAIL_LIGHT_COLOR)))
        parts.append(box((L / 2 + 0.02, side * 0.36 * W, lz), (0.03, 0.16 * W, 0.06 * H), np.array(HEADLIGHT_COLOR)))
    return parts


def _player_marks(spec, tops, band, along):
    """White stripes over the top surfaces and a white band along both sides."""
    W = float(spec.width)
    mark = np.array(PLAYER_MARK_COLOR)
    parts = []
    for x0, x1, z in tops:
        if x1 - x0 > 0.2:
            for y in (0.09 * W, -0.09 * W):
                parts.append(box(((x0 + x1) / 2, y, z + PROUD + 0.005), (x1 - x0 - 0.1, 0.07 * W, 0.01), mark))
    z_lo, z_hi = band
    if z_hi - z_lo > 0.02 and z_lo > 2.0 * float(spec.tire_radius) + GAP:
        for side in (1.0, -1.0):
            parts.append(box(((along[0] + along[1]) / 2, side * (W / 2 + PROUD + 0.003), (z_lo + z_hi) / 2),
                             (along[1] - along[0] - 0.1, 0.006, z_hi - z_lo), mark))
    return parts


def vehicle_mesh(spec, ground_z: float = 0.0, player: bool = False) -> VehicleMesh:
    """Body-frame mesh of one vehicle (x forward, y left, z up; origin at the body centre on the ground).

    The body (length x width, from 0.8 tire radius up to that plus ``height``) is shaped by its kind
    (:func:`vehicle_kind`); the wheels (:func:`.meshes.wheel`) sit at (+-wheelbase/2, +-track/2), centre
    height tire_radius; ``player`` adds the player's stripes and bands."""
    col = np.clip(np.asarray(spec.color, np.float64), 0, 1)
    z0 = ground_z + 0.8 * float(spec.tire_radius)
    build = {"car": _car, "van": _van, "truck": _truck}[vehicle_kind(spec)]
    parts, tops, band, along = build(spec, z0, col)
    parts += _trim(spec, z0)
    if player:
        parts += _player_marks(spec, tops, band, along)
    body = merge(parts)
    R = float(spec.tire_radius)
    centres = np.array([(sx * float(spec.wheelbase), sy * float(spec.track), ground_z + R)
                        for sx in (0.5, -0.5) for sy in (0.5, -0.5)])
    wheels = [wheel(R, float(spec.tire_width)) for _ in centres]
    v, n, c, i = merge([body] + wheels)
    owner = np.concatenate([np.full(len(body[0]), -1)] + [np.full(len(w[0]), k) for k, w in enumerate(wheels)])
    return VehicleMesh(v, n, c, i, owner, centres, centres[:, 0] < 0)


def scene_meshes(scene) -> list:
    """The meshes of a scene's vehicles, the player's (``bed.follow``, default the first) marked."""
    player = getattr(scene.bed, "follow", None) or scene.vehicles[0].name
    return [vehicle_mesh(v, 0.0, player=v.name == player) for v in scene.vehicles]
