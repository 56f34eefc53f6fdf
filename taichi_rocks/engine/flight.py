"""Flight of launched rocks: gravity, air drag, ground contact, and rest.

Acceleration of a rock of radius r, density rho (mass m = 4/3 pi r^3 rho):
    a(v) = -g z  +  drag
    linear (Stokes):  F = -6 pi mu_air r v            ->  a = -(9 mu_air / (2 rho r^2)) v
    quadratic:        F = -1/2 rho_air C_d (pi r^2) |v| v  ->  a = -(3 rho_air C_d / (8 rho r)) |v| v
Integrators (the acceleration depends on v only): symplectic Euler (v += a dt; x += v dt), Heun (RK2) and
classical RK4; Heun and RK4 are exact for gravity alone.
Ground contact at z = ground_z + r, resolved at the time of impact: the time since contact tau follows from
the end-of-step state under gravity (1/2 g tau^2 + v_z tau + depth = 0), the normal velocity at impact is
reflected with restitution e, the tangential one loses a Coulomb impulse mu (1 + e) |v_n|, and the rock then
flies the remaining tau. With e = 1 this keeps the energy of the step exactly. "stop" zeroes the velocity.
Rest: a rock touching the ground slower than rest_speed vertically slides (z pinned, friction deceleration
mu g) and then rests; resting rocks are not integrated at all and cannot jitter or sink.
Spin (the Plan's ``spin``, engine/tumble.py): constant in the air; the bounce's tangential impulse (the velocity
change of the tangential part above, at the contact point -r z) and a slide's friction change it by
5 (a x dv) / (2 r^2) (a solid sphere, I = 2/5 m r^2); none at rest. It does not act back on the translation.
"""

import taichi as ti

from . import tumble
from .world import FLYING, RESTING, SLIDING, Par


@ti.func
def acceleration(w: ti.template(), v, r, gravity: ti.template(), drag: ti.template()):
    a = v * 0.0
    if ti.static(gravity):
        a[2] = -w.par[Par.GRAVITY]
    if ti.static(drag == "linear"):
        a -= (w.par[Par.LINEAR_DRAG] / (r * r)) * v
    elif ti.static(drag == "quadratic"):
        a -= (w.par[Par.QUAD_DRAG] / r) * v.norm() * v
    return a


@ti.func
def integrate(w: ti.template(), x, v, r, dt, integrator: ti.template(), gravity: ti.template(),
              drag: ti.template()):
    """One free-flight step of (x, v); returns the new pair."""
    x1, v1 = x, v
    if ti.static(integrator == "symplectic_euler"):
        v1 = v + dt * acceleration(w, v, r, gravity, drag)
        x1 = x + dt * v1
    elif ti.static(integrator == "heun"):
        a0 = acceleration(w, v, r, gravity, drag)
        vp = v + dt * a0
        a1 = acceleration(w, vp, r, gravity, drag)
        x1 = x + 0.5 * dt * (v + vp)
        v1 = v + 0.5 * dt * (a0 + a1)
    else:  # rk4
        k1v = acceleration(w, v, r, gravity, drag)
        k2x = v + 0.5 * dt * k1v
        k2v = acceleration(w, k2x, r, gravity, drag)
        k3x = v + 0.5 * dt * k2v
        k3v = acceleration(w, k3x, r, gravity, drag)
        k4x = v + dt * k3v
        k4v = acceleration(w, k4x, r, gravity, drag)
        x1 = x + dt / 6.0 * (v + 2.0 * k2x + 2.0 * k3x + k4x)
        v1 = v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    return x1, v1


@ti.func
def ground_contact(w: ti.template(), i, x, v, r, dt, ground: ti.template(), gravity: ti.template(),
                   spin: ti.template()):
    """Resolve penetration of the ground after a flight step; writes the rock's state (with ``spin``, its
    rotation over the step too: engine/tumble.py)."""
    floor_z = w.par[Par.GROUND_Z] + r
    phase = FLYING
    after = 0.0 * r  # spin: the time flown after a bounce's impulse, and the velocity change it gave
    dv = ti.Vector([0.0, 0.0, 0.0], dt=w.real)
    if ti.static(ground != "none"):
        if x[2] < floor_z:
            if ti.static(ground == "stop"):
                x[2] = floor_z
                v = ti.Vector([0.0, 0.0, 0.0], dt=w.real)  # +0: a resting rock's velocity is exactly zero
                phase = RESTING
            else:
                e = w.par[Par.RESTITUTION]
                mu = w.par[Par.GROUND_FRICTION]
                g = 0.0 * r
                if ti.static(gravity):
                    g = w.par[Par.GRAVITY]
                depth = floor_z - x[2]
                vz = ti.min(v[2], 0.0)  # vertical velocity at the end of the step, downwards
                # time since impact: 1/2 g tau^2 + vz tau + depth = 0 (smallest positive root)
                tau = depth / ti.max(-vz, 1e-12)
                disc = vz * vz - 2.0 * g * depth
                if g > 0.0 and disc >= 0.0:
                    tau = (-vz - ti.sqrt(disc)) / g
                tau = ti.min(tau, dt)
                # negative; a rock that left the ground slower than the step resolves can give vz + g tau > 0
                # (the integrator's path is not the parabola): it touched down with no normal speed
                v_impact = ti.min(vz + g * tau, 0.0)
                v_out = -e * v_impact
                vt = ti.Vector([v[0], v[1]])
                vt_norm = vt.norm()
                loss = mu * (1.0 + e) * (-v_impact)
                if vt_norm > 0.0:
                    vt *= ti.max(vt_norm - loss, 0.0) / vt_norm
                if ti.static(spin):
                    after = tau
                    dv = ti.Vector([vt[0] - v[0], vt[1] - v[1], 0.0])
                # the horizontal position keeps the integrator's value (friction acts at the contact)
                x[2] = floor_z + v_out * tau - 0.5 * g * tau * tau
                v = ti.Vector([vt[0], vt[1], v_out - g * tau])
                if v_out < w.par[Par.REST_SPEED] or x[2] < floor_z:
                    x[2] = floor_z
                    v[2] = 0.0
                    phase = SLIDING
    w.pos[i] = x
    w.vel[i] = v
    w.phase[i] = phase
    if ti.static(spin):
        tumble.through_contact(w, i, dt, after, dv, r, phase)


@ti.func
def slide(w: ti.template(), i, x, v, dt, spin: ti.template()):
    """A rock on the ground with horizontal speed: Coulomb friction decelerates it, then it rests."""
    vt = ti.Vector([v[0], v[1]])
    speed = vt.norm()
    g = w.par[Par.GRAVITY]
    new_speed = speed - w.par[Par.GROUND_FRICTION] * g * dt
    phase = SLIDING
    if new_speed <= w.par[Par.REST_SPEED] or speed <= 0.0:
        phase = RESTING
        vt = ti.Vector([0.0, 0.0], dt=w.real)  # +0 (not -0): the same bits as a rock resting in a tile
    else:
        vt *= new_speed / speed
        x[0] += vt[0] * dt
        x[1] += vt[1] * dt
    w.pos[i] = ti.Vector([x[0], x[1], w.par[Par.GROUND_Z] + w.radius[i]])
    w.vel[i] = ti.Vector([vt[0], vt[1], 0.0])
    w.phase[i] = phase
    if ti.static(spin):
        tumble.slide_spin(w, i, dt, ti.Vector([vt[0] - v[0], vt[1] - v[1], 0.0]), phase)


@ti.func
def fly(w: ti.template(), i, dt, integrator: ti.template(), gravity: ti.template(), drag: ti.template(),
        ground: ti.template(), spin: ti.template()):
    """Advance rock i by dt unless it rests (resting rocks cost one read of the phase); ``spin``: its spin and
    orientation too (engine/tumble.py)."""
    ph = w.phase[i]
    if ph == FLYING:
        r = w.radius[i]
        x, v = integrate(w, w.pos[i], w.vel[i], r, dt, integrator, gravity, drag)
        ground_contact(w, i, x, v, r, dt, ground, gravity, spin)
    elif ph == SLIDING:
        slide(w, i, w.pos[i], w.vel[i], dt, spin)
