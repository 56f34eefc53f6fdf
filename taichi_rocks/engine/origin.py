"""The floating origin's move on the device: every rock, stored rock and mirror row of a World moved by the
origin's step in one world kernel whose inputs lie in the World (no float64 arguments: a host without Python
launches it through Taichi's C API, which passes no 64-bit scalars or vectors; native/).

The host writes the move into ``w.origin_move`` (float64 2-vectors, rows MOVE, BEFORE, AFTER: the shift d of the
local frame (XY, whole multiples of ORIGIN_SNAP), the frame's origin before and after it in world coordinates)
with :func:`put_move`, then launches :func:`move_origin`, which does what the three kernels of the move did:

  * every rock of the rock arrays (the active list with active stepping): p' = fl(p - d) in the World's precision;
  * with active stepping every rock in the tiles the same (their keys are anchor-relative and stay;
    engine/active.py);
  * with the mirror of ``changes()`` (engine/changes.py ``shift_drawn_rows``): every mirror row the same, and the
    rocks whose world position float64(p') + after differs from float64(p) + before listed (every rock where
    ``exact`` is False: a backend that does not compute in float64).
"""

import numpy as np
import taichi as ti

from .changes import shift_drawn_rows
from .params import IPar
from .view import world_kernel

__all__ = ["MOVE", "BEFORE", "AFTER", "ROWS", "put_move", "move_origin"]

MOVE, BEFORE, AFTER = range(3)  # rows of World.origin_move
ROWS = 3


def put_move(w, d, before, after) -> None:
    """The origin's move ``d`` and the origin before and after it (XY, float64, world) into ``w.origin_move``."""
    w.origin_move.from_numpy(np.array([d, before, after], np.float64).reshape(ROWS, 2))


@ti.func
def _move(w: ti.template()):
    """The move d as a 3-vector (z = 0) in the World's precision."""
    d = w.origin_move[MOVE]
    return ti.Vector([ti.cast(d[0], w.real), ti.cast(d[1], w.real), 0.0])


@world_kernel
def move_origin(w: ti.template(), exact: ti.template()):
    """The local frame's origin moved by ``w.origin_move[MOVE]`` (module docstring): every rock's local position,
    in the rock arrays, the tiles and the mirror, moves by -d. ``exact``: the backend computes in float64 (CPU,
    CUDA), so the mirror lists only the rocks whose world position changes by rounding."""
    dv = _move(w)
    for i in range(w.ipar[IPar.N_ROCKS]):
        w.pos[i] -= dv
    if ti.static(w.stored):
        cap = w.store_capacity
        for t, k in ti.ndrange(w.store_grid * w.store_grid, cap):
            if k < w.ts_count[t]:
                w.ts_pos[t * cap + k] -= dv
    if ti.static(w.drawn):
        shift_drawn_rows(w, dv, w.origin_move[BEFORE], w.origin_move[AFTER], exact)
