"""Counter-based random numbers: the same values on every run, thread count and backend.

``ti.random()`` keeps one state per CPU thread, so its values depend on scheduling. Instead every random
number is a pure function of (seed, rock id, step, stream): a 32-bit integer hash (the "lowbias32" mixer
of C. Wellons, hash-prospector) applied in a chain, scaled to [0, 1) with 24 bits.
"""

import taichi as ti


@ti.func
def mix32(x):
    x ^= x >> ti.u32(16)
    x *= ti.u32(0x7FEB352D)
    x ^= x >> ti.u32(15)
    x *= ti.u32(0x846CA68B)
    x ^= x >> ti.u32(16)
    return x


@ti.func
def uniform01(seed, a, b, stream):
    """A uniform number in [0, 1) from four integers."""
    h = mix32(ti.cast(seed, ti.u32) ^ ti.u32(0x9E3779B9))
    h = mix32(h ^ ti.cast(a, ti.u32))
    h = mix32(h ^ ti.cast(b, ti.u32))
    h = mix32(h ^ ti.cast(stream, ti.u32))
    return ti.cast(h >> ti.u32(8), ti.f32) * (1.0 / 16777216.0)
