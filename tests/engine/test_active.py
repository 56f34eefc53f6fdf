"""Active stepping (engine/active.py) against full stepping, the reference: the same launches, recycles and
states, bit for bit, over straight, turning, reversing, parked, coasting, jumping and far-from-origin scenes;
the bookkeeping of the tiles and the active list after every step of randomised scenes; uniform density."""

import numpy as np
import pytest

from scenes_util import FakePath, scene, uniformity_pvalue
from taichi_rocks.config.keys import choices
from taichi_rocks.config.scene import scene_with
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.world import FLYING, RESTING

pytestmark = pytest.mark.usefixtures("taichi_cpu")

CAR = {"length": 4.0, "width": 1.8, "wheelbase": 2.6, "track": 1.5, "tire_radius": 0.33}


def _lead_and_player(points, speed, lead_offset=6.0, **path):
    """A splashing car ``lead_offset`` m ahead of the (non-splashing) player the bed follows, on parallel
    straight paths through ``points`` (2 points)."""
    (x0, y0), (x1, y1) = points
    d = np.array([x1 - x0, y1 - y0]) / np.hypot(x1 - x0, y1 - y0)
    ahead = lambda p: [p[0] + lead_offset * d[0], p[1] + lead_offset * d[1]]
    return [{"name": "lead", **CAR, "path": {"points": [ahead((x0, y0)), ahead((x1, y1))], "speed": speed, **path}},
            {"name": "player", **CAR, "splash": False, "path": {"points": [[x0, y0], [x1, y1]], "speed": speed, **path}}]


def _circle(speed):
    return [{"name": "lead", **CAR, "path": {"kind": "circle", "center": [0.0, 0.0], "radius": 9.0, "speed": speed}},
            {"name": "player", **CAR, "splash": False,
             "path": {"kind": "circle", "center": [0.0, 0.0], "radius": 9.0, "speed": speed, "start_angle": -40.0}}]


BASE = dict(rocks=3000, radius=6.0, bed={"follow": "player"}, sim={"detection": "patch", "dt": 0.004})


def _case(name):
    """(scene, path override or None, steps)."""
    far = (123_456.0, -98_765.0)
    cases = {
        "straight": (scene(vehicles=_lead_and_player([[0, 0], [400, 0]], 20.0), **BASE), None, 150),
        "turning": (scene(vehicles=_circle(14.0), **BASE), None, 150),
        "reversing": (scene(vehicles=_lead_and_player([[0, 0], [400, 0]], 15.0, lead_offset=-6.0, reverse=True),
                            **BASE), None, 150),
        "parked": (scene(vehicles=_lead_and_player([[0, 0], [400, 0]], 0.0), **BASE), None, 60),
        "stopping": (scene(vehicles=_lead_and_player([[0, 0], [6, 0]], [18.0, 0.0]), **BASE), None, 200),
        "teleport": (scene(vehicles=_lead_and_player([[0, 0], [400, 0]], 20.0), **BASE),
                     lambda t: (0.0 if t < 0.2 else 40.0, 0.0, 0.0, 20.0), 120),
        "far": (scene(vehicles=_lead_and_player([far, (far[0] + 4000.0, far[1] + 300.0)], 40.0), **{
            **BASE, "sim": {"detection": "patch", "dt": 0.02}}), None, 200),  # > 128 m: the origin shifts
        "world-origin": (scene(vehicles=_lead_and_player([[3000.0, 0], [3400.0, 0]], 20.0), **{
            **BASE, "sim": {"detection": "patch", "dt": 0.004, "origin": "world"}}), None, 150),
        "ray-aabb-all": (scene(vehicles=_lead_and_player([[0, 0], [400, 0]], 20.0), **{
            **BASE, "sim": {"detection": "ray", "substeps": 2, "dt": 0.004,
                            "hash": {"insert": "aabb", "cell_size": "min_radius", "scope": "all",
                                     "reorder_every": 8}}}), None, 120),
        "no-recycle": (scene(vehicles=_lead_and_player([[0, 0], [400, 0]], 20.0), effects={"recycle": False},
                             **BASE), None, 100),
        "bed-only": (scene(vehicles=_lead_and_player([[0, 0], [400, 0]], 25.0), effects={"splash": False},
                           **BASE), None, 150),
    }
    return cases[name]


def _pair(sc, path):
    sims = [Simulation(scene_with(sc, {"sim.stepping": mode})) for mode in ("full", "active")]
    assert not sims[0].plan.active and sims[1].plan.active
    if path is not None:
        for s in sims:
            s.fleet.paths[s.follow] = FakePath(path)
    return sims


def _assert_same(full, act):
    a, b = full.state(), act.state()
    assert a["step"] == b["step"]
    for k in ("positions", "velocities", "radii", "phase", "bed_center", "vehicle_positions"):
        assert np.array_equal(a[k], b[k]), (k, a["step"], np.flatnonzero(np.any(np.atleast_2d(a[k] != b[k]), axis=-1))[:5])
        assert a[k].tobytes() == b[k].tobytes(), (k, "the same values, other bits (signed zeros)")
    assert (a["launches_total"], a["recycles_total"]) == (b["launches_total"], b["recycles_total"])
    return a


@pytest.mark.parametrize("name", ["straight", "turning", "reversing", "parked", "stopping", "teleport", "far",
                                  "world-origin", "ray-aabb-all", "no-recycle", "bed-only"])
def test_active_stepping_equals_full_stepping(name):
    sc, path, steps = _case(name)
    full, act = _pair(sc, path)
    launches = []
    for _ in range(steps // 10):
        full.step(10)
        act.step(10)
        launches.append(full.launches_total)
        st = _assert_same(full, act)
    act.check_health()
    if sc.effects.splash:  # every case throws rocks, except the parked and bed-only ones
        assert (launches[-1] > 0) == (name not in ("parked",)), launches
    if name == "far":
        assert np.any(full.origin != full.anchor), "the floating origin should have moved"
    if name == "teleport":
        assert st["recycles_total"] >= 0.9 * sc.bed.rocks  # the jump recycled the whole bed
    if name == "stopping":
        assert full.steps_coasted > 0 and act.steps_coasted > 0


def test_active_stepping_equals_full_with_advance_to_and_restore():
    sc, _, _ = _case("straight")
    full, act = _pair(sc, None)
    for s in (full, act):
        s.advance_to(0.2 + 1 / 30)  # whole steps, then a short one
    _assert_same(full, act)
    saved = act.checkpoint()
    for s in (full, act):
        s.step(40)
    _assert_same(full, act)
    del full, s  # one simulation at a time beside act
    other = Simulation(scene_with(sc, {"sim.stepping": "full"}))  # a checkpoint of one mode restores into the other
    other.restore(saved)
    other.step(40)
    _assert_same(other, act)


def _bookkeeping(sim):
    """Every rock in exactly one place (the active list or one tile), counts conserved, stored rocks resting on
    their tile inside the bed, the active list free of settled entries."""
    w, n = sim.world, sim.n_rocks
    m = sim.active_count
    ids_active = w.rock_id.to_numpy()[:m]
    counts = w.ts_count.to_numpy()
    cap = w.store_capacity
    assert counts.min() >= 0 and counts.max() <= cap
    taken = (np.arange(cap)[None, :] < counts[:, None]).ravel()
    ids_store = w.ts_rock_id.to_numpy()[taken]
    assert m + len(ids_store) == n
    everything = np.concatenate([ids_active, ids_store])
    assert np.array_equal(np.sort(everything), np.arange(n)), "a rock is missing or in two places"
    pos = w.ts_pos.to_numpy()[taken].astype(np.float64)
    slot = np.repeat(np.arange(len(counts)), counts)
    key = w.ts_key.to_numpy()[slot]
    s = w.store_tile
    local_key = np.floor(pos[:, :2] / s).astype(np.int64) + np.round(sim._host.shift / s).astype(np.int64)
    assert np.array_equal(local_key, key), "a stored rock is off its tile"
    g = w.store_grid
    assert np.array_equal((key[:, 0] % g) * g + key[:, 1] % g, slot), "a tile is in the wrong slot"
    c = sim._host.local_centre()
    assert np.hypot(pos[:, 0] - c[0], pos[:, 1] - c[1]).max(initial=0.0) <= sim.scene.bed.radius * (1 + 1e-6)
    phase = w.phase.to_numpy()[:m]
    # the active list holds the rocks in the air or sliding, and resting ones only when their tile was full
    resting_active = int(np.sum(phase == RESTING))
    assert resting_active <= max(1, int(0.01 * n)), resting_active


@pytest.mark.parametrize("seed", [1, 2])
def test_bookkeeping_holds_after_every_step_of_random_scenes(seed):
    rng = np.random.default_rng(seed)
    pts = np.cumsum(rng.uniform(-30, 30, (4, 2)), axis=0)
    speed = float(rng.uniform(5, 30))
    sc = scene(rocks=int(rng.integers(500, 3000)), radius=float(rng.uniform(2.0, 6.0)),
               vehicles=[{"name": "lead", **CAR, "path": {"points": pts.tolist(), "speed": speed}},
                         {"name": "player", **CAR, "path": {"points": (pts - [0.0, 3.0]).tolist(), "speed": speed}}],
               bed={"follow": "player", "rock_radius": [0.01, float(rng.uniform(0.02, 0.08))]},
               sim={"detection": str(rng.choice(list(choices("sim.detection")))), "dt": float(rng.uniform(0.002, 0.02))})
    sim = Simulation(sc)
    assert sim.plan.active
    flown = 0
    for _ in range(80):
        sim.step(1)
        _bookkeeping(sim)
        flown = max(flown, int(np.sum(sim.world.phase.to_numpy()[:sim.active_count] == FLYING)))
    assert sim.recycles_total > 0 and flown > 0


def test_density_stays_uniform_under_active_stepping():
    sim = Simulation(scene(rocks=12000, radius=6.0, effects={"splash": False}, sim={"dt": 0.01}))
    assert sim.plan.active
    sim.fleet.paths[0] = FakePath(lambda t: (25.0 * t if t < 2.0 else 50.0 + 1000.0 * (t > 3.0), 0.0, 0.0, 25.0))
    for k in range(8):
        sim.step(50)  # a drive of 50 m (every rock recycled ~4 times), a stop, a jump of 1 km
        st = sim.state()
        c = st["bed_center"][:2]
        assert uniformity_pvalue(st["positions"][:, :2], c, 6.0) > 1e-3
        assert sim.active_count == 0  # nothing flies without tires: every rock rests in a tile
