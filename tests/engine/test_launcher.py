"""engine/launcher.py: a kernel launched through a Launcher does what Taichi's own call does (same writes, same
returned value) for every kind of argument the engine's hot kernels take, takes Taichi's own path for the rest,
and builds its launch context again when Taichi drops its compiled kernels."""

import numpy as np
import pytest
import taichi as ti
from taichi.lang import impl

from taichi_rocks.engine.launcher import Launcher
from taichi_rocks.engine.trees import FieldTrees

pytestmark = pytest.mark.usefixtures("taichi_cpu")

vec2 = ti.types.vector(2, ti.f64)


@ti.data_oriented
class Box:
    def __init__(self, n):
        self.trees = FieldTrees()  # owned, as every field of the package (engine/trees.py)
        self.a = self.trees.field(ti.f32, (n,))
        self.count = self.trees.field(ti.i32, ())
        self.trees.finalize()


@ti.kernel
def _fill(box: ti.template(), k: ti.i32, x: ti.f64, rows: ti.types.ndarray(dtype=vec2, ndim=1),
          out: ti.types.ndarray(dtype=ti.f64, ndim=2)) -> ti.i32:
    for i in range(box.a.shape[0]):
        box.a[i] = ti.cast(x * i + k, ti.f32)
    total = 0
    for j in range(rows.shape[0]):
        out[j, 0] = rows[j][0] * x
        out[j, 1] = rows[j][1] + k
        total += 1
    box.count[None] += total
    return total + k


@ti.kernel
def _scaled(m: ti.types.vector(2, ti.f32)) -> ti.f32:  # a matrix-typed argument: Taichi's own path
    return m[0] * m[1]


def _call(fn, box, k, x, rows, out):
    return fn(box, k, x, rows, out)


def test_the_same_writes_and_value_as_taichis_call():
    a, b = Box(17), Box(17)
    fast = Launcher(_fill)
    rng = np.random.default_rng(1)
    for k, x, n in ((3, 0.5, 4), (-7, 1e-3, 1), (0, -2.25, 9), (2**31 - 10, 3.0, 0)):
        rows = rng.normal(size=(n, 2))
        out_a, out_b = np.full((max(n, 1), 2), np.nan), np.full((max(n, 1), 2), np.nan)
        got = fast(a, k, x, rows, out_a)
        want = _fill(b, k, x, rows, out_b)
        assert got == want == n + k
        assert np.array_equal(out_a, out_b, equal_nan=True)
        assert np.array_equal(a.a.to_numpy(), b.a.to_numpy()) and a.count[None] == b.count[None]


def test_another_dtype_or_layout_takes_taichis_path():
    box = Box(4)
    fast = Launcher(_fill)
    out = np.zeros((3, 2))
    assert fast(box, 1, 1.0, np.ones((3, 2)), out) == 4
    # float32 rows: another compiled instance, which Taichi's path makes
    assert fast(box, 1, 1.0, np.ones((3, 2), np.float32), out) == 4
    # not contiguous: Taichi's path (which refuses it as it always did, or copies a Fortran-ordered one)
    rows = np.ones((3, 4))[:, ::2]
    with pytest.raises(ValueError, match="contiguous"):
        fast(box, 1, 1.0, rows, out)
    assert Launcher(_scaled)(ti.Vector([2.0, 3.0])) == pytest.approx(6.0)


def test_a_plain_function_is_called_as_it_is():
    seen = []
    fast = Launcher(lambda *a: seen.append(a) or len(a))
    assert fast(1, 2, 3) == 3 and seen == [(1, 2, 3)]


def test_it_binds_again_after_taichi_drops_its_kernels():
    """Destroying an SNode tree clears every compiled kernel (engine/trees.py): the launcher's context must not
    outlive the instance it was made for."""
    box = Box(5)
    fast = Launcher(_fill)
    out = np.zeros((2, 2))
    assert fast(box, 1, 2.0, np.ones((2, 2)), out) == 3
    first = next(iter(fast._bound.values())).t_kernel
    impl.get_runtime().clear_compiled_functions()
    assert fast(box, 2, 2.0, np.ones((2, 2)), out) == 4
    assert next(iter(fast._bound.values())).t_kernel is not first
    assert np.array_equal(box.a.to_numpy(), np.arange(5, dtype=np.float32) * 2 + 2)


def test_two_template_arguments_two_contexts():
    a, b = Box(3), Box(3)
    fast = Launcher(_fill)
    out = np.zeros((1, 2))
    fast(a, 1, 1.0, np.ones((1, 2)), out)
    fast(b, 5, 1.0, np.ones((1, 2)), out)
    assert len(fast._bound) == 2
    assert a.a.to_numpy()[0] == 1 and b.a.to_numpy()[0] == 5


def test_a_compile_between_two_launches_changes_nothing():
    """Taichi hands the compiled code as a reference into its cache, which a later compile may move: a launch
    after another instance compiled must still run its own code (it wrote garbage when the launcher kept it)."""
    a = Box(6)
    fast = Launcher(_fill)
    out = np.zeros((1, 2))
    assert fast(a, 1, 1.0, np.ones((1, 2)), out) == 2
    for k in range(3):  # new instances compile in between: of this kernel (another template) and another one
        Launcher(_scaled)(ti.Vector([1.0 + k, 2.0]))
        _fill(Box(6 + k), k, 0.5, np.ones((1, 2)), np.zeros((1, 2)))
    assert fast(a, 2, 1.0, np.ones((1, 2)), out) == 3
    assert np.array_equal(a.a.to_numpy(), np.arange(6, dtype=np.float32) + 2)


def test_device_arrays_set_again_at_every_launch():
    """A launch turns a device array's handle in the context into its address: the same context launched again
    with the same array, or with another of the same features, must write where it should."""
    from taichi_rocks.engine.worlddata import HostField, copy_launchers

    copies = copy_launchers()
    a, b = ti.ndarray(ti.f32, 8), ti.ndarray(ti.f32, 8)
    fa = HostField("a", a, 0, 0, (8,), np.float32, 1, copies)
    fb = HostField("b", b, 2, 0, (4,), np.float32, 1, copies)
    for k in range(4):  # the same array, then another through the same bound context
        fa[k] = k + 0.5
        fb[k] = -k - 1.0
    assert np.array_equal(fa.to_numpy(), [0.5, 1.5, 2.5, 3.5, 0, 0, 0, 0])
    assert np.array_equal(b.to_numpy(), [0, 0, -1, -2, -3, -4, 0, 0])


def test_each_instance_gets_its_own_context(monkeypatch):
    """Arrays of two element types are two compiled instances of one kernel: after the first call of each, the
    launcher launches both itself (Taichi's own call, ten times the cost, is not taken again)."""
    from taichi_rocks.engine.worlddata import HostField, copy_launchers

    copies = copy_launchers()
    fa = HostField("a", ti.ndarray(ti.f32, 4), 0, 0, (4,), np.float32, 1, copies)
    fb = HostField("b", ti.ndarray(ti.i32, 4), 0, 0, (4,), np.int32, 1, copies)
    fa[0], fb[0] = 1.0, 1
    monkeypatch.setattr(Launcher, "_primal_call", lambda self, args: pytest.fail("Taichi's own call was taken"))
    for k in range(3):
        fa[k + 1], fb[k + 1] = k + 2.0, k + 2
    assert list(fa.to_numpy()) == [1, 2, 3, 4] and list(fb.to_numpy()) == [1, 2, 3, 4]
