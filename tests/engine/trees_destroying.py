"""The cases of engine/trees.py that destroy SNode trees, run by tests/engine/test_trees.py in a pytest process of
their own: destroying a tree makes every kernel compiled in the process compile again (Taichi 1.7.4), which
would slow every later test of the same process. Not collected by the suite itself (no test_ prefix)."""

import gc

import numpy as np
import pytest

from taichi_rocks.engine import trees as T


class _Owner:
    pass


def test_destroyed_trees_are_reused_past_taichis_limit(taichi_cpu):
    """600 trees made and destroyed one after another, every 100th and the last used by a kernel: more than
    Taichi's 512, so this holds only if destroy() gives the tree back (without it the process crashes at the
    first launch past about 500 trees)."""
    import taichi as ti

    base = T.live_trees()
    for i in range(600):
        t = T.FieldTrees()
        f = t.scalar(ti.i32, 3)
        if i % 100 == 0 or i == 599:
            f.from_numpy(np.array([i, 1, 2], np.int32))
            assert f[0] == i
        assert T.live_trees() == base + 1
        t.destroy()
        t.destroy()  # idempotent
        assert T.live_trees() == base


def test_released_and_collected_trees_wait_for_pressure_then_go_together(taichi_cpu, monkeypatch):
    """Destroying a tree recompiles every kernel of the process, so trees an owner is done with (released, or
    whose owner was collected) are only retired, and destroyed together when the live trees pass the soft
    limit, at an allocation."""
    import taichi as ti

    base, base_retired = T.live_trees(), T.retired_trees()
    owner = _Owner()
    t = T.FieldTrees(owner=owner)
    t.vector(3, ti.f32, 4)
    t.image(5, 3, (1, ti.i64), (2, ti.i64))
    u = T.FieldTrees()
    u.scalar(ti.i32, 2)
    assert t.count == 2 and T.live_trees() == base + 3
    fresh = u.release()
    assert fresh.count == 0 and T.retired_trees() == base_retired + 1
    del owner
    gc.collect()
    assert T.retired_trees() == base_retired + 3 and T.live_trees() == base + 3  # retired, not destroyed
    T.FieldTrees().scalar(ti.i32)  # no pressure: nothing destroyed
    assert t.count == 2 and u.count == 1
    monkeypatch.setattr(T, "SOFT_LIMIT", T.live_trees())
    k = T.FieldTrees()
    k.scalar(ti.i32)  # past the soft limit: the retired trees go first
    assert t.count == 0 and u.count == 0 and T.retired_trees() == 0
    k.destroy()


def test_image_layout_is_indexed_x_y(taichi_cpu):
    import taichi as ti

    t = T.FieldTrees()
    img = t.image(7, 2, (4, ti.u8))
    assert img.shape == (7, 2)
    a = np.arange(7 * 2 * 4, dtype=np.uint8).reshape(7, 2, 4)
    img.from_numpy(a)
    assert np.array_equal(img.to_numpy(), a)
    t.destroy()


def test_allocation_past_the_hard_limit_is_an_error_not_a_crash(taichi_cpu, monkeypatch):
    import taichi as ti

    monkeypatch.setattr(T, "HARD_LIMIT", T.live_trees() + 1)
    keep = T.FieldTrees()
    keep.scalar(ti.i32)
    with pytest.raises(RuntimeError, match="SNode trees"):
        keep.scalar(ti.i32)
    with pytest.raises(RuntimeError, match="SNode trees"):
        T.FieldTrees().field(ti.f32, 4)  # a batch is refused before it starts
    keep.destroy()
    monkeypatch.undo()
    f = T.FieldTrees().scalar(ti.i32, 2)  # the refusals left nothing half-made for the next launch to trip on
    f.fill(3)
    assert f.to_numpy().tolist() == [3, 3]


class _Buffers:
    """An object of fields leased from a Pool, as the renderer's buffers and dust's fields are (engine/trees.py)."""

    def __init__(self, n: int):
        import taichi as ti

        self.trees = T.FieldTrees()
        self.a = self.trees.field(ti.f32, (n, 3))
        self.trees.finalize()
        self.owner = None


def test_a_pool_gives_back_released_objects_under_pressure(taichi_cpu, monkeypatch):
    """Released objects stay pooled (no recompile for the next owner of their layout) until the live trees pass
    the soft limit; then the next allocation destroys them, and an object in use is never touched."""
    import taichi as ti

    pool = T.Pool()
    held, dropped = _Owner(), _Owner()
    b_held = pool.lease(held, 13, lambda: _Buffers(13))
    b_dropped = pool.lease(dropped, 13, lambda: _Buffers(13))
    assert b_held is not b_dropped
    del dropped
    gc.collect()
    assert b_dropped.trees.count > 0  # released but kept
    again = _Owner()
    assert pool.lease(again, 13, lambda: _Buffers(13)) is b_dropped  # handed on
    del again
    gc.collect()
    monkeypatch.setattr(T, "SOFT_LIMIT", T.live_trees())
    T.FieldTrees().scalar(ti.i32)  # any allocation past the soft limit runs the evictors
    assert b_dropped.trees.count == 0 and b_held.trees.count > 0
    b_held.a.from_numpy(np.ones((13, 3), np.float32))  # still usable
    assert float(b_held.a.to_numpy().sum()) == 39.0
    other = _Owner()
    b_new = pool.lease(other, 13, lambda: _Buffers(13))  # not the destroyed one
    assert b_new is not b_dropped and b_new is not b_held
    del held
    gc.collect()
