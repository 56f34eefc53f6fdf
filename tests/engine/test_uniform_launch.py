"""The "uniform" launch model's distributions (engine/tires.py): the release angle alpha is uniform over
[release_angle min, max] and the lateral angle beta over [-spread, spread], tested by Kolmogorov-Smirnov
against those closed-form CDFs on about 2,000 launches by a car driving straight at 15 m/s over rocks laid on
its rear-tire tracks. Each launch is inverted from the model's velocity (relative to the wheel moving at V
along +x, omega R = V (1 + slip)):
    v - v_wheel = (-omega R cos(alpha) Rot(beta) x,  mu omega R sin(alpha))
so alpha = atan2(v_z / mu, |v_xy - v_wheel|) and beta = atan2(-dv_y, -dv_x), and the speed |(dv_xy, v_z / mu)|
must be omega R. The same KS test against a range 5 degrees narrower must reject: the test can fail."""

import numpy as np
import pytest
from scipy.stats import kstest, uniform

from scenes_util import reference_scene
from taichi_rocks.engine.simulation import Simulation  # the public face; the one engine import here

pytestmark = pytest.mark.usefixtures("taichi_cpu")

SPEED = 15.0
A_MIN, A_MAX, SPREAD = 10.0, 60.0, 20.0  # the reference scene's launch ranges (deg)


@pytest.fixture(scope="module")
def launches():
    scene = reference_scene(speed=SPEED)
    la, car = scene.launch, scene.vehicles[0]
    assert (la.model, *la.release_angle, la.spread) == ("uniform", A_MIN, A_MAX, SPREAD)
    sim = Simulation(scene)
    n = sim.n_rocks
    r = sim.state()["radii"]
    side = np.where(np.arange(n) % 2 == 0, 0.5, -0.5) * car.track
    x = np.linspace(-1.0, 3.5, n)  # ahead of the rear axle (at -wheelbase/2), inside the 4.5 m bed
    sim.set_rocks(np.arange(n), positions=np.column_stack([x, side, scene.world.ground_z + r]))
    vel, mu = [], []
    for _ in range(90):  # the rear axle passes x = 3.5 after about 80 steps
        sim.step()
        a = sim.rock_arrays()
        now = a["hit_step"] == sim.step_count
        vel.append(a["vel"][now].astype(np.float64))
        mu.append(a["friction"][now].astype(np.float64))
    vel, mu = np.concatenate(vel), np.concatenate(mu)
    dv = vel[:, :2] - np.array([SPEED, 0.0])
    spin = SPEED * (1.0 + car.slip)
    lift = vel[:, 2] / mu
    alpha = np.degrees(np.arctan2(lift, np.hypot(dv[:, 0], dv[:, 1])))
    beta = np.degrees(np.arctan2(-dv[:, 1], -dv[:, 0]))
    return alpha, beta, np.hypot(np.hypot(dv[:, 0], dv[:, 1]), lift) / spin


def test_enough_launches_and_the_model_speed(launches):
    alpha, beta, speed_ratio = launches
    assert len(alpha) > 1500
    np.testing.assert_allclose(speed_ratio, 1.0, atol=1e-5)  # the tread point's speed, omega R


def test_release_angle_is_uniform_over_its_range(launches):
    alpha = launches[0]
    assert A_MIN - 1e-3 <= alpha.min() and alpha.max() <= A_MAX + 1e-3
    assert kstest(alpha, uniform(loc=A_MIN, scale=A_MAX - A_MIN).cdf).pvalue > 0.01
    assert kstest(alpha, uniform(loc=A_MIN, scale=A_MAX - A_MIN - 5.0).cdf).pvalue < 1e-6  # not vacuous


def test_spread_is_uniform_over_plus_minus_spread(launches):
    beta = launches[1]
    assert -SPREAD - 1e-3 <= beta.min() and beta.max() <= SPREAD + 1e-3
    assert kstest(beta, uniform(loc=-SPREAD, scale=2 * SPREAD).cdf).pvalue > 0.01
    assert kstest(beta, uniform(loc=-SPREAD + 5.0, scale=2 * SPREAD - 5.0).cdf).pvalue < 1e-6
    assert abs(np.corrcoef(launches[0], beta)[0, 1]) < 0.06  # drawn independently
