"""Ground contact (engine/flight.py) against closed forms, through the public face (Simulation, set_rocks,
rock_arrays), for the three integrators at three step lengths.

A rock dropped from rest from a height h above its resting height z_0 = ground_z + r meets the ground at
v = sqrt(2 g h); with restitution e it leaves at e v and rises to e^2 h, then e^4 h after the next bounce. A rock
that also moves sideways at u loses the Coulomb impulse mu (1 + e) v at the impact: it leaves at
max(u - mu (1 + e) v, 0) sideways. A rock sliding on the ground at s decelerates at mu g and stops after
s^2 / (2 mu g), in the direction it had.

Tolerances, and why each integrator meets them:
* Heun and RK4 are exact for gravity alone, and the contact is resolved on the exact parabola through the
  end-of-step state, so the impact speed is exact at any dt: rebound speed, sideways speed and the apex from
  the state agree to f32 round-off (TOL, 2e-4 m or m/s over ~1,000 steps). The apex read off the sampled
  heights is lower by at most g (dt/2)^2 / 2 (the true apex lies within dt/2 of a sample).
* Symplectic Euler conserves z + v^2 / 2g - v dt / 2 instead of the energy (with v_n = -g n dt,
  z_n = h - g dt^2 n (n + 1) / 2), so the parabola it hands to the contact is low: a fall from rest meets the
  ground g dt / 2 too slowly, and each rise and fall after a bounce loses another g dt. The k-th rebound
  (k = 0, 1, ...) is then slow by g dt (e^(k+1) / 2 + e + ... + e^k) and its apex, for a rebound speed w, low
  by w times that / g plus w dt / 2; the test allows 1.25 times these, and mu (1 + e) g dt / 2 of sideways
  speed lost to the larger impulse.
* Sliding is the same first-order update for every integrator (speed -= mu g dt, then x += v dt): the speed
  drops by mu g dt a step (to f32 round-off, a few 1e-7 m/s a step), and the distance is short of s^2 / (2 mu g) by at most s dt plus the
  rest_speed^2 / (2 mu g) not slid once the speed falls below rest_speed.
"""

import numpy as np
import pytest

from scenes_util import reference_scene
from taichi_rocks.config.scene import scene_with
from taichi_rocks.engine.simulation import Simulation  # the public face; the one engine import here

pytestmark = pytest.mark.usefixtures("taichi_cpu")

G, E, MU, REST = 9.81, 0.5, 0.3, 0.05
H_DROP, H_OBLIQUE, U_FAST, U_SLOW, S_SLIDE = 0.8, 0.5, 3.0, 0.5, 2.5
TOL = 2e-4
DTS = (0.002, 0.005, 0.01)
INTEGRATORS = ("symplectic_euler", "heun", "rk4")
FLYING, SLIDING, RESTING = 1, 2, 0


def contact_scene():
    """The reference tests' scene with the car parked (so nothing but the test rocks moves, and no tire
    throws) and no air drag (the closed forms are for gravity alone)."""
    return reference_scene(speed=0.0, world={"restitution": E, "ground_friction": MU, "rest_speed": REST},
                           effects={"drag": "none"})


# test rocks: (id, offset from the bed centre (m), height above rest, velocity)
DROP, OBLIQUE, STUCK, SLIDE = 0, 1, 2, 3
ROCKS = {DROP: ((0.0, 3.0), H_DROP, (0.0, 0.0, 0.0)),
         OBLIQUE: ((-3.5, 1.5), H_OBLIQUE, (U_FAST, 0.0, 0.0)),
         STUCK: ((2.5, 1.5), H_OBLIQUE, (0.0, U_SLOW, 0.0)),
         SLIDE: ((0.0, -3.0), 0.0, (0.6 * S_SLIDE, 0.8 * S_SLIDE, 0.0))}


def run(integrator, dt, seconds=1.15):
    """Put the test rocks in flight (the slider on the ground, sliding), step, and return the test rocks' local
    positions (z: the height above rest), velocities (float64) and phases, at the start (row 0) and after
    every step."""
    sim = Simulation(scene_with(contact_scene(), {"sim.integrator": integrator, "sim.dt": dt}))
    sim.coast = False  # every step through the stepping path
    ids = np.array(sorted(ROCKS))
    st = sim.state()
    r = st["radii"][ids]
    centre = st["bed_center"]
    z0 = st["bed_center"][2] + r  # ground_z + r
    pos = np.array([[centre[0] + ROCKS[i][0][0], centre[1] + ROCKS[i][0][1], z0[k] + ROCKS[i][1]]
                    for k, i in enumerate(ids)])
    vel = np.array([ROCKS[i][2] for i in ids])
    sim.set_rocks(ids[:3], positions=pos[:3], velocities=vel[:3], phase=FLYING)
    sim.set_rocks(ids[3:], positions=pos[3:], velocities=vel[3:], phase=SLIDING)
    z_rest = sim.rock_arrays()["pos"][ids, 2].astype(np.float64) - np.array([ROCKS[i][1] for i in ids])
    xs, vs, ph = [], [], []
    for k in range(int(round(seconds / dt)) + 1):
        if k:
            sim.step()
        a = sim.rock_arrays()
        xs.append(a["pos"][ids].astype(np.float64))
        vs.append(a["vel"][ids].astype(np.float64))
        ph.append(a["phase"][ids])
    xs, vs, ph = np.array(xs), np.array(vs), np.array(ph)
    xs[:, :, 2] -= z_rest  # height above the resting height
    return xs, vs, ph


@pytest.fixture(scope="module", params=[(i, dt) for i in INTEGRATORS for dt in DTS],
                ids=lambda p: f"{p[0]}-dt{p[1]:g}")
def flight(request):
    integrator, dt = request.param
    xs, vs, ph = run(integrator, dt)
    return integrator, dt, xs, vs, ph


def bounces(vz):
    """Indices of the steps that end just after a bounce (vertical velocity turns from down to up)."""
    return np.flatnonzero((vz[1:] > 0.0) & (vz[:-1] <= 0.0)) + 1


def leaving_speed(z, vz):
    """The speed at which a rock left the ground, from a state on its way up (the parabola through it)."""
    return np.sqrt(vz * vz + 2.0 * G * z)


def exact_integrator(integrator):
    return integrator in ("heun", "rk4")


def test_bounce_rebound_speed_and_apex(flight):
    integrator, dt, xs, vs, _ = flight
    z, vz = xs[:, DROP, 2], vs[:, DROP, 2]
    b = bounces(vz)
    assert len(b) >= 2, "two bounces expected within the run"
    v = np.sqrt(2.0 * G * H_DROP)
    for k, i in enumerate(b[:2]):
        w = E ** (k + 1) * v  # the rebound speed
        expected_apex = w * w / (2.0 * G)  # e^(2k+2) h
        sample = G * (dt / 2) ** 2 / 2
        if exact_integrator(integrator):
            tol_speed, tol_apex = TOL, TOL + sample
        else:
            slow = G * dt * (E ** (k + 1) / 2 + sum(E ** j for j in range(1, k + 1)))
            tol_speed = 1.25 * slow + TOL
            tol_apex = 1.25 * (w * slow / G + w * dt / 2) + sample + TOL
        assert leaving_speed(z[i], vz[i]) == pytest.approx(w, abs=tol_speed), k
        end = b[k + 1] if k + 1 < len(b) else len(z)
        apex = z[i:end].max()
        assert apex == pytest.approx(expected_apex, abs=tol_apex), (k, apex, expected_apex)
        assert expected_apex == pytest.approx(E ** (2 * k + 2) * H_DROP)
    assert np.all(xs[:, DROP, :2] == xs[0, DROP, :2])  # straight down and up: no sideways motion


def test_oblique_impact_loses_the_coulomb_impulse(flight):
    integrator, dt, xs, vs, ph = flight
    v = np.sqrt(2.0 * G * H_OBLIQUE)
    tol = TOL if exact_integrator(integrator) else 1.25 * MU * (1.0 + E) * G * dt / 2 + TOL
    i = bounces(vs[:, OBLIQUE, 2])[0]
    before, after = vs[i - 1, OBLIQUE, :2], vs[i, OBLIQUE, :2]
    assert before == pytest.approx([U_FAST, 0.0], abs=1e-6)  # no drag: the sideways speed is kept in flight
    assert after[0] == pytest.approx(U_FAST - MU * (1.0 + E) * v, abs=tol) and after[1] == 0.0
    assert leaving_speed(xs[i, OBLIQUE, 2], vs[i, OBLIQUE, 2]) == pytest.approx(
        E * v, abs=TOL if exact_integrator(integrator) else 1.25 * E * G * dt / 2 + TOL)
    # an impulse larger than the sideways momentum stops the sideways motion, never reverses it
    j = bounces(vs[:, STUCK, 2])[0]
    assert vs[j - 1, STUCK, 1] == pytest.approx(U_SLOW, abs=1e-6) and MU * (1.0 + E) * v > U_SLOW
    assert np.all(vs[j:, STUCK, :2] == 0.0)
    assert np.all(xs[j:, STUCK, :2] == xs[j, STUCK, :2])


def test_slide_decelerates_at_mu_g_and_stops_after_the_closed_form_length(flight):
    integrator, dt, xs, vs, ph = flight
    speed = np.hypot(vs[:, SLIDE, 0], vs[:, SLIDE, 1])
    sliding = ph[:, SLIDE] == SLIDING
    n = int(np.count_nonzero(sliding))  # row 0 (the start) and the steps it slid through
    assert np.all(sliding[:n]) and np.all(ph[n:, SLIDE] == RESTING) and n < len(ph)
    expected = S_SLIDE - MU * G * dt * np.arange(n)
    np.testing.assert_allclose(speed[:n], expected, atol=4e-7 * n)  # f32: a few roundings of S a step
    assert expected[-1] > REST and S_SLIDE - MU * G * dt * n <= REST  # stopped once below rest_speed
    assert np.all(vs[n:, SLIDE] == 0.0) and np.all(xs[:, SLIDE, 2] == 0.0)  # pinned to the ground
    moved = xs[-1, SLIDE, :2] - xs[0, SLIDE, :2]
    length = np.hypot(*moved)
    closed = S_SLIDE ** 2 / (2.0 * MU * G)
    assert closed - S_SLIDE * dt - REST ** 2 / (2.0 * MU * G) - TOL <= length <= closed + TOL, (length, closed)
    np.testing.assert_allclose(moved / length, [0.6, 0.8], atol=1e-5)  # in the direction it had
