"""Hard cases of the whole simulation, each asserting physical invariants (not just "no exception").

Far from the origin, 60 m/s tires, time-step extremes, sharp turns / U-turn / reversing, stops, bed jumps,
edge geometry of the hash queries, hash stress through full runs, energy with restitution 1 and 0, rest,
a one-hour run, degenerate counts and the runtime guard.

Every Simulation compiles its kernels, so the scenes are small and few; the state of a rock is changed
through the fields (``sim.world.pos/vel/phase``, local coordinates in memory order, mapped through
``rock_id``) with :func:`set_rocks`.
"""

import math
import os
import re

import numpy as np
import pytest

from harness import Probe
from scenes_util import FakePath, reload_probe, scene, uniformity_pvalue
from taichi_rocks.config.scene import SceneError, parse_scene
from taichi_rocks.engine.simulation import HealthError, Simulation
from taichi_rocks.engine.world import FLYING, RESTING

pytestmark = pytest.mark.usefixtures("taichi_cpu")

G = 9.81


# ------------------------------------------------------------------------------------------ helpers
def car(points=((0.0, 0.0), (400.0, 0.0)), speed=10.0, name="car", **path):
    return {"name": name, "path": {"points": [list(p) for p in points], "speed": speed, **path}}


def parked(x=0.0, y=0.0, name="car", **extra):
    return {"name": name, "path": {"points": [[x, y], [x + 10.0, y]], "speed": 0.0}, **extra}


def memory_index(sim):
    """rock id -> index into the fields."""
    n = sim.n_rocks
    mem = np.empty(n, np.int64)
    mem[sim.world.rock_id.to_numpy()[:n]] = np.arange(n)
    return mem


def set_rocks(sim, ids, pos=None, vel=None, phase=None):
    """Overwrite the state of rocks (by id): world positions, velocities, phases (either stepping mode)."""
    sim.set_rocks(ids, positions=pos, velocities=vel, phase=phase)


def energy(st, ground_z=0.0, g=G):
    """Mechanical energy per unit mass, relative to resting on the ground: 1/2 |v|^2 + g (z - r - ground)."""
    v = st["velocities"].astype(np.float64)
    h = st["positions"][:, 2] - st["radii"] - ground_z
    return 0.5 * np.sum(v * v, axis=1) + g * h


def assert_sane(sim, st=None, ground_z=0.0):
    """All finite, nothing below the ground, everything inside the bed (if recycling), guard quiet."""
    st = sim.state() if st is None else st
    assert np.all(np.isfinite(st["positions"])) and np.all(np.isfinite(st["velocities"]))
    below = st["positions"][:, 2] - st["radii"] - ground_z
    assert below.min(initial=0.0) >= -1e-6, f"rock below the ground by {-below.min():.3g} m"
    if sim.plan.recycle and sim.n_rocks:
        d = np.hypot(*(st["positions"][:, :2] - st["bed_center"][:2]).T)
        assert d.max() <= sim.scene.bed.radius * (1 + 1e-6) + 1e-5, d.max()
    sim.check_health()
    return st


def launched_since(sim, step):
    """Ids of the rocks launched after `step` (the engine's per-rock record of its last launch step)."""
    return np.flatnonzero(sim.rock_arrays()["hit_step"] > step).astype(np.int64)


def launched_now(sim):
    """Ids of the rocks launched by the last step."""
    if not sim.last_launches:
        return np.zeros(0, np.int64)
    ids = launched_since(sim, sim.step_count - 1)
    assert len(ids) == sim.last_launches
    return ids


def rear_wheels(sim):
    return sim.fleet.rear_tires(sim.vehicle_poses())


# ------------------------------------------------------------------------------------------ 1. far away
def far_scene(x0, origin="floating"):
    return scene(rocks=3000, radius=4.0, sim={"dt": 0.008, "origin": origin},
                 vehicles=[car(((x0, 0.0), (x0 + 400.0, 0.0)), speed=40.0)])


def far_run(x0, origin="floating"):
    sim = Simulation(far_scene(x0, origin))
    sim.step(440)  # 141 m: the floating origin moves once (> 128 m), every rock is recycled ~15 times
    st = assert_sane(sim) if origin == "floating" else sim.state()
    assert np.all(np.isfinite(st["positions"]))
    return sim, st, st["positions"] - st["vehicle_positions"][0]


def test_far_from_origin_same_motion_relative_to_the_vehicle():
    base, st0, rel0 = far_run(0.0)
    assert st0["launches_total"] > 20 and (st0["phase"] == FLYING).sum() > 0
    assert base.origin[0] == 128.0, "the floating origin was expected to move once"
    local0 = base.rock_arrays()["pos"]
    del base
    for x0 in (100_000.0, 1_000_000.0):
        sim, st, rel = far_run(x0)
        # anchored at the bed's start, moved by the same whole steps: the local frame is the one at 0, the
        # kernels get the same bits and the run is bit-identical locally (before the origin was anchored,
        # 1e5, not a multiple of 64, put the bed 32 m from the origin and a rim rock landed 4.6 m away)
        assert sim.origin[0] - x0 == 128.0 and sim.origin[1] == 0.0, sim.origin
        assert st["launches_total"] == st0["launches_total"]
        assert st["recycles_total"] == st0["recycles_total"]
        np.testing.assert_array_equal(sim.rock_arrays()["pos"], local0)
        np.testing.assert_array_equal(st["phase"], st0["phase"])
        err = np.max(np.abs(rel - rel0), axis=1)
        assert err.max() < 1e-9, err.max()  # f64 rounding of the world outputs only
        del sim
    # the same at 100 km with the kernels in world coordinates (origin = "world"): f32 spacing is 7.8 mm
    _, stw, relw = far_run(100_000.0, origin="world")
    errw = np.max(np.abs(relw - rel0), axis=1)
    print(f"far: world origin at 100 km: max {errw.max():.4g} m, median {np.median(errw):.4g} m, "
          f"{np.mean(errw > 1e-3):.3f} of the rocks off by > 1 mm, launches {stw['launches_total']} vs "
          f"{st0['launches_total']}")
    # measured: max 7.7 m, median 2.7 mm, 80 % of the rocks off by > 1 mm, 200 launches instead of 190;
    # floating origin at 100 km and 1000 km: bit-identical locally (world outputs within 1e-10 m)
    assert np.median(errw) > 1e-3 and np.mean(errw > 1e-3) > 0.5


def test_world_origin_far_away_passes_the_runtime_guard():
    sim = Simulation(far_scene(100_000.0, origin="world"))
    for _ in range(40):
        sim.step()
        sim.check_health()


# ------------------------------------------------------------------------------------------ 2. 60 m/s
HS_DT, HS_STEPS, HS_STRIP = 0.004, 50, 0.12


def high_speed_run(detection):
    """Rocks in two strips along the rear tires' tracks, a car at 60 m/s, recycling off (the bed moves
    past, rocks stay), 0.2 s: no launched rock can land (the slowest rises at >= 4.7 m/s: flight ~1 s)."""
    sc = scene(rocks=3000, radius=4.0, effects={"recycle": False}, sim={"dt": HS_DT, "detection": detection},
               vehicles=[car(speed=60.0)])
    sim = Simulation(sc)
    st = sim.state()
    rng = np.random.default_rng(21)
    n = sim.n_rocks
    ray_y = sim.tire_rays()[:, 0, 1]
    side = rng.integers(0, 2, n)
    pos = np.column_stack([rng.uniform(-3.0, 13.0, n), ray_y[side] + rng.uniform(-HS_STRIP, HS_STRIP, n),
                           st["radii"]])
    set_rocks(sim, np.arange(n), pos=pos, vel=np.zeros((n, 3)), phase=RESTING)
    rays = [sim.tire_rays()]
    for _ in range(HS_STEPS):
        sim.step()
        rays.append(sim.tire_rays())
    st = sim.state()
    launched = set(np.flatnonzero(st["phase"] != RESTING).tolist())
    assert sim.launches_total == len(launched)
    return sim, np.array(rays), pos.astype(np.float32).astype(np.float64), st["radii"], launched


def strip_distance(c, x0, x1, y):
    """XY distance of points c to the segment x in [x0, x1] at height y (the vertical tire ray sweeps the
    rectangle [x0, x1] x {y} x [0, tire radius]; rock centres lie within that z range)."""
    dx = np.maximum(np.maximum(x0 - c[:, 0], c[:, 0] - x1), 0.0)
    return np.hypot(dx, c[:, 1] - y)


def test_high_speed_swept_misses_nothing_and_ray_misses_many():
    sim, rays, pos, r, got_swept = high_speed_run("swept")
    del sim  # one simulation at a time
    assert np.ptp(rays[:, :, :, 1], axis=0).max() == 0 and np.all(rays[:, :, 0, 2] > rays[:, :, 1, 2])
    swept_d = np.min([strip_distance(pos, rays[0, t, 0, 0], rays[-1, t, 0, 0], rays[0, t, 0, 1])
                      for t in range(rays.shape[1])], axis=0)
    ray_d = np.min([np.hypot(pos[:, 0] - rays[k, t, 0, 0], pos[:, 1] - rays[k, t, 0, 1])
                    for k in range(1, len(rays)) for t in range(rays.shape[1])], axis=0)
    band = 1e-5  # f32 rounding around tangency: not asserted either way
    clear = np.abs(swept_d - r) > band
    ref_swept = set(np.flatnonzero(clear & (swept_d <= r)).tolist())
    assert len(ref_swept) > 300
    assert (got_swept & set(np.flatnonzero(clear).tolist())) == ref_swept
    _, _, _, _, got_ray = high_speed_run("ray")
    clear_ray = np.abs(ray_d - r) > band
    ref_ray = set(np.flatnonzero(clear_ray & (ray_d <= r)).tolist())
    assert (got_ray & set(np.flatnonzero(clear_ray).tolist())) == ref_ray
    assert got_ray <= got_swept
    missed = 1.0 - len(got_ray) / len(got_swept)
    # measured: ray detection launches 143 of the 634 rocks under the tires' path at 60 m/s, dt = 4 ms
    # (24 cm per step for rocks 4-10 cm wide): it misses 77 %
    print(f"high speed: ray detection misses {missed:.3f} ({len(got_ray)} of {len(got_swept)})")
    assert missed > 0.3


# ------------------------------------------------------------------------------------------ 3. dt extremes
@pytest.mark.parametrize("dt, steps, every", [(0.05, 120, 1), (1e-5, 1500, 10)])
def test_time_step_extremes(dt, steps, every):
    """Drag off, ground bounce, a car driving through the bed; plus rocks thrown at the ground at 40 m/s
    (2 m per step at dt = 0.05: they must bounce, not tunnel) and rocks thrown up. Checked every `every`
    steps (the invariants hold over any number of steps)."""
    sc = scene(rocks=2000, radius=4.0, effects={"drag": "none", "ground": "bounce"}, sim={"dt": dt},
               vehicles=[car(speed=15.0)])
    sim = Simulation(sc)
    st = sim.state()
    rng = np.random.default_rng(4)
    down = np.arange(0, 20)
    up = np.arange(20, 40)
    r = st["radii"]
    xy = st["positions"][:, :2]
    ahead = np.column_stack([rng.uniform(0.5, 3.0, 20), rng.uniform(-2.0, 2.0, 20)])  # in the bed after a step
    set_rocks(sim, down, pos=np.column_stack([ahead, r[down] + 0.002]),
              vel=np.column_stack([rng.uniform(-1, 1, (20, 2)), np.full(20, -40.0)]), phase=FLYING)
    set_rocks(sim, up, pos=np.column_stack([xy[up], r[up] + rng.uniform(0, 1, 20)]),
              vel=np.column_stack([rng.uniform(-2, 2, (20, 2)), rng.uniform(-3, 12, 20)]), phase=FLYING)
    before = sim.state()
    bounced = np.zeros(20, bool)
    for k in range(0, steps, every):
        start = sim.step_count
        sim.step(every)
        st = sim.state()
        # a rock flying before and neither recycled (it left the bed: it rests at the leading edge) nor
        # launched again after landing: its energy must not grow (symplectic Euler loses g^2 dt^2 / 2 a
        # step in flight, a bounce loses more); f32 rounding of the state is ~1e-7 relative
        recycled = (st["phase"] == RESTING) & (before["phase"] == FLYING)
        keep = (before["phase"] == FLYING) & ~recycled
        keep[launched_since(sim, start)] = False
        e_before = energy(before)
        tol = 2e-6 * (np.abs(e_before) + G * np.abs(before["positions"][:, 2]) + 1.0)
        growth = (energy(st) - e_before)[keep]
        assert np.all(growth <= tol[keep]), (k, growth.max())
        step_xy = np.hypot(*(st["positions"][:, :2] - before["positions"][:, :2]).T)
        speed_xy = np.hypot(*before["velocities"][:, :2].T)
        assert np.all(step_xy[keep] <= speed_xy[keep] * dt * every * 1.0001 + 1e-5)
        # no tunnelling: the rocks thrown down stay above the ground and, once they hit it, move up
        assert np.all(st["positions"][down, 2] - r[down] >= -1e-6)
        assert np.all(st["phase"][down][~bounced] != RESTING), "a rock thrown down vanished (recycled)"
        bounced |= st["velocities"][down, 2] > 0
        if k % (50 * every) == 0:
            assert_sane(sim, st)
        before = st
    assert bounced.all(), "every rock thrown at the ground bounced back up"
    st = assert_sane(sim)
    if dt == 0.05:  # 6 s: everything thrown has landed; the car launched rocks on the way
        assert sim.launches_total > 0
        assert np.all(st["phase"][np.concatenate([down, up])] != FLYING)


# ------------------------------------------------------------------------------------------ 4. turns, reversing
def launch_records(sim, steps):
    """(rock velocity, wheel index, wheel velocity, wheel forward, pose) of every launch. A launched rock's
    velocity after the step is its launch velocity and its position the one it was hit at (the tire pass
    runs after the flight)."""
    out = []
    for _ in range(steps):
        sim.step()
        new = launched_now(sim)
        if len(new):
            st = sim.state()
            tires = rear_wheels(sim)
            pose = sim.vehicle_poses()[0]
            for i in new:
                d = np.hypot(*(tires.center[:, :2] - st["positions"][i, :2]).T)
                t = int(np.argmin(d))
                assert d[t] <= st["radii"][i] + 1e-4, "launched by a tire that does not touch it"
                out.append((st["velocities"][i].astype(np.float64), t, tires.velocity[t], tires.forward[t], pose))
    return out


def check_backwards(records):
    for v, _, vw, fwd, _ in records:
        rel = v[:2] - vw[:2]
        assert rel @ vw[:2] < 0, "relative to the wheel, a rock leaves against the wheel's travel"
        assert v[2] > 0


def bed_uniform(sim):
    st = sim.state()
    rest = st["phase"] == RESTING
    p = uniformity_pvalue(st["positions"][rest, :2], st["bed_center"][:2], sim.scene.bed.radius)
    assert p > 1e-3, p


def test_sharp_clockwise_turn_throws_outwards_and_backwards():
    # radius 3 m at 8 m/s, clockwise: the rear wheels slide to the left (outside) at |yaw| wheelbase / 2 = 3.6 m/s
    sim = Simulation(scene(rocks=4000, radius=5.0, vehicles=[{"name": "car", "path": {
        "kind": "circle", "center": [0.0, 0.0], "radius": 3.0, "speed": 8.0, "clockwise": True}}]))
    recs = launch_records(sim, 600)
    assert len(recs) > 30
    check_backwards(recs)
    for v, _, vw, fwd, pose in recs:
        left = np.array([-fwd[1], fwd[0]])
        assert pose.yaw_rate < -2.0
        assert v[:2] @ left > 0.5, "thrown to the outside of the turn"
    bed_uniform(sim)


def test_u_turn_and_reversing():
    hairpin = car(((0.0, 0.0), (12.0, 0.0), (15.0, 3.0), (12.0, 6.0), (0.0, 6.0)), speed=8.0)
    sim = Simulation(scene(rocks=4000, radius=5.0, vehicles=[hairpin]))
    recs = launch_records(sim, 1000)
    assert len(recs) > 30
    check_backwards(recs)
    sharp = 0
    for v, _, vw, fwd, pose in recs:
        left = np.array([-fwd[1], fwd[0]])
        if abs(pose.yaw_rate) * 2.7 / 2 > 2.0:  # the outward slide beats the lateral spread of the launch
            sharp += 1
            assert np.sign(v[:2] @ left) == -np.sign(pose.yaw_rate), "thrown to the outside of the turn"
    assert sharp > 5
    headings = sim.state()["vehicle_headings"]
    assert abs(headings[0]) > 2.5, "the car came back"
    bed_uniform(sim)
    del sim, recs  # one simulation at a time
    # driving backwards: the nose points to -x, the car travels to +x, rocks leave towards the nose
    back = Simulation(scene(rocks=4000, radius=5.0, vehicles=[car(speed=10.0, reverse=True)]))
    recs = launch_records(back, 300)
    assert len(recs) > 30
    check_backwards(recs)
    for v, _, vw, fwd, pose in recs:
        assert fwd[0] < -0.999 and vw[0] > 9.0 and v[0] < vw[0]
    bed_uniform(back)


# ------------------------------------------------------------------------------------------ 5. stops
def test_stop_and_start_and_parked_vehicles_never_launch_from_a_still_tire():
    # "car" (followed) stops at x = 8 (t = 2 s), starts again, parks for good at x = 20 (t = 5 s);
    # "parked" stands beside its path with its splashing tires on the rocks.
    stopper = car(((0.0, 0.0), (8.0, 1.0), (16.0, 0.0), (20.0, -1.0)), speed=[8.0, 0.0, 8.0, 0.0])
    still = {"name": "parked", "path": {"kind": "circle", "center": [6.0, 3.5], "radius": 1.0, "speed": 0.0}}
    sim = Simulation(scene(rocks=4000, radius=6.0, vehicles=[stopper, still], sim={"dt": 0.004}))
    moving_launches = 0
    stopped_steps = 0
    for _ in range(1500):
        sim.step()
        poses = sim.vehicle_poses()
        for p in poses:
            assert math.isfinite(p.heading) and math.isfinite(p.yaw_rate) and math.isfinite(p.speed)
        assert poses[1].speed == 0.0 and poses[1].yaw_rate == 0.0
        new = launched_now(sim)
        if len(new):
            pos = sim.state()["positions"][new]
            tires = rear_wheels(sim)
            d = np.hypot(tires.center[None, :, 0] - pos[:, None, 0], tires.center[None, :, 1] - pos[:, None, 1])
            assert np.all(np.argmin(d, axis=1) < 2), "the parked vehicle launched a rock"
        if abs(poses[0].speed) < 1e-3:
            stopped_steps += 1
            assert len(new) == 0, f"launch at t = {sim.time:.3f} s while the car stands still"
        else:
            moving_launches += len(new)
    assert stopped_steps > 200 and moving_launches > 20
    assert_sane(sim)


# ------------------------------------------------------------------------------------------ 6. bed jumps
def test_bed_jumps_farther_than_its_diameter_with_rocks_in_flight():
    R = 5.0
    sim = Simulation(scene(rocks=4000, radius=R))
    rng = np.random.default_rng(6)
    spots = [(0.0, 0.0)]
    for d in (2.0 * R, 2.0 * R + 1e-3, 3.7 * R, 50_000.0, 2.5 * R, 1_000_000.0):
        a = rng.uniform(0, 2 * np.pi)
        x, y = spots[-1]
        spots.append((x + d * np.cos(a), y + d * np.sin(a)))
    # drive for 0.4 s (rocks fly), then jump every 0.1 s, still driving (velocity 10 m/s along +x)
    def path(t):
        k = min(max(math.ceil((t - 0.4) / 0.1 - 1e-6), 0), len(spots) - 1)
        x, y = spots[k]
        return x + 10.0 * t, y, 0.0, 10.0
    sim.fleet.paths[0] = FakePath(path)
    sim.step(100)
    assert sim.launches_total > 20 and (sim.state()["phase"] == FLYING).sum() > 0
    for k in range(1, len(spots)):
        sim.step(25)
        st = assert_sane(sim)
        c = st["bed_center"][:2]
        np.testing.assert_allclose(c, path(sim.time)[:2], rtol=0, atol=1e-6)
        p = uniformity_pvalue(st["positions"][:, :2], c, R)
        assert p > 1e-3, (k, p)


def test_swept_detection_does_not_sweep_across_a_path_jump():
    """A circle arc with loop = true (documented: "an arc jumps back to its start") jumps 14 m at t = pi/2 s.
    Rocks launched in that step must lie under the tire's old or new ray, not on the chord in between."""
    sim = Simulation(scene(rocks=4000, radius=5.0, sim={"detection": "swept", "dt": 0.01}, vehicles=[
        {"name": "car", "path": {"kind": "circle", "radius": 10.0, "speed": 10.0, "sweep": 90.0, "loop": True}}]))
    prev_pos = sim.vehicle_poses()[0].position
    jumped = False
    for _ in range(170):
        prev_rays = sim.tire_rays()
        sim.step()
        pos = sim.vehicle_poses()[0].position
        if np.hypot(*(pos - prev_pos)[:2]) > 5.0:
            jumped = True
            ids = launched_now(sim)
            st = sim.state()
            p = st["positions"][ids, :2]
            rays = np.concatenate([prev_rays, sim.tire_rays()])
            d = np.min([np.hypot(*(p - ray[0, :2]).T) for ray in rays], axis=0) if len(ids) else np.zeros(0)
            assert np.all(d <= st["radii"][ids] + 1e-4), np.sort(d)
        prev_pos = pos
    assert jumped


# ------------------------------------------------------------------------------------------ 7. edge geometry
def edge_geometry(l, radii, same_radius=False):
    """Rocks and rays on the edges of the cell grid of edge l, one group per radius (5 m apart): a vertical
    ray along a cell edge, a horizontal ray along the x axis (on two cell faces), a vertical ray on one
    face, a zero-length ray on a cell corner and a diagonal through cell corners; rocks centred on cell
    corners, exactly tangent to the rays (along an axis, beyond the ends, on a 3-4-5 diagonal) and a hair
    (1e-4 r) outside. Coordinates are float32 values, so "on a boundary" and "tangent" are what the kernels
    see: a tangent rock's radius is the exact float32 distance (dropped if that is not a float32, or, with
    ``same_radius``, not r itself)."""
    f = np.float32
    lf = f(l)
    rocks, rays = [], []

    def lat(*ijk):  # a cell corner, as float32 (i * l rounded once)
        return np.array([f(i) * lf for i in ijk], np.float32)

    def add(c, r):
        rocks.append((np.asarray(c, np.float32), f(r)))

    def tangent(p, offset, r):
        """A rock at p + offset (float32) whose radius is |offset| after rounding, if that is exact."""
        c = (np.asarray(p, np.float32) + np.asarray(offset, np.float32)).astype(np.float32)
        d = float(np.linalg.norm(c.astype(np.float64) - np.asarray(p, np.float64)))
        if float(f(d)) == d and d > 0 and (not same_radius or d == float(r)):
            add(c, d)

    for g, r in enumerate(f(x) for x in radii):
        hair = r * f(1.0 + 1e-4)
        base = lat(0, 0, 0) + np.array([f(5.0 * g), 0, 0], np.float32)
        top = f(0.33)
        # (1) vertical ray along a cell edge
        a = base + np.array([0, 0, top], np.float32)
        rays.append((a, base.copy()))
        for i, j, k in ((0, 0, 1), (1, 0, 1), (0, -1, 2), (1, 1, 0), (-1, 0, 0), (0, 0, 0)):
            add(base + lat(i, j, k), r)  # on corners: the one on the ray is hit, the others are > r away
        for z in (f(0.1), lat(0, 0, 2)[2]):
            p = base + np.array([0, 0, z], np.float32)
            for s in (1, -1):
                tangent(p, [s * r, 0, 0], r)
                tangent(p, [0, s * r, 0], r)
                add(p + np.array([s * hair, 0, 0], np.float32), r)
        tangent(a, [0, 0, r], r)  # beyond the top end
        tangent(base, [0, 0, -r], r)  # below the bottom end
        add(a + np.array([0, 0, hair], np.float32), r)
        tangent(base + np.array([0, 0, f(0.2)], np.float32), [f(3) * r / f(5), f(4) * r / f(5), 0], r)  # 3-4-5
        # (2) horizontal ray along the x axis: on the faces y = 0 and z = 0 of the cells around it
        b2 = base + lat(0, 10, 0)
        rays.append((b2 - lat(3, 0, 0), b2 + lat(3, 0, 0)))
        for x in (lat(0, 0, 0)[0], lat(1, 0, 0)[0], f(0.05)):
            p = b2 + np.array([x, 0, 0], np.float32)
            for d in ((0, r, 0), (0, -r, 0), (0, 0, r), (0, 0, -r)):
                tangent(p, d, r)
            add(p + np.array([0, hair, 0], np.float32), r)
            add(p + np.array([0, 0, -hair], np.float32), r)
        tangent(b2 + lat(3, 0, 0), [r, 0, 0], r)  # beyond the end
        add(b2 - lat(3, 0, 0) - np.array([hair, 0, 0], np.float32), r)
        # (3) vertical ray on one face (x on a boundary, y mid-cell)
        b3 = base + lat(0, 20, 0) + np.array([0, f(0.5) * lf, 0], np.float32)
        rays.append((b3 + np.array([0, 0, top], np.float32), b3.copy()))
        for s in (1, -1):
            tangent(b3 + np.array([0, 0, f(0.15)], np.float32), [s * r, 0, 0], r)
            add(b3 + np.array([s * hair, 0, f(0.15)], np.float32), r)
        # (4) zero-length ray on a cell corner
        b4 = base + lat(0, 30, 1)
        rays.append((b4.copy(), b4.copy()))
        for d in np.eye(3, dtype=np.float32):
            for s in (1, -1):
                tangent(b4, s * r * d, r)
                add(b4 + s * hair * d, r)
        add(b4, r)
        tangent(b4, [f(3) * r / f(5), 0, -f(4) * r / f(5)], r)
        # (5) a diagonal through cell corners (the DDA's 3-way ties), rocks on and beside the corners
        b5 = base + lat(0, 40, 0)
        rays.append((b5.copy(), b5 + lat(4, 4, 4)))
        for i in range(5):
            add(b5 + lat(i, i, i), r)
            add(b5 + lat(i + 1, i, i), r)
            for k in (0.5, 1.5):  # perpendicular to the diagonal, well inside / outside
                add(b5 + lat(i, i, i) + np.array([r, -r, 0], np.float32) * f(k / np.sqrt(2)), r)
    pos = np.array([c for c, _ in rocks], np.float64)
    rad = np.array([r for _, r in rocks], np.float64)
    return pos, rad, np.array(rays, np.float64)


def brute_hit_distance(pos, rad, rays):
    """min over rays of (distance to the segment) - r, float64 on the float32 inputs; <= 0 is a hit."""
    out = np.full(len(pos), np.inf)
    for a, b in rays:
        d = b - a
        dd = d @ d
        t = np.zeros(len(pos)) if dd == 0 else np.clip((pos - a) @ d / dd, 0.0, 1.0)
        dist = np.linalg.norm(pos - (a + t[:, None] * d), axis=1)
        out = np.minimum(out, dist - rad)
    return out


@pytest.fixture(scope="module")
def edge_probes(taichi_cpu):
    """One compiled probe per insert mode (and a swept one), reloaded for each geometry."""
    cap, rays = 1200, np.zeros((16, 2, 3))
    rays[:, 0, 2] = 0.6  # longest ray / smallest cell used below: sizes the ray-cell buffers
    pos = np.zeros((cap, 3))
    pos[:, 0] = np.arange(cap) * 0.5
    big = np.full(cap, 0.08)
    return {mode: Probe(pos, big, cell=0.04, insert=ins, rays=rays, swept=sw)
            for mode, ins, sw in (("center", "center", False), ("aabb", "aabb", False),
                                  ("swept", "center", True))}


@pytest.mark.parametrize("l, radii, same", [
    (0.125, [0.03125, 0.046875, 0.078125], False),  # dyadic: boundaries and tangencies exact
    (0.1, [0.03, 0.046875, 0.078125], False),  # 0.1 is not a float: i * l rounds, floor(x / l) on ties
    (0.0625, [0.0625], True),  # radius min = max = the cell (r_max / l = 1: the dilation's rounding edge)
    (0.125, [0.0625], True),  # min = max, cell = diameter ("auto" for centre insert)
])
def test_edge_geometry_found_exactly_as_brute_force(edge_probes, l, radii, same):
    pos, rad, rays = edge_geometry(l, radii, same_radius=same)
    if same:
        assert np.all(rad == radii[0])
    margin = brute_hit_distance(pos, rad, rays)
    exact = margin == 0.0
    assert exact.sum() >= 8 * len(radii), "the geometry should hold exactly tangent rocks"
    # everything else is clearly in or out (no f32 coin flips): the kernels must agree exactly
    assert np.all(exact | (np.abs(margin) > 1e-6 * rad)), np.sort(np.abs(margin[~exact]))[:5]
    ref = np.flatnonzero(margin <= 0.0)
    for mode, probe in edge_probes.items():
        got = reload_probe(probe, pos, rad, rays, cell=l).hits(step=7)
        np.testing.assert_array_equal(got, ref, err_msg=f"{mode}, l = {l}, r = {radii}")


# ------------------------------------------------------------------------------------------ 8. hash stress
def hash_run(**hash_settings):
    sc = scene(rocks=1200, radius=3.0, bed={"rock_radius": [0.03, 0.03]},
               sim={"dt": 0.004, "hash": hash_settings}, vehicles=[car(speed=12.0)])
    sim = Simulation(sc)
    ids = []
    for _ in range(100):
        sim.step()
        ids.extend((sim.step_count, int(i)) for i in launched_now(sim))
    return sim, ids, sim.state()


def test_hash_stress_full_runs_launch_the_same_rocks():
    """table_size 1 (every cell collides), a table 130x larger than N, one cell holding the whole bed,
    radius min = max: the same (step, rock) launches and a bit-identical state as the automatic table."""
    _, ref_ids, ref = hash_run()
    assert len(ref_ids) > 15
    variants = [
        {"table_size": 1, "cell_size": 50.0},  # 4 cells (x, y < 0 and >= 0), 1 slot: every query lists all
        {"table_size": 1, "insert": "aabb", "scope": "all"},
        {"table_size": 200_003, "scope": "all", "reorder_every": 7},
    ]
    for hs in variants:
        sim, ids, st = hash_run(**hs)
        assert ids == ref_ids, hs
        np.testing.assert_array_equal(st["positions"], ref["positions"], err_msg=str(hs))
        np.testing.assert_array_equal(st["velocities"], ref["velocities"], err_msg=str(hs))
        np.testing.assert_array_equal(st["phase"], ref["phase"], err_msg=str(hs))


# ------------------------------------------------------------------------------------------ 9. energy
def dropped_rocks(restitution, integrator, n, heights, horizontal, **world):
    sc = scene(rocks=n, radius=3.0, effects={"drag": "none", "ground": "bounce"},
               world={"restitution": restitution, **world}, sim={"dt": 0.01, "integrator": integrator},
               vehicles=[parked()])
    sim = Simulation(sc)
    st = sim.state()
    rng = np.random.default_rng(9)
    xy = rng.uniform(-1.5, 1.5, (n, 2))
    vxy = rng.uniform(-horizontal, horizontal, (n, 2))
    set_rocks(sim, np.arange(n), pos=np.column_stack([xy, st["radii"] + heights]),
              vel=np.column_stack([vxy, np.zeros(n)]), phase=FLYING)
    return sim


def test_restitution_one_keeps_the_energy_over_ten_thousand_bounces():
    """Heun is exact in free flight and the bounce is resolved at its time, so with restitution 1, no drag
    and no ground friction the energy per unit mass stays (f32 rounding only). Dropped from 1-3 mm (a
    bounce every 3-5 steps of 10 ms), 100 rocks make 10^4 bounces in ~450 steps."""
    n = 100
    rng = np.random.default_rng(10)
    period = rng.uniform(0.03, 0.05, n)
    sim = dropped_rocks(1.0, "heun", n, G * period ** 2 / 8, 0.02, ground_friction=0.0, rest_speed=1e-3)
    st = sim.state()
    e0 = energy(st)
    vz = st["velocities"][:, 2].copy()
    bounces = 0
    worst_total = worst_rock = -1.0
    for _ in range(450):
        sim.step()
        st = sim.state()
        bounces += int(np.sum((vz < 0) & (st["velocities"][:, 2] > 0)))
        vz = st["velocities"][:, 2].copy()
        e = energy(st)
        worst_total = max(worst_total, e.sum() / e0.sum() - 1.0)
        worst_rock = max(worst_rock, float(np.max(e / e0 - 1.0)))
        assert np.all(st["phase"] == FLYING)
        assert np.all(st["positions"][:, 2] - st["radii"] >= -1e-7)
    print(f"restitution 1: {bounces} bounces, energy growth total {worst_total:.3g}, worst rock {worst_rock:.3g}")
    assert bounces >= 10_000
    assert worst_total < 1e-3 and worst_rock < 1e-3
    assert_sane(sim)


def test_restitution_zero_stops_rocks_on_the_ground():
    n = 100
    rng = np.random.default_rng(11)
    sim = dropped_rocks(0.0, "symplectic_euler", n, rng.uniform(0.05, 1.0, n), 0.8)
    sim.step(120)  # 1.2 s: all have fallen (<= 0.45 s) and slid to a stop (<= 0.8 / (0.6 g) = 0.14 s)
    st = assert_sane(sim)
    assert np.all(st["phase"] == RESTING)
    assert np.all(st["velocities"] == 0)
    np.testing.assert_allclose(st["positions"][:, 2], st["radii"], rtol=0, atol=1e-7)
    sim.step(100)
    np.testing.assert_array_equal(sim.state()["positions"], st["positions"])


# ------------------------------------------------------------------------------------------ 10, 12. settle
@pytest.fixture(scope="module")
def settled(taichi_cpu):
    """200 rocks thrown up at once (restitution 0.3, a parked car): they land, bounce, slide and rest.
    The invariants of every step are recorded for the tests below."""
    n = 200
    sim = Simulation(scene(rocks=n, radius=3.0, world={"restitution": 0.3}, sim={"dt": 0.01},
                           vehicles=[parked()]))
    sim.coast = False  # every step through the whole pipeline (the car is parked: it would coast)
    st = sim.state()
    rng = np.random.default_rng(12)
    vel = np.column_stack([rng.uniform(-1.0, 1.0, (n, 2)), rng.uniform(1.0, 6.0, n)])
    set_rocks(sim, np.arange(n), vel=vel, phase=FLYING)
    history = {"lowest": np.inf, "flying_max": 0, "steps": 0}
    for k in range(200):
        sim.step(2)
        st = sim.state()
        assert np.all(np.isfinite(st["positions"])) and np.all(np.isfinite(st["velocities"]))
        history["lowest"] = min(history["lowest"], float(np.min(st["positions"][:, 2] - st["radii"])))
        history["flying_max"] = max(history["flying_max"], int(np.sum(st["phase"] == FLYING)))
        if k % 10 == 0:
            sim.check_health()
        history["steps"] = 2 * (k + 1)
        if np.all(st["phase"] == RESTING):
            break
    return sim, history


def test_all_rocks_launched_at_once_land_and_settle(settled):
    sim, history = settled
    assert history["flying_max"] >= sim.n_rocks - 5  # a few near the rim leave the bed in the first step
    assert history["lowest"] >= -1e-6, history["lowest"]
    st = assert_sane(sim)
    assert np.all(st["phase"] == RESTING), f"not settled after {history['steps']} steps"
    np.testing.assert_allclose(st["positions"][:, 2], st["radii"], rtol=0, atol=1e-7)
    assert sim.launches_total == 0  # a parked car launches nothing


# The full pipeline (flight, recycling, hash, tire pass) costs ~1-2 ms a step here, mostly host overhead: it
# runs REST_STEPS steps (TAICHI_ROCKS_REST_STEPS=100000 runs all 10^5 that way: 164 s). Then 10^5 more
# steps run the way the engine runs a scene whose vehicles have stopped for good: one coast_pass launch
# (bit-identical to stepping: test_engine.py::test_coasting_is_bit_identical_to_stepping).
REST_STEPS = int(os.environ.get("TAICHI_ROCKS_REST_STEPS", "5000"))


def test_settled_rocks_stay_put_bit_for_bit(settled):
    """Resting rocks are not integrated: no jitter, sinking or creep over 10^5 steps, with the parked car's
    tires on the bed."""
    sim, _ = settled
    before = sim.state()
    assert np.all(before["phase"] == RESTING)
    sim.coast = False
    sim.step(REST_STEPS)
    mid = sim.state()
    for k in ("positions", "velocities", "phase"):
        np.testing.assert_array_equal(mid[k], before[k])
    sim.coast = True
    sim.step(100_000)
    assert sim.steps_coasted == 100_000 and sim.step_count == before["step"] + REST_STEPS + 100_000
    after = sim.state()
    for k in ("positions", "velocities", "phase"):
        np.testing.assert_array_equal(after[k], before[k])
    assert sim.launches_total == 0
    sim.check_health()


# ------------------------------------------------------------------------------------------ 11. a long run
# ten simulated minutes at dt = 0.1 (the largest dt a scene accepts) are 6,000 steps: ~7 s on a 2-core machine
# with its twelve checks; TAICHI_ROCKS_LONG_RUN_S=3600 runs the full hour (36,000 steps, ~19 s)
LONG_RUN_S = float(os.environ.get("TAICHI_ROCKS_LONG_RUN_S", "600"))


def test_a_long_run_on_a_circle():
    """Ten minutes (an hour with TAICHI_ROCKS_LONG_RUN_S=3600) at dt = 0.1: a car looping on a circle, every
    rock hashed and re-sorted in memory every 64 steps (scope "all"). Count, identity, finiteness, bed and
    ground hold throughout; uniform at the end."""
    R = 4.0
    sc = scene(rocks=600, radius=R, sim={"dt": 0.1, "hash": {"scope": "all"}, "stepping": "full"},  # re-sorting
               vehicles=[{"name": "car", "path": {"kind": "circle", "center": [0.0, 0.0], "radius": 12.0,
                                                  "speed": 6.0}}])
    sim = Simulation(sc)
    launches = 0
    for block in range(12):
        sim.advance_to(LONG_RUN_S * (block + 1) / 12)
        st = assert_sane(sim)
        ids = np.sort(sim.world.rock_id.to_numpy()[: sim.n_rocks])
        np.testing.assert_array_equal(ids, np.arange(sim.n_rocks))  # the re-sorting loses and doubles none
        assert len(st["positions"]) == 600
        launches = sim.launches_total
    assert sim.step_count == round(LONG_RUN_S / 0.1) and abs(sim.time - LONG_RUN_S) < 1e-6
    assert launches > LONG_RUN_S / 36
    p = uniformity_pvalue(st["positions"][:, :2], st["bed_center"][:2], R)
    assert p > 1e-3, p
    np.testing.assert_allclose(np.hypot(*st["vehicle_positions"][0, :2]), 12.0, rtol=1e-9)


# ------------------------------------------------------------------------------------------ 12. degenerate
def test_zero_and_one_rock():
    empty = Simulation(scene(rocks=0))
    empty.step(20)
    st = empty.state()
    assert st["positions"].shape == (0, 3) and st["launches_total"] == 0 and empty.plan.passes() == []
    empty.check_health()
    # one rock, right in the left rear tire's track: launched, flies, lands, nothing breaks
    one = Simulation(scene(rocks=1, radius=3.0, vehicles=[car(speed=5.0)], sim={"dt": 0.01}))
    r = one.state()["radii"][0]
    y = one.tire_rays()[0, 0, 1]
    set_rocks(one, [0], pos=[[1.0, y, r]])
    for _ in range(50):
        one.step(5)
        s = one.state()
        assert np.all(np.isfinite(s["positions"])) and s["positions"][0, 2] - r >= -1e-6
    assert one.launches_total >= 1
    assert_sane(one)


def test_vehicle_outside_the_bed_launches_nothing():
    """The followed car is parked and does not splash; a splashing car passes 0.3 m outside the rim
    (its tires are within the 'near' reach: its rays are traced) and another 100 m away (parked rays)."""
    R = 3.0
    player = parked(splash=False)
    grazing = car(((-20.0, R + 0.3 + 0.8), (20.0, R + 0.3 + 0.8)), speed=10.0, name="grazing")
    far = car(((-20.0, 100.0), (20.0, 100.0)), speed=10.0, name="far")
    sim = Simulation(scene(rocks=2000, radius=R, vehicles=[player, grazing, far]))
    assert sim.plan.splash and sim.world.n_tires == 4
    before = sim.state()
    for _ in range(6):  # 1.2 s: the grazing car drives 12 m along the rim
        sim.step(50)
        assert_sane(sim)
    st = sim.state()
    assert sim.launches_total == 0
    np.testing.assert_array_equal(st["positions"], before["positions"])


def test_scene_without_vehicles_is_rejected_clearly():
    for data in ({"bed": {"rocks": 10}}, {"bed": {"rocks": 10}, "vehicle": []}):
        with pytest.raises(SceneError) as err:
            parse_scene(data, source="novehicle.toml")
        msg = str(err.value)
        assert "novehicle.toml" in msg and "vehicle" in msg
        assert "at least one [[vehicle]] table is required" in msg, msg


# ------------------------------------------------------------------------------------------ 13. the guard
def test_runtime_guard_names_step_rock_and_kind():
    # full stepping: the faults are written into the rock arrays directly (test_runtime_guard_sees_the_tiles
    # covers active stepping)
    sim = Simulation(scene(rocks=50, radius=3.0, vehicles=[parked()], sim={"stepping": "full"}))
    sim.step(3)
    sim.check_health()
    w = sim.world
    mem = memory_index(sim)
    R = sim.scene.bed.radius

    def expect(rock, kind):
        with pytest.raises(HealthError) as err:
            sim.check_health()
        msg = str(err.value)
        assert re.search(rf"\bstep {sim.step_count}\b", msg), msg
        assert re.search(rf"\brock {rock}\b", msg), msg
        assert kind in msg, msg
        return msg

    i = int(mem[17])
    keep_p, keep_v = np.asarray(w.pos[i]), np.asarray(w.vel[i])
    w.pos[i] = [float("nan"), 0.0, 0.0]
    expect(17, "non-finite")
    w.pos[i] = keep_p.tolist()
    w.vel[i] = [0.0, float("inf"), 0.0]
    expect(17, "non-finite")
    w.vel[i] = keep_v.tolist()
    sim.check_health()

    j = int(mem[23])
    keep = np.asarray(w.pos[j])
    c = sim.bed_center - sim.origin
    w.pos[j] = [float(c[0] + R + 0.5), float(c[1]), float(keep[2])]
    expect(23, "outside the bed")
    sim.step()  # recycling brings it back to the bed
    sim.check_health()

    k = int(mem[31])
    p = np.asarray(w.pos[k])
    w.pos[k] = [float(p[0]), float(p[1]), float(p[2] - 0.01)]
    expect(31, "below the ground")
    w.pos[k] = p.tolist()
    sim.check_health()


def test_runtime_guard_sees_the_tiles():
    """Active stepping: a bad rock resting in a tile is found too, named by its id."""
    sim = Simulation(scene(rocks=50, radius=3.0, vehicles=[parked()]))
    assert sim.plan.active
    sim.step(3)
    sim.check_health()
    assert sim.active_count == 0  # every rock rests in a tile
    w = sim.world
    j = int(np.flatnonzero(w.ts_rock_id.to_numpy() == 23)[0])  # rock 23's place in the tiles
    p = np.asarray(w.ts_pos[j])
    c = sim.bed_center - sim.origin
    w.ts_pos[j] = [float(c[0] + 3.5), float(c[1]), float(p[2])]
    with pytest.raises(HealthError) as err:
        sim.check_health()
    assert re.search(r"\brock 23\b", str(err.value)) and "outside the bed" in str(err.value), str(err.value)
    w.ts_pos[j] = p.tolist()
    sim.check_health()
