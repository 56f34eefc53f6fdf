"""The declaration of the per-rock fields (engine/rockfields.py) and what is derived from it: every field
round-trips through checkpoints and through the tiles in both stepping modes; a field added to the declaration
(a dummy, in a test layout) is allocated, carried with its rock through the tiles, the active list's compaction
and the re-sort, saved and restored, reported by state() and counted by the memory estimate; the in-kernel
count of flying rocks against NumPy; the memory estimate against the bytes the World's fields take."""

import numpy as np
import pytest

from scenes_util import scene
from taichi_rocks.bench.activity import field_bytes
from taichi_rocks.config.scene import SceneError, scene_with
from taichi_rocks.engine import rockfields
from taichi_rocks.engine.layout import EXACT_UP_TO, check_fits, estimate_memory, world_layout
from taichi_rocks.engine.rockfields import FLYING, ID, RESTING, ROCK_FIELDS, SLIDING, RockField, present
from taichi_rocks.engine.setup import initial_rocks
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.world import field_specs
from taichi_rocks.config.plan import Plan

pytestmark = pytest.mark.usefixtures("taichi_cpu")

CAR = {"length": 4.0, "width": 1.8, "wheelbase": 2.6, "track": 1.5, "tire_radius": 0.33}
VEHICLES = [{"name": "lead", **CAR, "path": {"points": [[6.0, 0.0], [406.0, 0.0]], "speed": 20.0}},
            {"name": "player", **CAR, "splash": False, "path": {"points": [[0.0, 0.0], [400.0, 0.0]], "speed": 20.0}}]
# the scene of test_active's "straight" case: its layouts' kernels are compiled once
BASE = scene(rocks=3000, radius=6.0, bed={"follow": "player"}, sim={"detection": "patch", "dt": 0.004},
             vehicles=VEHICLES)
MODES = {"active": {"sim.stepping": "active"},
         "full": {"sim.stepping": "full", "sim.hash.scope": "all", "sim.hash.reorder_every": 8}}  # re-sorted


def test_the_declaration_is_consistent():
    names = [f.name for f in ROCK_FIELDS]
    assert len(set(names)) == len(names) and ID in names
    for f in ROCK_FIELDS:
        assert f.dtype in rockfields.DTYPES and f.n >= 1
        assert f.stored or not f.carried or f.rest is not None
    with pytest.raises(ValueError, match="rest value"):
        RockField("spin", "real", 3, stored=False)
    with pytest.raises(ValueError, match="scratch"):
        RockField("tmp", "i32", stored=False, carried=False)
    splash = {f.name for f in present(Plan.from_scene(BASE), "active")}
    dry = {f.name for f in present(Plan.from_scene(scene_with(BASE, {"effects.splash": False})), "full")}
    assert {"hit_step", "slot"} <= splash and not {"hit_step", "slot"} & dry and "pos" in dry


def _rocks_of(data):
    return {k: v for k, v in data.items() if k.startswith("rock_")}


def _assert_same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert np.asarray(a[k]).dtype == np.asarray(b[k]).dtype, k
        assert np.asarray(a[k]).tobytes() == np.asarray(b[k]).tobytes(), k


@pytest.mark.parametrize("into", ["active", "full"])
@pytest.mark.parametrize("source", ["active", "full"])
def test_every_saved_field_round_trips_through_checkpoints_and_tiles(source, into):
    """A checkpoint with new values in every stored field (rocks in flight, sliding and resting), restored into
    either mode, comes back bit for bit; one step later (active stepping: the resting rocks have gone through
    the tiles) it is the state full stepping reaches from it."""
    sim = Simulation(scene_with(BASE, MODES[source]))
    sim.step(60)
    data = sim.checkpoint()
    phase = data["rock_phase"]
    assert (phase == FLYING).any() and (phase == RESTING).any()
    rng = np.random.default_rng(5)
    n = sim.n_rocks
    data["rock_friction"] = rng.uniform(0.2, 0.9, n).astype(data["rock_friction"].dtype)
    data["rock_hit_step"] = rng.integers(-1, 60, n).astype(np.int32)
    del sim
    other = Simulation(scene_with(BASE, MODES[into]))
    other.restore(data)
    _assert_same(_rocks_of(other.checkpoint()), _rocks_of(data))
    if into == "active":
        other.step()
        assert other.active_count < n // 4  # most rocks went through the tiles
        ref = Simulation(scene_with(BASE, MODES["full"]))
        ref.restore(data)
        ref.step()
        _assert_same(_rocks_of(other.checkpoint()), _rocks_of(ref.checkpoint()))


@pytest.fixture
def dummy_fields(monkeypatch):
    """Two fields added to the declaration: a stored int ("tag") and a 2-vector the tiles do not keep
    ("glow", rest value 0.25), which state() reports."""
    extra = (RockField("tag", "i32", initial=7), RockField("glow", "real", 2, stored=False, rest=0.25, initial=0.25,
                                                               state="glow"))
    monkeypatch.setattr(rockfields, "ROCK_FIELDS", ROCK_FIELDS + extra)
    return extra


@pytest.mark.parametrize("mode", ["active", "full"])
def test_a_field_added_to_the_declaration_is_carried_everywhere(dummy_fields, mode):
    sim = Simulation(scene_with(BASE, MODES[mode]))
    w = sim.world
    assert {"tag", "glow"} <= {f.name for f in w.rocks} and hasattr(w, "tag")
    assert hasattr(w, "ts_tag") == (mode == "active") and not hasattr(w, "ts_glow")
    assert estimate_memory(sim.scene) == field_bytes(w)
    r = sim.rock_arrays()
    assert np.all(r["tag"] == 7) and np.all(r["glow"] == np.float32(0.25))
    sim.step(30)
    data = sim.checkpoint()
    assert "rock_tag" in data and "rock_glow" in data
    n = sim.n_rocks
    rng = np.random.default_rng(11)
    tag = rng.integers(-1000, 1000, n).astype(np.int32)
    glow = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
    data["rock_tag"], data["rock_glow"] = tag, glow
    sim.restore(data)
    r = sim.rock_arrays()
    np.testing.assert_array_equal(r["tag"], tag)
    np.testing.assert_array_equal(r["glow"], glow)  # every rock as restored, until a step
    sim.step()
    r = sim.rock_arrays()
    moving = r["phase"] != RESTING
    rest = ~moving & (data["rock_phase"] == RESTING)
    np.testing.assert_array_equal(r["tag"], tag)
    if mode == "active":  # the resting rocks went into the tiles, which do not keep "glow"
        assert np.all(r["glow"][rest] == np.float32(0.25)) and rest.sum() > n // 2
        np.testing.assert_array_equal(r["glow"][moving], glow[moving])
    else:
        np.testing.assert_array_equal(r["glow"], glow)
    launches = sim.launches_total
    sim.step(120)  # rocks launched, landed, stored, recycled; the active list compacted / the rocks re-sorted
    assert sim.launches_total > launches
    np.testing.assert_array_equal(sim.rock_arrays()["tag"], tag)
    g = sim.state()["glow"]
    assert g.shape == (n, 2)
    if mode == "full":  # in memory order of the slots now, each rock's values with it
        assert not np.array_equal(w.rock_id.to_numpy()[:n], np.arange(n))
        np.testing.assert_array_equal(g, glow)
    else:  # a rock's own value, or the rest value once it has been in a tile
        assert np.all((g == glow).all(axis=1) | (g == np.float32(0.25)).all(axis=1))


@pytest.mark.parametrize("mode", ["active", "full"])
def test_rocks_in_air_is_counted_in_a_kernel(mode):
    """Simulation.rocks_in_air against NumPy: none, all, one, and random phases."""
    sim = Simulation(scene_with(BASE, {"sim.stepping": mode}))
    n = sim.n_rocks
    rng = np.random.default_rng(2)
    cases = [np.zeros(n, int), np.full(n, FLYING), np.where(np.arange(n) == n - 1, FLYING, RESTING),
             rng.choice([RESTING, FLYING, SLIDING], n, p=[0.7, 0.2, 0.1])]
    for phase in cases:
        sim.set_rocks(np.arange(n), phase=phase)
        expect = int(np.count_nonzero(phase == FLYING))
        assert sim.rocks_in_air() == expect == int(np.count_nonzero(sim.state()["phase"] == FLYING))
    sim.step(40)
    assert sim.rocks_in_air() == int(np.count_nonzero(sim.state()["phase"] == FLYING))


VARIANTS = [{}, {"sim.stepping": "full"}, {"sim.hash.insert": "aabb", "sim.hash.cell_size": "min_radius"},
            {"sim.stepping": "full", "sim.precision": "f64", "sim.hash.scope": "all"}, {"effects.splash": False},
            {"bed.rocks": 0}]


@pytest.mark.parametrize("over", VARIANTS, ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()) or "default")
def test_memory_estimate_is_the_bytes_of_the_fields(over):
    sc = scene_with(BASE, over)
    sim = Simulation(sc)
    assert estimate_memory(sc) == field_bytes(sim.world)


def test_memory_estimate_grows_with_what_is_allocated():
    base = estimate_memory(BASE)
    assert estimate_memory(scene_with(BASE, {"bed.rocks": 6000})) > base  # the tiles' edge is a power of two
    full = {"sim.stepping": "full"}
    assert estimate_memory(scene_with(BASE, {**full, "bed.rocks": 6000})) > 1.9 * estimate_memory(scene_with(BASE, full))
    assert estimate_memory(scene_with(BASE, {"sim.precision": "f64"})) > base
    assert estimate_memory(scene_with(BASE, {"sim.hash.insert": "aabb", "sim.hash.cell_size": "min_radius"})) > 2 * base
    full = estimate_memory(scene_with(BASE, {"sim.stepping": "full"}))
    assert full < base  # the tile store is the bigger part with active stepping
    per_rock = sum(f.n * (4 if f.dtype in ("real", "i32") else 8) for f in present(Plan.from_scene(BASE), "full"))
    assert full > per_rock * BASE.bed.rocks


def test_memory_estimate_extrapolates_aabb_entries_past_the_exact_limit():
    sc = scene_with(BASE, {"bed.rocks": EXACT_UP_TO + 4321, "sim.hash.insert": "aabb",
                           "sim.hash.cell_size": "min_radius"})
    plan = Plan.from_scene(sc)
    layout, _ = world_layout(sc, plan, initial_rocks(sc).radius)
    exact = sum(s.nbytes("f32") for s in field_specs(sc.bed.rocks, "f32", **layout))
    assert abs(estimate_memory(sc) - exact) < 0.01 * exact


def test_a_scene_too_big_for_the_machine_is_refused_in_one_line_before_anything_is_allocated():
    huge = scene_with(BASE, {"bed.rocks": 10 ** 12})
    with pytest.raises(SceneError) as info:
        check_fits(huge)
    [line] = info.value.problems
    assert line.startswith("<test>: bed.rocks: needs about ") and "more than this machine has" in line
    with pytest.raises(SceneError):
        Simulation(huge)
