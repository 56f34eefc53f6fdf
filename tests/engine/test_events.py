"""Impact event records (engine/events.py): appended atomically from a kernel, drained as a structured array,
overflow counted, memory flat over many drains."""

import os

import numpy as np
import pytest
import taichi as ti

from taichi_rocks.engine.events import EVENT_DTYPE, EVENT_FIELDS, EventBuffer, append

pytestmark = pytest.mark.usefixtures("taichi_cpu")
DT, R = 2.0 ** -13, 2.0 ** -10


@ti.kernel
def emit(buf: ti.template(), n: ti.i32, first: ti.i32, step: ti.i32, t_rel: ti.f64):
    """n events, event k (rock first + k) with values that tell it apart (binary fractions: kernel float
    literals are float32)."""
    for k in range(n):
        i = first + k
        x = ti.cast(i, buf.real)
        ev = buf.record(time=ti.cast(t_rel, buf.real) + DT * (k % 7), step=step, vehicle=i % 4, part=i % 7,
                        damage=i % 3, point=ti.Vector([x, -x, 0.5 * x]), normal=ti.Vector([0.0, 0.0, 1.0]),
                        speed=2.0 * x, normal_speed=x, normal_momentum=0.25 * x, energy=x * x, radius=R * x,
                        rock=i, thrower=(i + 1) % 4)
        append(buf, ev)


def expected(first, n, step):
    i = np.arange(first, first + n)
    return i, {"step": np.full(n, step), "vehicle": i % 4, "part": i % 7, "damage": i % 3, "speed": 2.0 * i,
               "normal_speed": i, "normal_momentum": 0.25 * i, "energy": i * i, "radius": R * i, "rock": i,
               "thrower": (i + 1) % 4}


@pytest.fixture(scope="module")
def buffers(taichi_cpu):
    return {"f64": EventBuffer(4096, ti.f64), "f32": EventBuffer(4096, ti.f32), "small": EventBuffer(64, ti.f32)}


def test_the_dtype_is_the_declaration():
    assert EVENT_DTYPE.names == tuple(f[0] for f in EVENT_FIELDS)
    for name in ("time", "vehicle", "part", "point", "speed", "normal_speed", "normal_momentum", "energy", "radius",
                 "rock", "thrower", "damage", "step"):
        assert name in EVENT_DTYPE.names
    assert EVENT_DTYPE["point"].shape == (3,) and EVENT_DTYPE["time"] == np.float64


@pytest.mark.parametrize("which", ["f64", "f32"])
def test_append_from_a_kernel_and_drain_twice(buffers, which):
    buf = buffers[which]
    buf.reset(t_now=100.0)
    emit(buf, 1000, 0, 7, 0.25)
    ev = buf.drain(t_now=100.5)
    assert ev.dtype == EVENT_DTYPE and len(ev) == 1000 and buf.dropped == 0
    i, want = expected(0, 1000, 7)
    np.testing.assert_array_equal(ev["rock"], i)  # sorted by step, rock, vehicle whatever order threads took
    for key, value in want.items():
        np.testing.assert_allclose(ev[key], value, rtol=1e-6 if which == "f32" else 1e-15, err_msg=key)
    np.testing.assert_allclose(ev["point"], np.stack([i, -i, 0.5 * i], 1), rtol=1e-6)
    np.testing.assert_allclose(ev["time"], 100.25 + DT * (np.arange(1000) % 7), atol=1e-6)
    assert len(buf.drain()) == 0  # nothing new
    emit(buf, 10, 5000, 8, 0.0)
    emit(buf, 5, 6000, 9, 0.125)
    ev = buf.drain()
    assert list(ev["step"]) == [8] * 10 + [9] * 5 and list(ev["rock"][:3]) == [5000, 5001, 5002]
    np.testing.assert_allclose(ev["time"][10:] - DT * (np.arange(5) % 7), 100.625, atol=1e-6)


def test_overflow_is_counted_not_hidden(buffers):
    buf = buffers["small"]
    buf.reset()
    emit(buf, 100, 0, 1, 0.0)
    ev = buf.drain()
    assert len(ev) == 64 and buf.dropped == 36
    assert len(set(ev["rock"])) == 64 and set(ev["rock"]) <= set(range(100))
    emit(buf, 10, 0, 2, 0.0)
    assert len(buf.drain()) == 10 and buf.dropped == 36  # the count is kept over drains
    buf.reset()
    assert buf.dropped == 0


def _rss() -> int:
    with open(f"/proc/{os.getpid()}/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_memory_stays_flat_over_many_drains(buffers):
    """2,000 append-and-drain rounds of 1,000 events (~170 MB of events in all) grow the process by less than
    the events of 100 rounds would take if they were kept."""
    buf = buffers["f64"]
    buf.reset()
    for _ in range(50):  # warm up: compiled kernels, allocator pools
        emit(buf, 1000, 0, 1, 0.0)
        buf.drain()
    before = _rss()
    total = 0
    for k in range(2000):
        emit(buf, 1000, k, k, 0.0)
        total += len(buf.drain(t_now=0.001 * k))
    assert total == 2_000_000
    grown = _rss() - before
    assert grown < 100 * 1000 * EVENT_DTYPE.itemsize, grown
