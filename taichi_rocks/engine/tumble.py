"""Stones that tumble: each rock's angular velocity and orientation (compiled in only with the Plan's ``spin``).

State (engine/rockfields.py): ``spin``, the angular velocity omega (rad/s, world axes), and ``orient``, a unit
quaternion q = (x, y, z, w) turning the rock's own frame into the world's (the export's convention; a
prototype point p of the rock is at centre + r q p q*).

Dynamics: the stone is the translation's sphere (radius r, uniform density rho, mass m = 4/3 pi rho r^3) with
the inertia of a solid sphere, I = 2/5 m r^2 about every axis. An isotropic inertia makes torque-free
rotation trivial (Euler's equations: I domega/dt = 0): in the air omega is constant and the orientation is
exactly

    q(t + h) = exp(omega h / 2) q(t),    exp(omega h / 2) = (sin(|omega| h / 2) omega / |omega|, cos(|omega| h / 2))

(the quaternion kinematics dq/dt = 1/2 (omega, 0) q for world-frame omega), applied per step and then
renormalised against round-off (:func:`turn`).

Contact impulses: an impulse J at a contact point c (arm a = c - centre) changes the spin by
Delta omega = (a x J) / I. The engine's contacts give the velocity change Delta v = J / m of the centre, so
Delta omega = 5 (a x Delta v) / (2 r^2) and the mass cancels (:func:`kick`); the normal part of Delta v has no
moment about a sphere's centre (a is along the normal), so the whole Delta v may be passed. The ground
(a = -r z): a bounce's tangential Coulomb impulse (engine/flight.py ``ground_contact``; the step's rotation is
split at the time of impact) and the friction that decelerates a sliding rock (``slide``, each step). The spin
does not feed back into the translation: the contacts compute their impulses from the centre's velocity, as
without spin, so every position and launch is the same bit for bit with spin on or off. (A real sphere would
stop slipping and roll; the engine's rock slides to rest, and its spin grows with the friction until it rests.)
Impacts on vehicle bodies call :func:`apply_impulse` with their own arm and Delta v.

Rest: a rock at rest has no spin (omega = 0, the tiles do not store it) and keeps its orientation (the tiles
do store it).

Launch (:func:`launch_spin`): the stone rolls off the tread. Tire of signed tread speed s = omega_w R
(engine/world.py SPIN; s < 0 reversing), wheel velocity v_w, heading f, axle direction l = z x f (its spin is
Omega = (s / R) l); the release point at angle alpha up the back of the tire has the outward normal
n = -sign(s) sin(alpha) f - cos(alpha) z and moves at v_t = v_w + Omega x R n = v_w - s cos(alpha) f +
|s| sin(alpha) z. The stone leaves with the launch model's velocity v (before a fender or mud flap stops
it), slower than the tread (k = min(1, transfer mu) < 1 in the tread model): the tread slips under it, and
the friction at its inner side spins it. Rolling off without slipping, its contact point (at -r n) moves
with the tread, v + omega x (-r n) = v_t, which fixes omega up to a spin about n; the smallest solution is

    omega_roll = ((v_t - v) x n) / r.

Its axle part is -((v_t - v) . t) / r along l (t = l x n, the tread's direction of motion at the release
point): for a tread moving faster than the stone it is opposite to the wheel's own spin, a stone spins
backwards (about -l driving forwards, about +l reversing). With alpha = 0 and no lateral scatter it is
-(1 - k)(s - V) / r, e.g. 10-60 rad/s for gravel at 20 m/s with the defaults. Real stones are not spheres
and touch the grooves' walls at several points, so the spin scatters: omega = omega_roll + sigma |omega_roll| u,
u uniform in the unit ball (three counter-based uniforms of (seed, rock, step), config/streams.py
LAUNCH_SPIN) and sigma = ``[launch] spin_spread``. The reasoning is the rolling contact's kinematics; no
measurement of the spin of stones thrown by tires was found, so spin_spread is a look, not a fit.
"""

import taichi as ti

from ..config.streams import LAUNCH_SPIN
from . import tirerow
from .randomness import uniform01
from .world import RESTING, IPar, Par

__all__ = ["turn", "kick", "apply_impulse", "launch_spin", "tread_point", "rest", "through_contact", "slide_spin"]

S_AXIS_Z, S_AZIMUTH, S_RADIUS = LAUNCH_SPIN.ids  # the scatter's draws: a point uniform in the unit ball


@ti.func
def quat_mul(a, b):
    """The Hamilton product a b of quaternions (x, y, z, w): rotate by b, then by a."""
    av = ti.Vector([a[0], a[1], a[2]])
    bv = ti.Vector([b[0], b[1], b[2]])
    v = a[3] * bv + b[3] * av + av.cross(bv)
    return ti.Vector([v[0], v[1], v[2], a[3] * b[3] - av.dot(bv)])


@ti.func
def turn(q, omega, h):
    """exp(omega h / 2) q, not renormalised (exactly q for h = 0 or omega = 0)."""
    wn = omega.norm()
    half = 0.5 * wn * h
    k = 0.5 * h  # sin(|omega| h / 2) / |omega|, its limit at omega = 0
    if wn > 0.0:
        k = ti.sin(half) / wn
    p = ti.Vector([k * omega[0], k * omega[1], k * omega[2], ti.cos(half)])
    out = q
    if half != 0.0:
        out = quat_mul(p, q)
    return out


@ti.func
def unit(q):
    return q / q.norm()


@ti.func
def kick(omega, arm, dv, r):
    """omega + 5 (arm x dv) / (2 r^2): the spin after an impulse m dv at ``arm`` from the centre."""
    return omega + (2.5 / (r * r)) * arm.cross(dv)


@ti.func
def apply_impulse(w: ti.template(), plan: ti.template(), i, arm, dv):
    """Rock i (an index of the rock arrays) takes an impulse at a contact point: ``arm`` = contact point -
    centre (m), ``dv`` = the velocity change the impulse gives the centre (J / m, m/s; its normal part has no
    moment). Changes ``w.spin[i]`` by 5 (arm x dv) / (2 r^2) (module docstring); nothing without ``plan.spin``."""
    if ti.static(plan.spin):
        w.spin[i] = kick(w.spin[i], arm, dv, w.radius[i])


@ti.func
def rest(w: ti.template(), i):
    w.spin[i] = ti.Vector([0.0, 0.0, 0.0], dt=w.real)


@ti.func
def through_contact(w: ti.template(), i, dt, after, dv, r, phase):
    """A flying rock's rotation over a step of ``dt`` in which the ground's impulse (velocity change ``dv`` of
    the centre, horizontal) acted ``after`` before its end (0: no contact): turn, kick, turn the rest; a rock
    now at rest stops spinning."""
    om = w.spin[i]
    q = turn(w.orient[i], om, dt - after)
    if after > 0.0:
        om = kick(om, ti.Vector([0.0, 0.0, -r]), dv, r)
        q = turn(q, om, after)
    if phase == RESTING:
        om = ti.Vector([0.0, 0.0, 0.0], dt=w.real)  # +0 (not -0): the same bits as a rock out of a tile
    w.orient[i] = unit(q)
    w.spin[i] = om


@ti.func
def slide_spin(w: ti.template(), i, dt, dv, phase):
    """A sliding rock: the friction's impulse (``dv``, horizontal) spins it, then it turns for the step; at rest
    it stops spinning and keeps its orientation."""
    r = w.radius[i]
    om = kick(w.spin[i], ti.Vector([0.0, 0.0, -r]), dv, r)
    if phase == RESTING:
        rest(w, i)
    else:
        w.spin[i] = om
        w.orient[i] = unit(turn(w.orient[i], om, dt))


@ti.func
def tread_point(w: ti.template(), t, alpha):
    """Tire t's release point at angle alpha up the back: (its velocity v_t, its outward normal n)."""
    s = tirerow.spin(w, t)
    fw = tirerow.forward(w, t)
    f = ti.Vector([fw[0], fw[1], 0.0])
    sg = 1.0 if s >= 0.0 else -1.0
    ca, sa = ti.cos(alpha), ti.sin(alpha)
    v_t = tirerow.wheel_velocity(w, t) - s * ca * f
    v_t[2] += ti.abs(s) * sa
    n = -sg * sa * f
    n[2] = -ca
    return v_t, n


@ti.func
def launch_spin(w: ti.template(), t, alpha, v, r, rock, step):
    """The spin of a stone of radius r (id ``rock``) leaving tire t's tread at angle alpha with velocity v (the
    launch model's, before a fender or flap): omega_roll plus its scatter (module docstring)."""
    v_t, n = tread_point(w, t, alpha)
    om = (v_t - v).cross(n) / r
    seed = w.ipar[IPar.SEED]
    z = 2.0 * uniform01(seed, rock, step, S_AXIS_Z) - 1.0
    phi = 6.283185307179586 * uniform01(seed, rock, step, S_AZIMUTH)
    rho = ti.pow(uniform01(seed, rock, step, S_RADIUS), 1.0 / 3.0)  # uniform in the ball's volume
    s = ti.sqrt(ti.max(1.0 - z * z, 0.0))
    u = ti.Vector([s * ti.cos(phi), s * ti.sin(phi), z]) * rho
    return om + (w.par[Par.SPIN_SPREAD] * om.norm()) * ti.cast(u, w.real)
