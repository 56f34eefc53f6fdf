"""The lookahead (engine/host.py) changes no bit: the tire rays every step hands the rock pass, and the
final state, are the same with the host side computed 32 steps at a time, step by step (``lookahead = 0``),
and by a reference copy of the step-by-step computation as it was before the lookahead (per-tire monotone
chain ``patch._hull``, per-step ``Fleet.rear_tires``), over the shipped scenes, the bench fleet scene,
restore() in the middle of a batch, advance_to with a short last step, a path that jumps, a floating-origin
shift in the middle of a batch, reversing, parked vehicles and coasting."""

import math

import numpy as np
import pytest

from scenes_util import FakePath, scene
from taichi_rocks.bench.scenes import fleet_scene
from taichi_rocks.config.scene import load_scene, scene_with
from taichi_rocks.engine import patch, simulation, steppers
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.world import ACTIVE, HALF_W, HULL, HULL_VERTICES, RAY_FIELDS

pytestmark = pytest.mark.usefixtures("taichi_cpu")


# ------------------------------------------------------------------------------------------ the reference
def _old_hulls(b0, f0, b1, f1, half_width, half_length):
    corners = np.concatenate([patch.footprint_corners(b0, f0, half_width, half_length),
                              patch.footprint_corners(b1, f1, half_width, half_length)], axis=1)
    out = np.zeros((len(corners), HULL_VERTICES, 2))
    for t, pts in enumerate(corners):
        h = patch._hull(pts)
        out[t, :len(h)] = h
        out[t, len(h):] = h[-1]
    return out


def _old_ray_data(sim, prev, cur, dt=0.0):
    """HostSide.ray_data as it was before the lookahead (one tire at a time through patch._hull)."""
    n_tires = sim.world.n_tires
    data = np.zeros((max(n_tires, 1), RAY_FIELDS))
    if n_tires == 0:
        return data
    h = sim._host
    o = np.array([h.shift[0], h.shift[1], 0.0])
    moved = np.linalg.norm(cur.center - prev.center, axis=1)
    speed = np.maximum(np.linalg.norm(cur.velocity, axis=1), np.linalg.norm(prev.velocity, axis=1))
    jumped = moved > 2.0 * speed * dt + 0.05
    data[:, 0:3] = np.where(jumped[:, None], cur.center, prev.center) - o
    data[:, 3:6] = np.where(jumped[:, None], cur.bottom, prev.bottom) - o
    data[:, 6:9] = cur.center - o
    data[:, 9:12] = cur.bottom - o
    data[:, 12:15] = cur.velocity
    data[:, 15:17] = cur.forward
    data[:, 17] = cur.spin
    b0 = np.where(jumped[:, None], cur.bottom, prev.bottom)
    f0 = np.where(jumped[:, None], cur.forward, prev.forward)
    hulls = _old_hulls(b0, f0, cur.bottom, cur.forward, cur.half_width, cur.half_length) - o[:2]
    head = np.column_stack([cur.half_width, cur.half_length, cur.radius, cur.fender, cur.flap])
    data[:, HALF_W:] = np.concatenate([head, hulls.reshape(len(hulls), -1)], axis=1)
    reach = sim.scene.bed.radius + 2.0 * float(sim.scene.bed.rock_radius[1]) + 2.0
    far = np.hypot(cur.center[:, 0] - h.bed_rel[0], cur.center[:, 1] - h.bed_rel[1]) > reach
    if far.any():
        lc = h.local_centre()
        park = np.array([lc[0], lc[1], sim.bed_center[2] - sim.origin[2] + 1000.0])
        data[far, 0:12] = np.tile(park, 4)
        data[far, HULL:] = np.tile(park[:2], (RAY_FIELDS - HULL) // 2)
        data[far, 17] = 0.0
    data[:, ACTIVE] = ~far
    return data


MODES = ("reference", "per step", "lookahead")


def _simulation(sc, mode, monkeypatch, paths=None):
    """A Simulation of ``sc`` in ``mode`` (MODES) whose rock pass records the rays of every step (full
    stepping: its rock pass is the kernel the rays are recorded at; both stepping modes share the host side)."""
    sim = Simulation(scene_with(sc, {"sim.stepping": "full"}))
    for i, fn in (paths or {}).items():
        sim.fleet.paths[i] = FakePath(fn)
    if mode == "reference":
        sim.lookahead = 0
        sim.fleet.rear_tires_table = None  # nothing may use the batched motion
        # set on this simulation's own host side (not through monkeypatch, which would keep the simulation, and
        # so its World, alive to the end of the test)
        sim._host_side.ray_data = lambda st, prev, cur, dt=0.0: _old_ray_data(sim, prev, cur, dt)
    elif mode == "per step":
        sim.lookahead = 0
    sim.recorded = []
    return sim


@pytest.fixture
def recording(monkeypatch):
    """Every rock pass launch's rays, as bytes, into the simulation's ``recorded`` (the pass still runs)."""
    sims = {}
    real = steppers.rock_pass

    def rock_pass(w, plan, rays, frame, dt, step):
        owner = sims.get(id(w))
        if owner is not None:
            owner.recorded.append((step, np.ascontiguousarray(rays).tobytes(), frame.tobytes(), dt))
        return real(w, plan, rays, frame, dt, step)

    monkeypatch.setattr(steppers, "rock_pass", rock_pass)

    def make(sc, mode, paths=None):
        sims.clear()  # one simulation at a time (sims maps a World to its Simulation)
        sim = _simulation(sc, mode, monkeypatch, paths)
        sims[id(sim.world)] = sim
        return sim

    return make


def _final(sim):
    st = sim.state()
    return {k: np.asarray(v).tobytes() for k, v in st.items() if k != "vehicle_names"}, \
        sim.world.pos.to_numpy().tobytes(), sim.world.vel.to_numpy().tobytes()


def _run_modes(recording, sc, drive, paths=None):
    """``drive(sim)`` in every mode; the recorded rays, frames and final states must all be equal."""
    runs = []
    for mode in MODES:
        sim = recording(sc, mode, paths)
        drive(sim)
        runs.append((mode, sim.recorded, _final(sim), sim._host_side.ahead.batches))
        del sim  # in a cycle (the reference mode's patch): the next make() collects it and takes its World
    (_, ref, ref_final, ref_batches), rest = runs[0], runs[1:]
    assert len(ref) > 50, "the drive took too few steps to say anything"
    assert ref_batches == 0
    for mode, rec, fin, batches in rest:
        assert len(rec) == len(ref), mode
        bad = [k for k, (a, b) in enumerate(zip(ref, rec)) if a != b]
        assert not bad, f"{mode}: steps {[ref[k][0] for k in bad[:5]]} differ ({len(bad)} of {len(ref)})"
        assert fin == ref_final, mode
        if mode == "lookahead":
            assert batches >= 1 and batches < len(rec), batches  # batches were used, more than a step each
    return runs


# ------------------------------------------------------------------------------------------ scenes
SHIPPED = ("circle", "convoy", "minimal", "slalom")


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scene_rays_bit_identical(recording, scenes_dir, name):
    """150 steps of each shipped scene (fewer rocks: the rays do not depend on them)."""
    sc = scene_with(load_scene(scenes_dir / f"{name}.toml"), {"bed.rocks": 800})
    _run_modes(recording, sc, lambda sim: sim.step(150))


def test_bench_fleet_scene_rays_bit_identical(recording):
    """The speed study's fleet: 20 rear tires of 10 vehicles spread over the bed."""
    _run_modes(recording, fleet_scene(1000, 20, 30.0), lambda sim: sim.step(150))


def test_restore_in_the_middle_of_a_batch(recording):
    """A checkpoint, some steps, restore() to it in the middle of a batch, then on."""
    def drive(sim):
        sim.step(45)
        ck = sim.checkpoint()
        sim.step(20)
        sim.restore(ck)
        sim.step(70)
        sim.restore(ck)
        sim.step(3)

    _run_modes(recording, scene(rocks=2000, radius=6.0), drive)


def test_advance_to_with_a_short_last_step(recording):
    """Frames at 1/30 s with dt = 4 ms: each frame ends with a shorter step (8.33 whole steps a frame)."""
    def drive(sim):
        for f in range(1, 40):
            sim.advance_to(f / 30.0)

    runs = _run_modes(recording, scene(rocks=2000, radius=6.0), drive)
    dts = {rec[3] for rec in runs[0][1]}
    assert len(dts) > 1, "no short step was taken"


def test_path_that_jumps(recording):
    """A path that teleports (jumps of more than the bed's diameter) every 0.1 s while driving."""
    spots = [(0.0, 0.0), (13.0, 2.0), (13.0, 40.0), (-500.0, 40.0), (-480.0, 44.0)]

    def path(t):
        k = min(max(math.ceil((t - 0.3) / 0.1 - 1e-6), 0), len(spots) - 1)
        x, y = spots[k]
        return x + 10.0 * t, y, 0.0, 10.0

    _run_modes(recording, scene(rocks=2000, radius=6.0), lambda sim: sim.step(200), paths={0: path})  # the layout above


def test_origin_shift_in_the_middle_of_a_batch(recording):
    """Far from the world's origin, the floating origin moves (141 m in 440 steps) at a step that is not the
    first of a batch; also with the kernels in world coordinates (no origin to move: 150 steps)."""
    for x0, origin in ((100_000.0, "floating"), (0.0, "floating"), (100_000.0, "world")):
        steps = 440 if origin == "floating" else 150
        sc = scene(rocks=1000, radius=4.0, sim={"dt": 0.008, "origin": origin},
                   vehicles=[{"name": "car", "path": {"points": [[x0, 0.0], [x0 + 400.0, 0.0]], "speed": 40.0}},
                             {"name": "lead", "path": {"points": [[x0 + 4.5, 0.4], [x0 + 404.5, 0.4]],
                                                       "speed": 40.0}}])
        shifts = []

        def drive(sim):
            for _ in range(steps):
                before = sim.origin[0]
                sim.step()
                if sim.origin[0] != before:
                    shifts.append(sim.step_count)

        _run_modes(recording, sc, drive)
        if origin == "floating":
            assert shifts and all(s % simulation.LOOKAHEAD != 1 for s in shifts), shifts


def test_reversing_parked_and_coasting(recording):
    """The followed car reverses, stops for good at 0.8 s (then the steps coast), a parked splashing van
    stands by, a turning car passes; restore() to before the stop, then on."""
    vehicles = [{"name": "car", "path": {"points": [[0.0, 0.0], [8.0, 0.0]], "speed": 10.0, "reverse": True}},
                {"name": "van", "path": {"points": [[2.0, 2.5], [12.0, 2.5]], "speed": 0.0}},
                {"name": "turn", "path": {"kind": "circle", "center": [0.0, -3.0], "radius": 3.0, "speed": 8.0,
                                                  "sweep": 90.0, "loop": False}}]

    def drive(sim):
        sim.step(150)
        ck = sim.checkpoint()
        sim.step(150)
        assert sim.steps_coasted > 0
        sim.restore(ck)
        sim.step(100)

    _run_modes(recording, scene(rocks=2000, radius=6.0, vehicles=vehicles), drive)


# ------------------------------------------------------------------------------------------ the hulls
def test_vectorised_hulls_are_the_monotone_chain():
    """patch.hulls over many footprints at once gives the bits and vertex order of patch._hull row by row,
    including duplicates, collinear points, a zero-width tread, a point and a segment."""
    rng = np.random.default_rng(5)
    n = 3000
    b0 = rng.normal(size=(n, 3)) * 5.0
    a0 = rng.uniform(-np.pi, np.pi, n)
    a1 = a0 + np.where(np.arange(n) % 2 == 0, 0.0, rng.normal(size=n) * 0.01)
    f0, f1 = (np.column_stack([np.cos(a), np.sin(a)]) for a in (a0, a1))
    d = rng.normal(size=(n, 3)) * 0.05
    d[::3] = 0.0
    hw, hl = rng.uniform(0.0, 0.2, n), rng.uniform(0.0, 0.1, n)
    hw[::7] = 0.0
    hl[::11] = 0.0
    hw[::13] = hl[::13] = 0.0  # a point (not moving) or a segment (moving)
    ref = _old_hulls(b0, f0, b0 + d, f1, hw, hl)
    got = patch.swept_footprint_hulls(b0, f0, b0 + d, f1, hw, hl)
    assert got.tobytes() == ref.tobytes()
    grid = rng.integers(0, 3, size=(2000, HULL_VERTICES, 2)).astype(np.float64)  # many collinear and equal
    ref = np.array([np.concatenate([h, np.repeat(h[-1:], HULL_VERTICES - len(h), axis=0)])
                    for h in map(patch._hull, grid)])
    assert patch.hulls(grid).tobytes() == ref.tobytes()
