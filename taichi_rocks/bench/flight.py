"""1a. Integrator x dt: accuracy of the flight against closed forms, and the flight pass's cost.

One rock per case is flown for 2 s (no ground) by the flight part of the engine's rock pass alone
(engine/probes.py ``fly_only``), in the lanes scene's World, against:
  * gravity only (parabola):  x = x0 + v0 t - g t^2 / 2 z;
  * linear (Stokes) drag, a = -g z - v / tau, tau = r^2 / LINEAR_DRAG:
        x = x0 + v_inf t + (v0 - v_inf) tau (1 - exp(-t / tau)),  v_inf = -g tau z;
  * quadratic drag, thrown straight up at w0, a = -g - (g / v_t^2) |v| v, v_t = sqrt(g r / QUAD_DRAG):
        rise v = v_t tan(atan(w0 / v_t) - g t / v_t) up to the apex t_a = v_t atan(w0 / v_t) / g,
        fall v = -v_t tanh(g (t - t_a) / v_t)  (heights: the integrals of these, below).
LINEAR_DRAG and QUAD_DRAG are the scene's (engine/params.py ``drag_coefficients``). Cost: the flight pass with
every rock of the main scene flying, per (integrator, drag).
"""

from __future__ import annotations

import math

import numpy as np

from ..engine import probes
from ..engine.params import drag_coefficients
from .config import ACC_T, CASE_OF_DRAG, DRAGS, G, INTEGRATORS, SAMPLE_EVERY, Config
from .measure import timed_call


def exact_gravity(x0, v0, t):
    t = np.asarray(t)[:, None]
    return x0 + v0 * t + 0.5 * np.array([0.0, 0.0, -G]) * t ** 2


def exact_linear(x0, v0, tau, t):
    t = np.asarray(t)[:, None]
    vinf = np.array([0.0, 0.0, -G * tau])
    return x0 + vinf * t - (v0 - vinf) * tau * np.expm1(-t / tau)


def exact_quadratic_vertical(z0, w0, vt, t):
    """Height of a rock thrown straight up at w0 > 0 with a = -g - (g / vt^2) |v| v."""
    t = np.asarray(t, float)
    th0 = math.atan(w0 / vt)
    ta = vt * th0 / G
    za = z0 - vt * vt / G * math.log(math.cos(th0))
    rise = z0 + vt * vt / G * np.log(np.cos(th0 - G * np.minimum(t, ta) / vt) / math.cos(th0))
    fall = za - vt * vt / G * np.log(np.cosh(G * np.maximum(t - ta, 0.0) / vt))
    return np.where(t <= ta, rise, fall)


CLOSED_FORMS = {
    "gravity": "x0 + v0 t - g t^2/2 z",
    "linear": "x0 + v_inf t + (v0 - v_inf) tau (1 - exp(-t/tau)), v_inf = -g tau z, tau = r^2 / L",
    "quadratic": "vertical: rise v = v_t tan(atan(v0/v_t) - g t/v_t), fall v = -v_t tanh(g (t-t_a)/v_t)"}


def flight_cases(scene, real=np.float64) -> dict:
    """Test rocks per drag case: case -> ([(x0, v0, r)], exact(x0, v0, r, t) -> positions, info). The drag
    coefficients are the scene's as a World of precision ``real`` stores them (like the radii, below)."""
    lin, quad = (float(np.asarray(k).astype(real)) for k in drag_coefficients(scene))
    if abs(scene.world.gravity - G) >= 1e-4:
        raise ValueError(f"the closed forms assume g = {G} m/s^2; the scene has {scene.world.gravity}")
    radii = (0.015, 0.03, 0.05)
    x0 = np.array([0.0, 0.0, 1.0])
    grav = [(x0, np.array([12.0, 2.0, 15.0]), 0.03), (x0 + [1.0, 1.0, 0.0], np.array([-6.0, 4.0, 9.0]), 0.02),
            (x0 - [1.0, 0.0, 0.0], np.array([3.0, 0.0, 22.0]), 0.05)]
    cases = {"gravity": (grav, lambda x, v, r, t: exact_gravity(x, v, t), {})}
    lin_rocks = [(x0, np.array([10.0, 0.0, 15.0]), r) for r in radii]
    cases["linear"] = (lin_rocks, lambda x, v, r, t: exact_linear(x, v, r * r / lin, t),
                       {"tau_s": [r * r / lin for r in radii]})
    quad_rocks = [(x0, np.array([0.0, 0.0, 20.0]), r) for r in radii]

    def q_exact(x, v, r, t):
        z = exact_quadratic_vertical(x[2], v[2], math.sqrt(G * r / quad), t)
        return np.stack([np.full_like(z, x[0]), np.full_like(z, x[1]), z], axis=1)

    cases["quadratic"] = (quad_rocks, q_exact, {"terminal_speed_m_s": [math.sqrt(G * r / quad) for r in radii],
                                                "launch_speed_m_s": 20.0})
    return cases


def fly(sim, x0_local, v0, radius, dt, integrator, drag, duration=ACC_T, gravity=True):
    """Fly test rocks (engine/probes.py ``fly_only``); returns the sample times and the local positions
    (k, samples, 3), sampled every SAMPLE_EVERY s."""
    steps = int(round(duration / dt))
    every = int(round(SAMPLE_EVERY / dt))
    assert abs(every * dt - SAMPLE_EVERY) < 1e-9 and abs(steps * dt - duration) < 1e-9, dt
    xs = probes.fly_only(sim, x0_local, v0, radius, dt, steps, every, integrator, drag, gravity=gravity)
    return np.arange(every, steps + 1, every) * dt, xs


def _max_error(sim, rocks, exact, xs, t) -> float:
    err = 0.0
    for j, (x0, v0, r) in enumerate(rocks):
        r_stored = float(np.asarray(r).astype(sim.world.np_real()))
        ref = exact(x0, v0, r_stored, t)
        err = max(err, float(np.max(np.linalg.norm(xs[j] - ref, axis=1))))
    return err


def integrator_sweep(sims: dict, cfg: Config, prog) -> dict:
    """Max position error of every (precision, drag case, integrator, dt) against its closed form."""
    rows, meta = [], {}
    for prec, sim in sims.items():
        cases = flight_cases(sim.scene, sim.world.np_real())
        for drag in DRAGS:
            case = CASE_OF_DRAG[drag]
            rocks, exact, info = cases[case]
            meta[case] = info
            x0, v0, rad = (np.array([r[k] for r in rocks]) for k in range(3))
            for integ in INTEGRATORS:
                if prec == "f64" and integ == "symplectic_euler":
                    continue  # first order: its error never comes near the f64 level
                for dt in cfg.acc_dts:
                    t, xs = fly(sim, x0, v0, rad, dt, integ, drag)
                    rows.append({"precision": prec, "integrator": integ, "case": case, "drag": drag, "dt": dt,
                                 "max_error_m": _max_error(sim, rocks, exact, xs, t)})
                prog(f"flight {prec} {case} {integ}")
    return {"rows": rows, "cases": meta, "flight_s": ACC_T, "sampled_every_s": SAMPLE_EVERY,
            "closed_forms": dict(CLOSED_FORMS)}


_EFFECT_VARIANTS = (("symplectic_euler", "none", False, "none"), ("symplectic_euler", "none", True, "none"),
                    ("symplectic_euler", "quadratic", True, "none"), ("symplectic_euler", "quadratic", True, "bounce"))


def flight_cost(sim, pairs, reps: int, prog, effects: bool = True) -> dict:
    """ms per flight pass with every rock flying, per (integrator, drag) (gravity on, ground contact off),
    plus, with ``effects``, gravity off and ground bounce variants; all variants timed interleaved. Leaves
    every rock of ``sim`` flying."""
    n = sim.n_rocks
    rng = np.random.default_rng(11)
    vel = np.stack([rng.uniform(-5, 5, n), rng.uniform(-2, 2, n), rng.uniform(2, 15, n)], axis=1)
    probes.set_flying(sim, vel)
    variants = [(i, d, True, "none") for i, d in pairs]
    if effects:
        variants += [v for v in _EFFECT_VARIANTS if v not in variants]
    fns = {}
    for v in variants:
        integ, drag, grav, ground = v
        fns[v] = probes.rock_pass_call(sim, flight=True, integrator=integ, gravity=grav, drag=drag, ground=ground)
        fns[v]()
        fns[v]()  # compile, warm
        prog(f"flight cost {integ} {drag}")
    times = {v: [] for v in variants}
    for _ in range(max(3, reps)):
        for v, fn in fns.items():
            times[v].append(timed_call(fn))
    med = {v: 1e3 * float(np.median(ts)) for v, ts in times.items()}
    out = {}
    for (integ, drag, grav, ground), ms in med.items():
        if grav and ground == "none":
            out.setdefault(integ, {})[drag] = ms
    res = {"n_rocks": n, "ms_per_step": out, "note": "every rock flying, flight pass alone, variants interleaved"}
    if effects:
        se = lambda d, g, gr: med[("symplectic_euler", d, g, gr)]
        res["effects_all_flying_ms"] = {
            "gravity (symplectic Euler, no drag)": se("none", True, "none") - se("none", False, "none"),
            "quadratic drag (symplectic Euler)": se("quadratic", True, "none") - se("none", True, "none"),
            "ground contact bounce (symplectic Euler, quadratic)": se("quadratic", True, "bounce")
                                                                 - se("quadratic", True, "none")}
    return res
