"""Pass 1: every rock stays in the bed and the density stays uniform (chi-square over equal-area bins)."""

import numpy as np
import pytest

from scenes_util import FakePath, scene, uniformity_pvalue
from taichi_rocks.engine.simulation import Simulation

pytestmark = pytest.mark.usefixtures("taichi_cpu")
N = 12000
R = 6.0


def bed_only(path_fn, dt=0.01):
    sim = Simulation(scene(rocks=N, radius=R, effects={"splash": False}, sim={"dt": dt}))
    sim.fleet.paths[0] = FakePath(path_fn)
    return sim


def check(sim):
    st = sim.state()
    xy = st["positions"][:, :2]
    c = st["bed_center"][:2]
    d = np.hypot(*(xy - c).T)
    assert d.max() <= R * (1 + 1e-6), d.max()
    assert np.allclose(st["positions"][:, 2], st["radii"] + sim.scene.world.ground_z, atol=1e-5)
    p = uniformity_pvalue(xy, c, R)
    assert p > 1e-3, p
    return st


def test_initial_bed_is_uniform():
    check(bed_only(lambda t: (0.0, 0.0, 0.0, 0.0)))


def test_long_straight_drive_stays_uniform():
    sim = bed_only(lambda t: (25.0 * t, 0.0, 0.0, 25.0))
    sim.step(400)  # 100 m: every rock recycled ~8 times
    st = check(sim)
    assert st["bed_center"][0] == pytest.approx(100.0)


def test_long_turn_and_reverse_stay_uniform():
    w = 20.0 / 8.0  # 20 m/s on a circle of radius 8 m (bed radius 6)

    def turn(t):
        a = w * t
        return 8 * np.cos(a), 8 * np.sin(a), a + np.pi / 2, 20.0

    sim = bed_only(turn)
    sim.step(600)
    check(sim)
    # then reverse along a line
    t0 = sim.time
    x0, y0 = sim.bed_center[:2]
    sim.fleet.paths[0] = FakePath(lambda t: (x0 - 15.0 * (t - t0), y0, 0.0, -15.0))
    sim.step(300)
    check(sim)


@pytest.mark.parametrize("jump", [2.5 * R, 0.7 * R, 100_000.0])
def test_jump_of_the_bed(jump):
    sim = bed_only(lambda t: (0.0 if t < 0.05 else jump, 0.0, 0.0, 0.0))
    sim.step(10)
    check(sim)


def test_rocks_never_move_without_recycling_or_splash():
    sim = Simulation(scene(rocks=500, radius=R, effects={"splash": False, "recycle": False}))
    before = sim.state()["positions"]
    sim.step(50)  # the car drives 2 m: rocks left behind stay where they are
    np.testing.assert_array_equal(sim.state()["positions"], before)
    assert sim.plan.passes() == []
    assert not sim.world.hashed and not hasattr(sim.world, "cell_start")
