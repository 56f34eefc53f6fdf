"""The batch's impacts rows (engine/impact_pass.py ``batch_pose_rows``, engine/host.py ``Frames``) have the bits of
the per-step rows (``pose_rows``, and the start time time - dt the steppers subtract the events' reference time
from): on random and adversarial poses (headings at +-pi, -0.0, huge; an origin shift in the middle of the
batch; the poses before the batch a list as ``Fleet.poses`` gives), and through the host side of the shipped
convoy scene and a floating origin far from the world's, step by step against the lookahead. NumPy only."""

from types import SimpleNamespace

import numpy as np
import pytest

from scenes_util import scene
from taichi_rocks.config.plan import Plan
from taichi_rocks.config.scene import load_scene
from taichi_rocks.engine.host import HostSide, HostState
from taichi_rocks.engine.impact_pass import batch_pose_rows, pose_rows
from taichi_rocks.engine.stepdata import batch_arrays
from taichi_rocks.motion.vehicles import Fleet, PoseTable, TablePoses, VehiclePose


def _table(rng, k, v):
    cols = {n: rng.uniform(-1e4, 1e4, (k, v)) for n in ("x", "y", "rx", "ry", "speed", "vx", "vy")}
    heading = rng.uniform(-20.0, 20.0, (k, v))
    heading.flat[:8] = [np.pi, -np.pi, -0.0, 0.0, 1e6, -1e6, np.nextafter(np.pi, 0), 0.5 * np.pi][:heading.size]
    yaw = rng.normal(0.0, 1.0, (k, v))
    yaw.flat[0] = -0.0
    return PoseTable(heading=heading, yaw_rate=yaw, **cols)


def _pose(rng):
    return VehiclePose("v", rng.normal(size=3), float(rng.uniform(-4, 4)), 1.0, float(rng.normal()),
                       rng.normal(size=3) * 30.0, rng.normal(size=3) * 1e5)


@pytest.mark.parametrize("seed", range(6))
def test_batch_pose_rows_are_the_per_step_rows(seed):
    rng = np.random.default_rng(seed)
    k, v = int(rng.integers(1, 65)), int(rng.integers(1, 6))
    targets = sorted(rng.choice(v, int(rng.integers(1, v + 1)), replace=False).tolist())
    table = _table(rng, k, v)
    fleet = SimpleNamespace(specs=[SimpleNamespace(name="v")] * v, ground_z=float(rng.normal()))
    shift = np.zeros((k, 2))
    shift[int(rng.integers(0, k)):] = rng.integers(-3, 4, 2) * 64.0  # the origin moves within the batch
    prev = [_pose(rng) for _ in range(v)]  # the poses before the batch: Fleet.poses' list
    batch = batch_pose_rows(prev, table, targets, shift)
    assert batch.shape == (k, 7 * len(targets), 2) and batch.dtype == np.float64
    for j in range(k):
        cur = TablePoses(fleet, table, j)
        want = pose_rows(prev, cur, targets, shift[j])
        assert want.tobytes() == batch[j].tobytes(), j
        prev = cur


def _served(sc, lookahead, steps):
    """Each step's (pose rows, start time) as the steppers get them, from a HostSide of ``sc``."""
    plan = Plan.from_scene(sc)
    fleet = Fleet(sc)
    follow = sc.vehicle_index(sc.bed.follow)
    side = HostSide(sc, fleet, follow, 0, lookahead, plan.targets)
    st = HostState()
    side.start(st)
    out = []
    for _ in range(steps):
        s = side.advance(st, side.dt)
        start = st.time - s.dt if s.frames is None else s.frames.start[s.row]
        out.append((np.asarray(s.bodies).tobytes(), np.float64(start).tobytes(), st.shift.tobytes()))
    return out, side.ahead.batches


@pytest.mark.parametrize("case", ["convoy", "far"])
def test_host_side_batches_give_the_step_by_step_rows(case, scenes_dir):
    if case == "convoy":  # 4 vehicles, each hit
        sc = load_scene(scenes_dir / "convoy.toml")
    else:  # 100 km out, the floating origin moving in the middle of a batch
        sc = scene(rocks=1000, radius=4.0, effects={"impacts": True},
                   sim={"dt": 0.008, "origin": "floating"}, bed={"rock_radius": [0.004, 0.01]},
                   vehicles=[{"name": "car", "path": {"points": [[1e5, 0.0], [1e5 + 400.0, 0.0]], "speed": 40.0}},
                             {"name": "lead", "path": {"points": [[1e5 + 8.0, 0.4], [1e5 + 408.0, 0.4]],
                                                       "speed": 40.0}}])
    assert Plan.from_scene(sc).impacts
    steps = 300 if case == "convoy" else 440
    one, _ = _served(sc, 0, steps)
    batched, batches = _served(sc, 64, steps)
    assert 1 <= batches < steps
    bad = [j for j, (a, b) in enumerate(zip(one, batched)) if a != b]
    assert not bad, f"steps {bad[:5]} differ ({len(bad)} of {steps})"
    if case == "far":
        assert len({s for _, _, s in one}) > 1  # the origin moved


def test_batch_arrays_carry_the_start_times_and_rows():
    k = 5
    z = np.zeros((k, 2))
    start = np.arange(k) * 0.004 + 1.0 / 3.0
    bodies = np.random.default_rng(0).normal(size=(k, 14, 2))
    _, frame, poses = batch_arrays(z, z, z, z, z, np.full(k, 0.004), 1.0, None, start, bodies)
    assert frame[:, 5, 1].tobytes() == start.tobytes() and poses.tobytes() == bodies.tobytes()
    _, frame, poses = batch_arrays(z, z, z, z, z, np.full(k, 0.004), 1.0, None)
    assert not frame[:, 5, 1].any() and poses.shape == (1, 1, 2)
