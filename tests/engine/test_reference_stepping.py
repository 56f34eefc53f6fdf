"""Active stepping against an independent NumPy reference: a bed of 3,000 rocks following a car that drives
straight at 15 m/s through a 4.5 m bed, stepped 400 times by the engine (the default stepping, "active") and by a plain NumPy loop
written here from the module docstrings: the flight (engine/flight.py: symplectic Euler, quadratic drag, ground
contact at the time of impact, sliding), recycling to the leading crescent (engine/bed.py) and the tire pass by
brute force (engine/tires.py: every rock against every rear-tire ray, closest-point test, first tire wins, the
"uniform" launch model), with "ray" detection and with "patch" (engine/patch.py: the ray swept over the step
and the tread's footprint, boxes for a straight drive). The random numbers are counter-based (engine/randomness.py), so the reference draws
the engine's with the NumPy twins ``uniform01_np`` (checked against known answers in test_randomness_known.py);
the vehicle's pose is the closed form of a straight drive at constant speed (checked against the engine's poses).

The reference starts from the engine's initial rocks and works in float32, as the engine does. It must launch
the same rocks at the same steps with the same velocities, recycle as many rocks, and end with every rock
within round-off of the engine's position (1e-5 m).
1.6 s at dt = 4 ms: about 130 launches with "ray" (about 5 times as many with "patch") and 10,000
recycles; the largest difference seen is one float32 ulp.
Only ``Simulation`` (state, rock_arrays, tire_rays) is used from the engine.
"""

import numpy as np
import pytest

from scenes_util import reference_scene
from taichi_rocks.engine.randomness import uniform01_np  # the hash's NumPy twin (known answers elsewhere)
from taichi_rocks.engine.simulation import Simulation

pytestmark = pytest.mark.usefixtures("taichi_cpu")

SPEED = 15.0
STEPS = 400
F = np.float32
FLYING, SLIDING, RESTING = 1, 2, 0


class Reference:
    """The rock bed stepped in NumPy (float32), from the equations of the engine's module docstrings."""

    def __init__(self, scene, rocks: dict):
        w, bed, car = scene.world, scene.bed, scene.vehicles[0]
        self.patch = scene.sim.detection == "patch"
        self.patch_tol = F(1e-4)  # how far above the tire's bottom a run-over rock's bottom may be (patch.py)
        self.seed = scene.seed & 0x7FFFFFFF
        self.clock_dt = float(scene.sim.dt)  # the clock runs in float64; the kernels take dt as float32
        self.dt = F(scene.sim.dt)
        self.g, self.ground = F(w.gravity), F(w.ground_z)
        self.e, self.mu_g, self.rest = F(w.restitution), F(w.ground_friction), F(w.rest_speed)
        self.quad = F(3.0 * w.air_density * bed.drag_coefficient / (8.0 * bed.density))  # a = -(quad/r)|v|v
        self.R = F(bed.radius)
        self.thickness = F(2.0 * bed.rock_radius[1])
        la = scene.launch
        self.a_min, self.a_max = F(np.radians(la.release_angle[0])), F(np.radians(la.release_angle[1]))
        self.spread = F(np.radians(la.spread))
        self.car = car
        self.pos = rocks["pos"].astype(F).copy()
        self.vel = rocks["vel"].astype(F).copy()
        self.r = rocks["radius"].astype(F)
        self.mu = rocks["friction"].astype(F)
        self.phase = rocks["phase"].astype(np.int32).copy()
        self.hit = np.full(len(self.r), -1)
        self.ids = np.arange(len(self.r))
        self.time, self.step_count, self.recycles = 0.0, 0, 0
        self.centre = np.zeros(2)
        self.lead = np.array([1.0, 0.0])

    # -------------------------------------------------------------------------------- the car (host, f64)
    def car_position(self, t):
        return np.array([SPEED * t, 0.0])

    def rear_tires(self, t):
        """(centre, bottom, wheel velocity, heading, omega R) of the rear tires, left then right: a rear wheel
        sits at body offset (-wheelbase/2, +-track/2), omega R = V (1 + slip) (motion/vehicles.py)."""
        c, car = self.car_position(t), self.car
        out = []
        for side in (1.0, -1.0):
            x, y = c[0] - 0.5 * car.wheelbase, c[1] + side * 0.5 * car.track
            out.append((np.array([x, y, self.ground + car.tire_radius]), np.array([x, y, self.ground]),
                        np.array([SPEED, 0.0]), np.array([1.0, 0.0]), SPEED * (1.0 + car.slip)))
        return out

    # -------------------------------------------------------------------------------- one step
    def step(self):
        self.step_count += 1
        self.time += self.clock_dt
        new = self.car_position(self.time)
        move = new - self.centre
        self.centre = new
        self.fly()
        self.recycle(move)
        return self.tires()

    def accel(self, v, r):
        speed = np.sqrt((v * v).sum(axis=1))
        a = -(self.quad / r)[:, None] * speed[:, None] * v
        a[:, 2] -= self.g
        return a

    def fly(self):
        dt = self.dt
        f = np.flatnonzero(self.phase == FLYING)
        s = np.flatnonzero(self.phase == SLIDING)
        if len(f):  # symplectic Euler: v += a dt, x += v dt
            r = self.r[f]
            v = self.vel[f] + dt * self.accel(self.vel[f], r)
            x = self.pos[f] + dt * v
            self.contact(f, x, v, r)
        if len(s):  # Coulomb friction mu g on the ground, then rest
            self.slide(s)

    def contact(self, idx, x, v, r):
        """Penetration resolved at the time of impact tau: 1/2 g tau^2 + v_z tau + depth = 0; the normal
        velocity reflected with e, the tangential one less mu (1 + e) |v_n|; then the rest of the step flown."""
        floor = self.ground + r
        phase = np.full(len(idx), FLYING)
        below = x[:, 2] < floor
        for k in np.flatnonzero(below):
            depth = floor[k] - x[k, 2]
            vz = min(v[k, 2], F(0.0))
            tau = depth / max(-vz, F(1e-12))
            disc = vz * vz - F(2.0) * self.g * depth
            if self.g > 0 and disc >= 0:
                tau = (-vz - np.sqrt(disc)) / self.g
            tau = min(tau, self.dt)
            v_impact = min(vz + self.g * tau, F(0.0))
            v_out = -self.e * v_impact
            vt = v[k, :2].copy()
            vt_norm = np.sqrt((vt * vt).sum())
            loss = self.mu_g * (F(1.0) + self.e) * (-v_impact)
            if vt_norm > 0:
                vt *= max(vt_norm - loss, F(0.0)) / vt_norm
            x[k, 2] = floor[k] + v_out * tau - F(0.5) * self.g * tau * tau
            v[k] = [vt[0], vt[1], v_out - self.g * tau]
            if v_out < self.rest or x[k, 2] < floor[k]:
                x[k, 2] = floor[k]
                v[k, 2] = 0.0
                phase[k] = SLIDING
        self.pos[idx], self.vel[idx], self.phase[idx] = x, v, phase

    def slide(self, idx):
        vt = self.vel[idx, :2].copy()
        speed = np.sqrt((vt * vt).sum(axis=1))
        new = speed - self.mu_g * self.g * self.dt
        stop = (new <= self.rest) | (speed <= 0)
        go = ~stop
        vt[go] *= (new[go] / speed[go])[:, None]
        vt[stop] = 0.0
        x = self.pos[idx]
        x[go, :2] += vt[go] * self.dt
        x[:, 2] = self.ground + self.r[idx]
        self.pos[idx] = x
        self.vel[idx] = np.column_stack([vt, np.zeros(len(idx), F)])
        self.phase[idx] = np.where(stop, RESTING, SLIDING)

    def recycle(self, move):
        """Rocks outside the disk |p - c| <= R (or R below the ground) re-enter uniformly in the leading crescent
        {|p - c| <= R, |p - c + d| > R}: y by rejection with density proportional to the chord length
        L(y) = min(2 w, |d|), w = sqrt(R^2 - y^2), then x uniform on the chord [w - L, w] (frame: x along d)."""
        c = self.centre.astype(F)
        d = self.pos[:, :2] - c
        out = np.flatnonzero(((d * d).sum(axis=1) > self.R * self.R) | (self.pos[:, 2] < self.ground - self.R))
        if np.hypot(*move) > 1e-9:
            self.lead = move / np.hypot(*move)
        m, lead = move.astype(F), self.lead.astype(F)
        for i in out:
            q = self.crescent_point(c, m, lead, int(self.ids[i]))
            self.pos[i] = [q[0], q[1], self.ground + self.r[i]]
            self.vel[i] = 0.0
            self.phase[i] = RESTING
            self.recycles += 1

    def crescent_point(self, c, move, lead, rock):
        u = lambda stream: uniform01_np(self.seed, rock, self.step_count, stream)
        R = self.R
        e1, dist = lead, np.sqrt((move * move).sum())
        if dist > self.thickness:
            e1 = move / dist
        else:
            dist = self.thickness
        e2 = np.array([-e1[1], e1[0]], F)
        chord_max = min(F(2.0) * R, dist)
        y, chord = F(0.0), chord_max
        for attempt in range(32):
            y = R * (F(2.0) * u(2 * attempt) - F(1.0))
            w = np.sqrt(max(R * R - y * y, F(0.0)))
            chord = min(F(2.0) * w, dist)
            if u(2 * attempt + 1) * chord_max <= chord:
                break
        w = np.sqrt(max(R * R - y * y, F(0.0)))
        x = w - chord * u(101)
        q = x * e1 + y * e2
        r2 = (q * q).sum()
        if r2 > R * R:
            q *= R / np.sqrt(r2) * F(1.0 - 1e-6)
        return c + q

    def tires(self):
        """Brute force over every rock: a rock (c, r) not flying and not launched this step is hit by the ray a
        -> b when |c - (a + t* (b - a))| <= r, t* = clamp((c - a).(b - a) / |b - a|^2, 0, 1) ("ray"), or, with
        "patch", when it is within r of the rectangle the ray swept since the previous step or (its bottom on
        the ground) within r in XY of the tread's footprint (tire_width x contact_length around the bottom)
        swept over the step: for a straight drive along +x both are boxes. The first tire in order launches it
        (uniform model) if its launch speed exceeds rest_speed. Returns the ids launched."""
        launched = []
        prev = self.rear_tires(self.time - self.clock_dt if self.step_count > 1 else 0.0)
        for (a, b, wheel, fwd, spin), (a0, b0, *_) in zip(self.rear_tires(self.time), prev):
            near = self.patch_hits(a0, b0, b) if self.patch else self.ray_hits(a, b)
            cand = np.flatnonzero(near & (self.hit != self.step_count) & (self.phase != FLYING))
            for i in cand:
                v = self.launch_velocity(wheel.astype(F), fwd.astype(F), F(spin), self.mu[i], int(self.ids[i]))
                if np.sqrt((v * v).sum()) > self.rest:
                    self.hit[i] = self.step_count
                    self.vel[i] = v
                    self.phase[i] = FLYING if v[2] > 0 else SLIDING
                    launched.append(i)
        return sorted(launched)

    def ray_hits(self, a, b):
        a, b = a.astype(F), b.astype(F)
        d = b - a
        t = np.clip(((self.pos - a) @ d) / (d @ d), F(0.0), F(1.0))
        q = a + t[:, None] * d
        return ((self.pos - q) ** 2).sum(axis=1) <= self.r * self.r

    def patch_hits(self, a0, b0, b1):
        c, r2 = self.pos, self.r * self.r
        x0, x1, y, top = F(b0[0]), F(b1[0]), F(b0[1]), F(a0[2])
        zero = F(0.0)
        dx = np.maximum(np.maximum(x0 - c[:, 0], zero), c[:, 0] - x1)
        dz = np.maximum(np.maximum(self.ground - c[:, 2], zero), c[:, 2] - top)
        swept = dx * dx + (c[:, 1] - y) ** 2 + dz * dz <= r2
        hl, hw = F(0.5 * self.car.contact_length), F(0.5 * self.car.tire_width)
        fx = np.maximum(np.maximum(x0 - hl - c[:, 0], zero), c[:, 0] - (x1 + hl))
        fy = np.maximum(np.abs(c[:, 1] - y) - hw, zero)
        on_ground = c[:, 2] - self.r <= self.ground + self.patch_tol
        return swept | (on_ground & (fx * fx + fy * fy <= r2))

    def launch_velocity(self, wheel, fwd, spin, mu, rock):
        """v_xy = v_wheel - omega R cos(alpha) Rot(beta) f, v_z = mu |omega R| sin(alpha); alpha uniform in the
        release range, beta uniform in [-spread, spread]."""
        ua = uniform01_np(self.seed, rock, self.step_count, 201)
        ub = uniform01_np(self.seed, rock, self.step_count, 202)
        alpha = self.a_min + (self.a_max - self.a_min) * ua
        beta = self.spread * (F(2.0) * ub - F(1.0))
        back = -spin * np.cos(alpha)
        cb, sb = np.cos(beta), np.sin(beta)
        fx, fy = cb * fwd[0] - sb * fwd[1], sb * fwd[0] + cb * fwd[1]
        return np.array([wheel[0] + back * fx, wheel[1] + back * fy, mu * abs(spin) * np.sin(alpha)], F)


@pytest.fixture(scope="module", params=["ray", "patch"])
def runs(request):
    scene = reference_scene(speed=SPEED, sim={"detection": request.param})
    sim = Simulation(scene)
    assert sim.plan.active and sim.plan.throw == "uniform" and sim.plan.patch == (request.param == "patch")
    assert np.all(sim.state()["bed_center"][:2] == 0.0) and np.all(sim.origin == 0.0)  # local = world here
    ref = Reference(scene, sim.rock_arrays())
    engine_launches, ref_launches, worst_tire = [], [], 0.0
    for _ in range(STEPS):
        before = sim.launches_total
        sim.step()
        got = ref.step()
        arrays = sim.rock_arrays()
        engine_launches.append(np.flatnonzero(arrays["hit_step"] == sim.step_count).tolist())
        ref_launches.append(got)
        assert sim.launches_total - before == len(engine_launches[-1])
        rays = np.array([(a, b) for a, b, *_ in ref.rear_tires(ref.time)])
        worst_tire = max(worst_tire, float(np.max(np.abs(sim.tire_rays() - rays))))
    return sim, ref, engine_launches, ref_launches, worst_tire


def test_the_reference_drives_like_the_engine(runs):
    sim, ref, _, _, worst_tire = runs
    assert sim.time == ref.time and sim.step_count == ref.step_count == STEPS
    np.testing.assert_allclose(sim.state()["bed_center"][:2], ref.centre, atol=1e-9)
    assert worst_tire < 1e-7  # the closed-form rear tires are the engine's (path arithmetic: ~1e-8 m)


def test_same_launches_at_the_same_steps(runs):
    sim, ref, engine, reference, _ = runs
    total = sum(len(x) for x in reference)
    assert total > 100, total  # the comparison is not vacuous
    for step, (a, b) in enumerate(zip(engine, reference), start=1):
        assert a == b, f"step {step}: engine launched {a}, the reference {b}"
    assert sim.launches_total == total


def test_same_recycles_and_positions_within_round_off(runs):
    sim, ref, _, _, _ = runs
    assert sim.recycles_total == ref.recycles > 500
    arrays = sim.rock_arrays()
    np.testing.assert_array_equal(arrays["phase"], ref.phase)
    err = np.abs(arrays["pos"].astype(np.float64) - ref.pos.astype(np.float64)).max(axis=1)
    assert err.max() < 1e-5, (err.max(), int(err.argmax()))
    np.testing.assert_allclose(arrays["vel"], ref.vel, atol=1e-5)
    flying = ref.phase == FLYING
    assert flying.sum() > 10 and (ref.phase == SLIDING).sum() + flying.sum() < len(flying)
