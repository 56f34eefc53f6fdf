"""Counter-based random numbers: the same values on every run, thread count and backend.

``ti.random()`` keeps one state per CPU thread, so its values depend on scheduling. Instead every random
number is a pure function of (seed, rock id, step, stream): a 32-bit integer hash (the "lowbias32" mixer
of C. Wellons, hash-prospector) applied in a chain, scaled to [0, 1) with 24 bits.
"""

import numpy as np
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


# NumPy twins of the two functions above (host side: tests, colours chosen on the host), equal bit for bit.
_M32 = 0xFFFFFFFF


def _u32(x) -> np.ndarray:
    """Integers (any sign, Python or NumPy) modulo 2^32, held in uint64 so that products of two fit."""
    return np.asarray(x).astype(np.int64).astype(np.uint64) & np.uint64(_M32)


def mix32_np(x) -> np.ndarray:
    """:func:`mix32` on the host: uint32 values (array or scalar), arithmetic modulo 2^32."""
    x = _u32(x)
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(0x7FEB352D)) & np.uint64(_M32)
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(0x846CA68B)) & np.uint64(_M32)
    x ^= x >> np.uint64(16)
    return x.astype(np.uint32)


def uniform01_np(seed, a, b, stream) -> np.ndarray:
    """:func:`uniform01` on the host (float32, broadcast over array arguments)."""
    h = mix32_np(_u32(seed) ^ np.uint64(0x9E3779B9))
    h = mix32_np(_u32(h) ^ _u32(a))
    h = mix32_np(_u32(h) ^ _u32(b))
    h = mix32_np(_u32(h) ^ _u32(stream))
    return (h >> np.uint32(8)).astype(np.float32) * np.float32(1.0 / 16777216.0)
