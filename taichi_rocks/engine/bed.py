"""Pass 1, the bed: rocks outside the bed's disk re-enter at its leading edge.

The bed is the disk |p_xy - c| <= R around the followed vehicle. When the centre moves by d in a step, the
rocks in the old disk but not the new one (trailing crescent) leave, and the leading crescent
{|p - c| <= R, |p - c + d| > R} is new ground with no rocks. Each leaving rock is placed uniformly at random
in that leading crescent, at rest on the ground. Because the two crescents have equal area for any d, the
density stays uniform over the disk while driving straight, turning or reversing, and after jumps of any
size (for |d| >= 2R the crescent is the whole disk).

Sampling the crescent, in the frame x along d / |d|, y across it: the chord of the new disk at height y is
x in [-w, w], w = sqrt(R^2 - y^2); the old disk removes x < w - |d| from it, so the crescent's chord is
[w - L, w] with L = min(2w, |d|). Draw y with density proportional to L(y) by rejection (acceptance >= pi/4),
then x uniformly on the chord. Rocks that leave while the bed stands still (thrown out by a tire) use the
vehicle's heading and a crescent one rock diameter thick. Rocks that fall more than R below the ground
(ground contact "none") are recycled the same way.
"""

import taichi as ti
from taichi.lang import impl

from ..config.streams import RECYCLE_CHORD, RECYCLE_TRIES
from .randomness import uniform01
from .world import RESTING, IPar, Par


@ti.func
def outside_bed(p, center_xy, radius, ground_z):
    d = ti.Vector([p[0] - center_xy[0], p[1] - center_xy[1]])
    return d.norm_sqr() > radius * radius or p[2] < ground_z - radius


@ti.func
def leading_crescent_point(center_xy, move, lead, radius, thickness, seed, rock, step):
    """A uniform random point of the leading crescent (see module docstring) as an XY vector."""
    e1 = lead
    dist = move.norm()
    if dist > thickness:
        e1 = move / dist
    else:
        dist = thickness
    e2 = ti.Vector([-e1[1], e1[0]])
    chord_max = ti.min(2.0 * radius, dist)
    y = 0.0 * radius
    chord = chord_max
    for attempt in range(RECYCLE_TRIES.count // 2):
        y = radius * (2.0 * uniform01(seed, rock, step, RECYCLE_TRIES.first + 2 * attempt) - 1.0)
        w = ti.sqrt(ti.max(radius * radius - y * y, 0.0))
        chord = ti.min(2.0 * w, dist)
        if uniform01(seed, rock, step, RECYCLE_TRIES.first + 2 * attempt + 1) * chord_max <= chord:
            break
    w = ti.sqrt(ti.max(radius * radius - y * y, 0.0))
    x = w - chord * uniform01(seed, rock, step, RECYCLE_CHORD.first)
    q = x * e1 + y * e2
    r2 = q.norm_sqr()
    if r2 > radius * radius:  # rounding at the rim
        q *= radius / ti.sqrt(r2) * (1.0 - 1e-6)
    return center_xy + q


@ti.func
def recycle_to_leading_edge(w: ti.template(), i, center_xy, move, lead, step):
    """Move rock i to the leading crescent, at rest on the ground, if it is outside the bed."""
    radius = w.par[Par.BED_RADIUS]
    ground = w.par[Par.GROUND_Z]
    p = w.pos[i]
    if outside_bed(p, center_xy, radius, ground):
        thickness = 2.0 * w.par[Par.R_MAX]
        q = leading_crescent_point(center_xy, move, lead, radius, thickness, w.ipar[IPar.SEED],
                                   w.rock_id[i], step)
        r = w.radius[i]
        w.pos[i] = ti.Vector([q[0], q[1], ground + r])
        w.vel[i] = ti.Vector([0.0, 0.0, 0.0])
        w.phase[i] = RESTING
        count_recycle(w)


def counts_per_thread() -> bool:
    """Compile-time: may a 0-d counter's ``+=`` in a parallel loop be Taichi's per-thread reduction? On the CPU
    it is one atomic per block of iterations (cheap). On a GPU each thread of the launch's grid ends with one
    atomic on the counter, zero or not, and a loop over a run-time count launches a grid that fills the device
    (some 270,000 threads on an H200): that many atomics on one address, whatever the rocks."""
    return impl.current_cfg().arch in (ti.x64, ti.arm64)


@ti.func
def count_recycle(w: ti.template()):
    """One more rock recycled. Off the CPU the atomic's old value is used (a store that cannot happen: the
    count is never negative), which keeps Taichi from turning it into a per-thread reduction
    (:func:`counts_per_thread`): one atomic per recycled rock instead."""
    if ti.static(counts_per_thread()):
        w.recycles[None] += 1
    else:
        if ti.atomic_add(w.recycles[None], 1) < 0:
            w.recycles[None] = 0
