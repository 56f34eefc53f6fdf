"""Quadratic air drag in flight (engine/flight.py) against SciPy's solve_ivp at tight tolerance.

The ODE, written here from the module docstring: a = -g z - (3 rho_air C_d / (8 rho r)) |v| v, for rocks
launched obliquely (in the x-z plane, and with a sideways part, so the drag couples the components through
|v|), flown 2 s by the flight part of the engine's rock pass alone (engine/probes.py ``fly_only``: no ground,
no recycling), in f64 so that round-off stays far below the truncation errors. The reference is DOP853 with
rtol = atol = 1e-12. RK4 at dt = 1 ms must agree within 1e-8 m; halving dt must cut the error by about 16 (RK4),
4 (Heun) and 2 (symplectic Euler), the orders of the three integrators.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from scenes_util import scene as make_scene
from taichi_rocks.engine import probes  # the public probe; with Simulation the only engine imports here
from taichi_rocks.engine.simulation import Simulation

pytestmark = pytest.mark.usefixtures("taichi_cpu")

T = 2.0
EVERY_S = 0.1
X0 = np.array([[0.0, 0.0, 1.0], [1.0, -1.0, 0.5], [-2.0, 2.0, 0.2]])
V0 = np.array([[20.0, 0.0, 12.0], [15.0, 5.0, 8.0], [-10.0, 3.0, 20.0]])
R = np.array([0.01, 0.03, 0.015])


@pytest.fixture(scope="module")
def sim():
    """A small full-stepping f64 scene: fly_only runs the passes of full stepping."""
    return Simulation(make_scene(rocks=2000, sim={"stepping": "full", "precision": "f64"}))


def reference(scene, t_eval):
    """Positions (rock, time, 3) from solve_ivp of the drag ODE, coefficients from the scene's values."""
    g = scene.world.gravity
    k = 3.0 * scene.world.air_density * scene.bed.drag_coefficient / (8.0 * scene.bed.density)
    out = []
    for x0, v0, r in zip(X0, V0, R):
        def rhs(_, y):
            v = y[3:]
            return np.concatenate([v, -k / r * np.linalg.norm(v) * v - np.array([0.0, 0.0, g])])

        sol = solve_ivp(rhs, (0.0, T), np.concatenate([x0, v0]), method="DOP853", t_eval=t_eval, rtol=1e-12,
                        atol=1e-12)
        assert sol.success
        out.append(sol.y[:3].T)
    return np.array(out)


def max_error(sim, integrator, dt):
    steps = int(round(T / dt))
    every = int(round(EVERY_S / dt))
    xs = probes.fly_only(sim, X0, V0, R, dt, steps, every, integrator, "quadratic")
    t = np.arange(1, steps // every + 1) * every * dt
    return float(np.max(np.linalg.norm(xs - reference(sim.scene, t), axis=2))), xs, t


def test_drag_matters_and_rk4_matches_solve_ivp(sim):
    err, xs, t = max_error(sim, "rk4", 1e-3)
    assert err < 1e-8, err
    # the drag is not negligible here: the drag-free parabola is metres away after 2 s
    parabola = X0[:, None, :] + V0[:, None, :] * t[None, :, None] - 0.5 * sim.scene.world.gravity * np.array(
        [0.0, 0.0, 1.0]) * t[None, :, None] ** 2
    assert np.min(np.linalg.norm(xs[:, -1] - parabola[:, -1], axis=1)) > 1.0


@pytest.mark.parametrize("integrator, dt, order", [("rk4", 0.05, 4), ("heun", 0.004, 2),
                                                   ("symplectic_euler", 0.004, 1)])
def test_each_integrator_converges_at_its_order(sim, integrator, dt, order):
    coarse, _, _ = max_error(sim, integrator, dt)
    fine, _, _ = max_error(sim, integrator, dt / 2)
    assert fine > 1e-9  # far above the reference and round-off floor (~1e-10 m): the ratio is truncation
    assert 2 ** order * 0.8 < coarse / fine < 2 ** order * 1.25, (coarse, fine)
