"""Vehicle meshes, host side (NumPy, no Taichi): the body parts of motion/bodies.py drawn in their colours,
with the decorations that are not hit (lights, stripes, a door line, wheel wells cut round the wheels), on four
wheels.

The parts (a car's lower body, glazed cabin and bumpers; a van's bonnet and tall glazed body; a truck's chassis,
cab and cargo box) come from :func:`..motion.bodies.body_parts`, the one definition that stones also collide
with. Around each wheel the lower body is cut back to an inner part (inside the wheels) below a fender, so the
wheels show. The player's vehicle (the one the bed follows) wears white stripes over its top and a white band
along its sides.
"""

import numpy as np

from ..motion.bodies import EPS, GAP, KINDS, body_parts, inner_width, vehicle_kind
from .looks import BUMPER_COLOR, GLASS_COLOR, HEADLIGHT_COLOR, PLAYER_MARK_COLOR, TAIL_LIGHT_COLOR, TIRE_COLOR
from .meshes import VehicleMesh, box, frustum, merge, wheel

__all__ = ["KINDS", "vehicle_kind", "vehicle_mesh", "scene_meshes"]

PROUD = 0.004  # m: lights, stripes and bands stand this far off the surface they are on


def _span(x0, x1, y, z0, z1, colors, width=None):
    """A box from x0 to x1 and z0 to z1, ``width`` wide (default 2 y) and centred on y = 0."""
    w = 2.0 * y if width is None else width
    return box(((x0 + x1) / 2, 0.0, (z0 + z1) / 2), (x1 - x0, w, z1 - z0), colors)


def _draw(part, colors):
    """One body part as drawn: its box or frustum in ``colors``."""
    return box(*part.dims, colors) if part.shape == "box" else frustum(*part.dims, colors)


def _lower_body(spec, part, color):
    """The lower body ``part`` with a well round each wheel: there an inner part (inside the wheels) up to a
    fender that starts just above the wheel."""
    x_lo, x_hi, hw, z_bot, z_top = part.bounds
    W, R = 2.0 * hw, float(spec.tire_radius)
    inner = inner_width(spec)
    wells = sorted((max(x - R - GAP, x_lo), min(x + R + GAP, x_hi))
                   for x in (0.5 * float(spec.wheelbase), -0.5 * float(spec.wheelbase)))
    parts, cur = [], x_lo
    for a, b in wells:
        if a > cur:
            parts.append(_span(cur, a, hw, z_bot, z_top, color))
        cur = max(cur, b)
    if cur < x_hi:
        parts.append(_span(cur, x_hi, hw, z_bot, z_top, color))
    fender = 2.0 * R + GAP
    for a, b in wells:
        a, b = max(a - EPS, x_lo), min(b + EPS, x_hi)
        parts.append(_span(a, b, 0.0, z_bot + 0.005, min(fender + EPS, z_top - 0.005), color, width=inner))
        if fender < z_top - 0.01:
            parts.append(_span(a, b, 0.0, fender, z_top - 0.005, color, width=W - 0.006))
    return parts


def _car(spec, body, col):
    """Lower body and a glazed cabin; the top surfaces (x0, x1, z), the side band's z range and x range."""
    H = float(spec.height)
    glass = np.array(GLASS_COLOR)
    lower, cabin = body.part("lower"), body.part("cabin")
    x_lo, x_hi, _, _, top = lower.bounds
    parts = _lower_body(spec, lower, col)
    # the cabin: windows sloping in to a roof in the body colour
    parts.append(_draw(cabin, {"front": glass, "back": glass, "left": glass, "right": glass, "top": col * 0.95}))
    (c0, c1, _), (r0, r1, _), _, roof = cabin.dims
    tops = [(c1, x_hi, top), (r0, r1, roof), (x_lo, c0, top)]
    return parts, tops, (top - 0.16 * H, top - 0.08 * H), (x_lo, x_hi)


def _van(spec, body, col):
    """Lower body, a tall upper body glazed at the front behind a short bonnet."""
    H = float(spec.height)
    glass = np.array(GLASS_COLOR)
    lower, glazed = body.part("lower"), body.part("glazed")
    x_lo, x_hi, _, _, top = lower.bounds
    parts = _lower_body(spec, lower, col)
    upper = col * 0.95
    parts.append(_draw(glazed, {"front": glass, "left": glass, "right": glass, "top": upper}))  # a sloping windscreen
    parts.append(_draw(body.part("upper"), {"-x": glass, "+y": upper, "-y": upper, "+z": upper}))
    (_, xf1, _), _, _, roof = glazed.dims
    tops = [(xf1, x_hi, top), (x_lo, xf1, roof)]
    return parts, tops, (top - 0.16 * H, top - 0.08 * H), (x_lo, x_hi)


def _truck(spec, body, col):
    """Chassis, cab at the front (glazed above), cargo box behind with a door line at its back."""
    H = float(spec.height)
    glass = np.array(GLASS_COLOR)
    chassis, cab, cargo_box = body.part("chassis"), body.part("cab"), body.part("cargo")
    parts = [_draw(chassis, np.array(TIRE_COLOR) * 2), _draw(cab, col)]
    parts.append(_draw(body.part("cab_glass"), {"+x": glass, "+y": glass, "-y": glass, "-x": col, "+z": col}))
    cargo = np.clip(col * 1.08 + 0.04, 0, 1)
    parts.append(_draw(cargo_box, {**{k: cargo for k in ("+x", "+y", "-y", "+z")}, "-x": col * 0.8}))
    x_back, box_x1, _, _, roof = cargo_box.bounds
    z0, chassis_top = chassis.bounds[3], chassis.bounds[4]
    parts.append(box((x_back - PROUD, 0.0, 0.5 * (chassis_top + z0 + H)), (0.008, 0.03, 0.9 * (roof - chassis_top)),
                     np.array(BUMPER_COLOR)))
    tops = [(cab.bounds[0], cab.bounds[1], body.part("cab_glass").bounds[4]), (x_back, box_x1, roof)]
    return parts, tops, (z0 + 0.55 * H, z0 + 0.63 * H), (x_back, box_x1)


def _trim(spec, body):
    """Bumpers, head and tail lights, proud of the body."""
    L, W, H = float(spec.length), float(spec.width), float(spec.height)
    z0 = body.floor
    front, rear = body.part("front_bumper"), body.part("rear_bumper")
    parts = [_draw(p, np.array(BUMPER_COLOR)) for p in (front, rear)]
    bump_h = front.dims[1][2]
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
    (:func:`vehicle_kind`; its parts: :func:`..motion.bodies.body_parts`); the wheels (:func:`.meshes.wheel`)
    sit at (+-wheelbase/2, +-track/2), centre height tire_radius; ``player`` adds the player's stripes and
    bands."""
    col = np.clip(np.asarray(spec.color, np.float64), 0, 1)
    shape = body_parts(spec, ground_z)
    build = {"car": _car, "van": _van, "truck": _truck}[shape.kind]
    parts, tops, band, along = build(spec, shape, col)
    parts += _trim(spec, shape)
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
