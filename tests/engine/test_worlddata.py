"""A World's fields from Python (engine/worlddata.py ``HostField``): what is written is read back with every bit
(subnormals, signed zeros, the largest values, NaN payloads, the extreme integers), in both precisions and every
group (scalars, 3- and 4-vectors, rows of int32, real and float64 scalars, int64), whole or part of the entries,
an entry at a time too; a write of some entries leaves the others and every other field as they were; a wrong
shape or index is refused."""

import numpy as np
import pytest
import taichi as ti

from taichi_rocks.engine.world import World

pytestmark = pytest.mark.usefixtures("taichi_cpu")

N = 37
# a field of each group and row kind: name -> (group, components)
KINDS = {"pos": "r3", "rock_id": "i1", "radius": "r1", "tire_box": "r4", "ts_key": "i1 x2", "target_box": "r1 x6",
         "step_frame": "d1 x2", "launches": "l1"}


def _world(real):
    return World(N, real, hash_table=101, hash_entries=N, n_tires=3, ray_capacity=4, tiles=(2, 2), tile_size=0.5,
                 store=(0.5, 4, 8, True), bodies=(2, 3), events=8)


def _nasty(f, rng):
    """Random values of the field's shape, with the values a conversion would change at the front."""
    shape = f.shape + ((f.n,) if f.n > 1 else ())
    if f.np_dtype.kind == "i":
        info = np.iinfo(f.np_dtype)
        a = rng.integers(info.min, info.max, shape, dtype=f.np_dtype, endpoint=True)
        front = (info.min, info.max)
    else:
        info = np.finfo(f.np_dtype)
        a = rng.normal(0.0, 1e6, shape).astype(f.np_dtype)
        bits = "u4" if f.np_dtype == np.float32 else "u8"
        nan = np.array(0x7FC0_1234 if bits == "u4" else 0x7FF8_0000_0000_1234, bits).view(f.np_dtype)  # a payload
        front = (info.tiny / 4, -0.0, info.max, -info.max, nan)  # a subnormal, a signed zero, ...
    flat = a.reshape(-1)
    k = min(len(front), flat.size)
    flat[:k] = np.array(front, f.np_dtype)[:k]
    return a


@pytest.mark.parametrize("real", [ti.f32, ti.f64], ids=["f32", "f64"])
def test_host_fields_keep_every_bit(real):
    w = _world(real)
    rng = np.random.default_rng(5)
    fields = {name: getattr(w, name) for name in KINDS}
    assert {name: (f.n, f.np_dtype.kind) for name, f in fields.items()} == {
        "pos": (3, "f"), "rock_id": (1, "i"), "radius": (1, "f"), "tire_box": (4, "f"), "ts_key": (2, "i"),
        "target_box": (6, "f"), "step_frame": (2, "f"), "launches": (1, "i")}
    assert fields["step_frame"].np_dtype == np.float64 and fields["launches"].np_dtype == np.int64
    values = {name: _nasty(f, rng) for name, f in fields.items()}
    for name, f in fields.items():
        f.from_numpy(values[name])
    for name, f in fields.items():  # every field whole, after all were written: none wrote over another
        got = f.to_numpy()
        assert got.dtype == f.np_dtype and got.shape == values[name].shape, name
        assert got.tobytes() == values[name].tobytes(), name
    for name, f in fields.items():  # part of the entries, flat: the first, some in the middle, none
        flat = values[name].reshape((f.entries,) + values[name].shape[len(f.shape):])
        for first, count in ((0, f.entries), (1, min(3, f.entries - 1)), (f.entries // 2, 0)):
            assert f.read(first, count).tobytes() == flat[first:first + count].tobytes(), (name, first, count)
    # a write of some entries leaves the others, and the other fields, as they were
    pos, fresh = fields["pos"], _nasty(fields["pos"], np.random.default_rng(6))[:4]
    pos.write(5, fresh)
    want = values["pos"].copy()
    want[5:9] = fresh
    assert pos.to_numpy().tobytes() == want.tobytes()
    for name, f in fields.items():
        if name != "pos":
            assert f.to_numpy().tobytes() == values[name].tobytes(), name
    # an entry at a time: a NumPy value (a vector's components, a scalar's number), written back the same
    assert np.asarray(pos[7]).tobytes() == want[7].tobytes() and isinstance(fields["launches"][None], int)
    pos[7] = [1.5, -0.0, 2.0]
    fields["launches"][None] = 2 ** 40 + 3
    fields["ts_key"][-1] = (-2 ** 31, 7)
    assert pos[7].tolist() == [1.5, 0.0, 2.0] and np.signbit(pos[7][1])
    assert fields["launches"][None] == 2 ** 40 + 3 and fields["ts_key"][-1].tolist() == [-2 ** 31, 7]
    fields["radius"].fill(0.25)
    assert np.all(fields["radius"].to_numpy() == 0.25)
    assert fields["rock_id"].to_numpy().tobytes() == values["rock_id"].tobytes()


def test_host_fields_refuse_wrong_shapes_and_indices():
    w = _world(ti.f32)
    with pytest.raises(ValueError, match="pos"):
        w.pos.from_numpy(np.zeros((N, 4), np.float32))
    with pytest.raises(IndexError, match="pos"):
        w.pos[N]
    with pytest.raises(IndexError, match="ray"):
        w.ray[0]  # two dimensions, one index
    assert np.asarray(w.pos[-1]).shape == (3,) and w.ray[2, 0] == 0.0


def test_a_world_field_indexed_in_a_plain_kernel_is_refused():
    """A plain kernel that indexes a World's field would read it once, as it compiles, and keep that value as a
    constant: refused (a world kernel reads it at every launch, engine/view.py)."""
    w = _world(ti.f32)

    @ti.kernel
    def read() -> ti.f32:
        return w.par[0]

    with pytest.raises(Exception, match="world kernel"):
        read()
