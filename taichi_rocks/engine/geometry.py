"""Small geometric functions the passes share (Taichi funcs, any dimension)."""

import taichi as ti


@ti.func
def closest_on_segment(a, b, c):
    """Point of segment a-b closest to c (a zero-length segment gives a)."""
    d = b - a
    dd = d.dot(d)
    t = 0.0 * dd
    if dd > 0.0:
        t = ti.min(ti.max((c - a).dot(d) / dd, 0.0), 1.0)
    return a + t * d
