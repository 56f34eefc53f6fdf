"""A splashing rear tire's row of ``World.ray`` (one row per tire, float columns; the layout: engine/world.py
A0 ... HULL), read through these accessors instead of packed offsets. Each is a plain read (the same bits)."""

import taichi as ti

from .world import A0, A1, ACTIVE, B0, B1, FENDER, FLAP, FWD, HALF_L, HALF_W, SPIN, TIRE_R, VEL


@ti.func
def point(w: ti.template(), t, col: ti.template()):
    """The 3-vector at column ``col``: the ray's ends A0, B0 (the previous step's centre and bottom), A1, B1
    (now), or VEL, the wheel's velocity (m/s)."""
    return ti.Vector([w.ray[t, col], w.ray[t, col + 1], w.ray[t, col + 2]])


@ti.func
def xy(w: ti.template(), t, col: ti.template()):
    """The 2-vector at column ``col``: a point's XY (A0, B0, A1, B1), the heading FWD, a hull vertex."""
    return ti.Vector([w.ray[t, col], w.ray[t, col + 1]])


@ti.func
def rays_box(w: ti.template(), t):
    """The XY box (lo, hi) of the ends of tire t's ray at the previous step and now (A0, B0, A1, B1)."""
    lo = xy(w, t, A0)
    hi = lo
    for k in ti.static((B0, A1, B1)):
        q = xy(w, t, k)
        lo = ti.min(lo, q)
        hi = ti.max(hi, q)
    return lo, hi


@ti.func
def near_bed(w: ti.template(), t):
    """Is tire t near the bed this step (else parked far away: its rays degenerate, high above the bed)?"""
    return w.ray[t, ACTIVE] != 0.0


@ti.func
def has_tread(w: ti.template(), t):
    """Has tire t a tread's contact patch (half its width or half its length > 0)?"""
    return w.ray[t, HALF_W] > 0.0 or w.ray[t, HALF_L] > 0.0


@ti.func
def wheel_velocity(w: ti.template(), t):
    """The wheel's velocity (m/s, 3-vector)."""
    return point(w, t, VEL)


@ti.func
def forward(w: ti.template(), t):
    """The wheel's heading, a unit XY vector."""
    return xy(w, t, FWD)


@ti.func
def spin(w: ti.template(), t):
    """The tread's speed omega * R (m/s)."""
    return w.ray[t, SPIN]


@ti.func
def half_length(w: ti.template(), t):
    """Half the contact patch's length (m)."""
    return w.ray[t, HALF_L]


@ti.func
def radius(w: ti.template(), t):
    """The tire's radius (m)."""
    return w.ray[t, TIRE_R]


@ti.func
def fender(w: ti.template(), t):
    """The fender's angle (rad) and the mud flap's lower edge (m; < 0: none)."""
    return w.ray[t, FENDER], w.ray[t, FLAP]
