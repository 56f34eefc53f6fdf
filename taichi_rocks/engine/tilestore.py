"""Active stepping's tile store between steps (engine/active.py holds the store and the step): the runtime guard
over the stored rocks (``Simulation.check_health``; the floating origin moves them with the others:
engine/origin.py)."""

import taichi as ti

from .tiles import same_key, tile_key, vec2
from .world import Par
from .view import world_kernel

__all__ = ["store_health"]


@world_kernel
def store_health(w: ti.template(), centre: vec2, slack: ti.f64, tiles: vec2):
    """The runtime guard over the stored rocks, into ``w.health_out`` after kernels.health: non-finite [0],
    outside the bed [1], below the ground or off its tile [2]; a bad stored rock's index goes to [3..5] as
    -1 - its store index (negative: it wins the atomic_min over an active rock's, and the host tells them
    apart by the sign)."""
    out = ti.static(w.health_out)
    radius = w.par[Par.BED_RADIUS] + ti.cast(slack, w.real)
    cap = w.store_capacity
    st = ti.cast(tiles, ti.i32)
    for t, k in ti.ndrange(w.store_grid * w.store_grid, cap):
        if k < w.ts_count[t]:
            j = t * cap + k
            p = w.ts_pos[j]
            if not (ti.abs(p[0]) < 1e30 and ti.abs(p[1]) < 1e30 and ti.abs(p[2]) < 1e30):
                out[0] += 1
                ti.atomic_min(out[3], -1 - j)
            else:
                d2 = (p[0] - centre[0]) ** 2 + (p[1] - centre[1]) ** 2
                if ti.static(w.recycles_rocks):
                    if d2 > radius * radius:
                        out[1] += 1
                        ti.atomic_min(out[4], -1 - j)
                if not same_key(tile_key(w, p, st), w.ts_key[t]) or p[2] < w.par[Par.GROUND_Z] - ti.cast(slack, w.real):
                    out[2] += 1
                    ti.atomic_min(out[5], -1 - j)
