"""The export's colours: what the renderer paints, so that a stage opened in a tool looks like the frames before
anyone assigns materials (NumPy only).

output/ does not import render/, so the renderer's colours are computed here from the same numbers and the
same formula (tests/output hold them equal to render/looks.py's and render/rocklook.py's):

* a rock's tint is the renderer's resting-rock colour of its rock index (render/rocklook.py ``rock_color``):
  with a, b, c uniform in [0, 1) hashed from the index (the ``look`` colour streams of config/streams.py,
  ``mix32`` of engine/randomness.py), ``col = grey + (brown - grey) a^2``, then ``col += (dark - col) 0.55
  c^2`` and ``col *= 0.72 + 0.45 b``. A recycled rock keeps its index, and its colour, as in the frames.
* Blender (4.5) reads neither per-instance primvars of a PointInstancer nor a mesh's displayColor without a
  material: each rock shape is therefore written in :data:`TINTS` tints (the centres of a k-means of the
  tint distribution, :func:`tint_palette`), a rock instancing the shape in the tint nearest to its own.
* the vehicles: each part of the body (motion/bodies.py) with the faces the renderer draws, in its colours
  (render/bodies.py: the scene's colour, glass, a truck's chassis, cargo box and bumpers; :func:`part_faces`);
  the tread blocks alternating between the renderer's two rubbers, the wheel's sides in the area-weighted mean
  of the renderer's rim (rubber ring, spokes, openings, cap); the ground in the mean of its two checker
  colours.

The renderer's colours are display values (GGUI writes colour x light to the frame as it is, with no
transfer function); USD's displayColor is linear. The stage therefore holds :func:`linear` of them (the sRGB
transfer function, IEC 61966-2-1), so that a tool showing linear colours through an sRGB view (Blender's
"Standard" view transform) shows the frames' colours.
"""

from __future__ import annotations

import numpy as np

from ..config.streams import LOOK_COLOUR

__all__ = ["ROCK_GREY", "ROCK_BROWN", "ROCK_DARK", "TIRE_COLOR", "TREAD_COLOR", "WHEEL_SIDE_COLOR",
           "GROUND_COLOR", "GLASS_COLOR", "BUMPER_COLOR", "TINTS", "rock_tints", "tint_palette", "nearest_tint",
           "linear", "part_faces"]

ROCK_GREY = (0.60, 0.59, 0.57)  # render/rocklook.py _GREY, _BROWN, _DARK
ROCK_BROWN = (0.62, 0.50, 0.37)
ROCK_DARK = (0.36, 0.34, 0.32)
TIRE_COLOR = (0.09, 0.09, 0.10)  # render/looks.py
TREAD_COLOR = (0.20, 0.20, 0.21)
_HUB = (0.62, 0.62, 0.64)
_RIM_DARK = (0.14, 0.14, 0.15)
# a wheel's side as render/meshes.py draws it: rubber out to 0.66 R, spokes and openings (half each) to 0.24 R,
# a light cap inside: each colour by its share of the disc's area
_RING, _RIM, _CAP = 1.0 - 0.66 ** 2, 0.66 ** 2 - 0.24 ** 2, 0.24 ** 2
WHEEL_SIDE_COLOR = tuple(_RING * t + 0.5 * _RIM * (h + d) + _CAP * h for t, h, d in zip(TIRE_COLOR, _HUB, _RIM_DARK))
GROUND_COLOR = tuple(0.5 * (a + b) for a, b in zip((0.56, 0.53, 0.44), (0.49, 0.46, 0.38)))  # GROUND_A, _B
GLASS_COLOR = (0.24, 0.31, 0.40)  # render/looks.py
BUMPER_COLOR = (0.13, 0.13, 0.14)
_ALL = ("front", "back", "left", "right", "top", "bottom")  # motion/bodies.py FACES
TINTS = 8  # tints per rock shape in the stage
_GOLDEN, _SALT = 0x9E3779B9, 0x85EBCA6B  # render/rocklook.py's hash of (rock id, salt)
_M32 = np.uint64(0xFFFFFFFF)


def _mix32(x: np.ndarray) -> np.ndarray:
    """engine/randomness.py ``mix32`` (uint32 arithmetic, in uint64 so that the products fit)."""
    x = x & _M32
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(0x7FEB352D)) & _M32
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(0x846CA68B)) & _M32
    x ^= x >> np.uint64(16)
    return x


def _unit(index: np.ndarray, salt: int) -> np.ndarray:
    x = (index.astype(np.uint64) * np.uint64(_GOLDEN) + np.uint64(salt) * np.uint64(_SALT)) & _M32
    return (_mix32(x) >> np.uint64(8)).astype(np.float64) / 16777216.0


def rock_tints(index) -> np.ndarray:
    """(M, 3) float64: the renderer's resting colour of the rocks of index ``index`` (M,) (see the module
    docstring)."""
    index = np.asarray(index, np.int64).reshape(-1)
    a, b, c = (_unit(index, salt)[:, None] for salt in LOOK_COLOUR.ids)
    grey, brown, dark = (np.array(x) for x in (ROCK_GREY, ROCK_BROWN, ROCK_DARK))
    col = grey + (brown - grey) * a * a
    col = col + (dark - col) * 0.55 * c * c
    return col * (0.72 + 0.45 * b)


def tint_palette(k: int = TINTS, sample: int = 8192, rounds: int = 25) -> np.ndarray:
    """(k, 3): centres of the tints of rock indices 0 .. sample - 1 by Lloyd's k-means (seeded at the tints'
    brightness quantiles, so the same every time)."""
    tints = rock_tints(np.arange(sample))
    order = np.argsort(tints.sum(axis=1), kind="stable")
    centres = tints[order[((np.arange(k) + 0.5) * sample / k).astype(int)]]
    for _ in range(rounds):
        near = nearest_tint(tints, centres)
        centres = np.array([tints[near == j].mean(axis=0) if np.any(near == j) else centres[j] for j in range(k)])
    return centres


def linear(rgb) -> np.ndarray:
    """Display (sRGB-encoded) colours in [0, 1] to linear ones (IEC 61966-2-1), same shape."""
    c = np.clip(np.asarray(rgb, np.float64), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def part_faces(kind: str, part: str, color) -> dict:
    """The faces of body part ``part`` of a ``kind`` body that the renderer draws (render/bodies.py), each
    face (motion/bodies.py FACES) -> (display colour, glass?); faces left out are not drawn. ``color``: the
    vehicle's scene colour."""
    col = np.clip(np.asarray(color, np.float64), 0.0, 1.0)
    glass, roof = (np.array(GLASS_COLOR), True), (col * 0.95, False)
    if part in ("front_bumper", "rear_bumper"):
        return {f: (np.array(BUMPER_COLOR), False) for f in _ALL}
    if part == "lower" or (kind, part) == ("truck", "cab"):
        return {f: (col, False) for f in _ALL}
    if part in ("cabin", "glazed"):
        sides = ("front", "back", "left", "right") if part == "cabin" else ("front", "left", "right")
        return {**{f: glass for f in sides}, "top": roof}
    if part == "upper":
        return {"back": glass, "left": roof, "right": roof, "top": roof}
    if part == "chassis":
        return {f: (np.array(TIRE_COLOR) * 2, False) for f in _ALL}
    if part == "cab_glass":
        return {"front": glass, "left": glass, "right": glass, "back": (col, False), "top": (col, False)}
    if part == "cargo":
        cargo = (np.clip(col * 1.08 + 0.04, 0.0, 1.0), False)
        return {"front": cargo, "left": cargo, "right": cargo, "top": cargo, "back": (col * 0.8, False)}
    raise KeyError(f"no colours for part {part!r} of a {kind} body")


def nearest_tint(tints, palette) -> np.ndarray:
    """(M,) int32: the palette entry nearest to each tint (Euclidean in RGB)."""
    d = ((np.asarray(tints)[:, None, :] - np.asarray(palette)[None, :, :]) ** 2).sum(axis=2)
    return np.argmin(d, axis=1).astype(np.int32)
