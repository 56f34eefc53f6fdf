"""The flash of an impact, host side (NumPy): a few frames of light where a stone hit a body.

Every impact flashes at its contact point for FLASH_S seconds (render/marks.py; 4 frames at 30 frames/s): a hot
core and RAYS short sparks along the surface, fading and spreading as it ages; the point rides with the vehicle
hit (its pose at the frame). Sizes are in metres, but never below FLASH_PX pixels for the core and RAY_PX for the
sparks at the camera's distance, so a hit 20 m ahead reads as well as one on the bonnet. A flash lasts a few
frames: it is made anew each frame (render/hits.py), unlike the marks.
"""

from __future__ import annotations

import math

import numpy as np

from .marks import FLASH_S, body_to_local

__all__ = ["flash_geometry", "FLASH_M", "FLASH_PX", "RAY_M", "RAY_PX", "RAYS", "HOT"]

FLASH_M = 0.012  # m: the flash core's radius, at its largest
FLASH_PX = 5.0  # pixels: the core's radius at least, at its largest
RAY_M = 0.09  # m: a spark's length, fully spread
RAY_PX = 24.0  # pixels: a spark's length at least, fully spread
RAYS = 8
HOT = 2.5  # the core's colour at its brightest (white-hot once GGUI's shading and the 8-bit image clip it)


def flash_geometry(events, ages, positions, headings, eye, px_per_rad: float):
    """The flashes of ``events`` (body frame) ``ages`` seconds old, on vehicles at ``positions`` (N, 3) with
    ``headings`` (N,) (the frame's poses of each event's vehicle, local frame): (centres (N, 3), radii (N,),
    colours (N, 3)) of the cores and the sparks as segments (N * RAYS, 2, 3) with their colours (N * RAYS, 3),
    all float32."""
    n = len(events)
    if not n:
        return (np.empty((0, 3), np.float32), np.empty(0, np.float32), np.empty((0, 3), np.float32),
                np.empty((0, 2, 3), np.float32), np.empty((0, 3), np.float32))
    p = body_to_local(events["point"], positions, headings)
    nrm = body_to_local(events["normal"], np.zeros((n, 3)), headings)
    u = np.clip(np.asarray(ages, np.float64) / FLASH_S, 0.0, 1.0)
    dist = np.maximum(np.linalg.norm(p - np.asarray(eye, np.float64), axis=1), 0.05)
    per_m = dist / float(px_per_rad)  # metres per pixel at the hit's distance
    glow = 1.0 - u  # fades out
    core = np.maximum(FLASH_M, FLASH_PX * per_m) * (1.0 - 0.6 * u)
    centres = p + 0.5 * core[:, None] * nrm  # a little off the surface, so the body does not hide it
    hot = np.array([HOT, HOT, 0.85 * HOT])  # GGUI shades particles (colour x light): over 1 saturates to white
    cols = hot[None] * (0.35 + 0.65 * glow[:, None])
    # sparks: RAYS directions in the surface's plane, spreading with age
    t1 = np.cross(nrm, np.array([0.0, 0.0, 1.0]))
    flat = np.linalg.norm(t1, axis=1) < 1e-6
    t1[flat] = np.cross(nrm[flat], np.array([1.0, 0.0, 0.0]))
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    ang = np.arange(RAYS) * 2.0 * math.pi / RAYS + events["rock"][:, None] * 0.7  # (n, RAYS)
    d = np.cos(ang)[..., None] * t1[:, None] + np.sin(ang)[..., None] * t2[:, None] + 0.6 * nrm[:, None]
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    reach = np.maximum(RAY_M, RAY_PX * per_m) * (0.35 + 0.65 * u)  # (n,)
    a = centres[:, None] + (0.3 * reach)[:, None, None] * d
    b = centres[:, None] + reach[:, None, None] * d
    segs = np.stack([a, b], axis=2).reshape(-1, 2, 3)
    spark = np.array([1.0, 0.85, 0.45])
    seg_cols = np.repeat(spark[None] * (0.4 + 0.6 * glow[:, None]), RAYS, axis=0)
    return (centres.astype(np.float32), core.astype(np.float32), cols.astype(np.float32),
            segs.astype(np.float32), seg_cols.astype(np.float32))
