"""The tread launch model ([launch] model = "tread", the default): which stones a tread carries, where they
leave it, how fast, and what the fender and the mud flap stop.

Sources. Chen, Fu & Wegman 1999, "A cellular automata model of vehicle-generated dust", ACM TOMACS 9(2):81-104:
the stones stick to the tread by its adhesive forces and friction and leave it at a height that depends on the
tire's speed and angular speed, the ground's wetness and the stone's weight. Plocher, Browand & Radovich 2014,
Tire Sci. Tech. 42(3): what a tread throws leaves near the contact patch. The constants below are proxies,
tuned to the field reports quoted in docs/physics.md, "The throw" (Berner et al. 2003; Albert, Nover & Nover 2006;
Strobl 1996), not measured on a tire.

Symbols: tire radius R, tread speed omega R = spin (signed; |spin| = V (1 + slip)), stone radius r, density
rho, static friction mu, wetness w in [0, 1], gravity g; alpha is measured up the back of the tire from its
bottom. u1..u4 are counter-based uniforms (engine/randomness.py) of (seed, rock, step, stream).

1. Capture. The grooves hold stones about their own size; a much larger stone is pinched in the contact patch:
       carried iff u1 < p_carry = min(1, mu) / (1 + (r / groove)^4).
2. A pinched stone leaves within the patch's exit: alpha = alpha_patch u2, alpha_patch = asin(min(1, L / 2R))
   (L the contact length).
3. A carried stone stays while the groove's clamp and the wet film's adhesion, per unit contact area pi r^2,
   hold it against the centrifugal pull and the outward part of gravity (mass per area 4/3 rho r):
       H(alpha) = mu grip xi exp(-(alpha - alpha_patch) / relax) + w adhesion,   xi = exp(spread (2 u3 - 1))
       P(alpha) = 4/3 rho r (omega^2 R + g cos alpha)
   and leaves at the first alpha >= alpha_patch with H <= P: alpha_patch if H <= P there already, pi (carried
   over the top) if never. Found by a march of 32 steps over [alpha_patch, pi] to the first sign change, then
   24 bisections (a launch is rare: the cost is per launch, not per rock). Heavier (larger) stones and faster
   wheels release earlier; wetter ground and higher friction later.
4. Velocity: the tread point's velocity at alpha plus the wheel's rigid-body velocity, times the transfer
   factor k = min(1, transfer mu) on every component:
       v = k (v_wheel_xy - spin cos(alpha) Rot(beta) f,  |spin| sin alpha),   beta = spread (2 u4 - 1)
   For alpha < 90 deg the stone leaves backwards relative to the wheel (the signed spin: also reversing); with
   beta = 0 and k = 1, |v| is the tread point's speed, 2 V sin(alpha / 2) when rolling without slip.
5. Fender and mud flap ([effects] fenders): a stone released above the fender angle hits the fender; with mud
   flaps (driving forwards: the flap is behind the wheel), a stone whose straight path in the vehicle's frame
   from the tread point (R sin alpha behind the axle, R (1 - cos alpha) up) crosses the flap plane 1.1 R behind
   the axle above the flap's lower edge hits the flap. Either way it drops: v = e (v_xy, -|v_z|), e the
   ground restitution.
"""

import math

import numpy as np
import taichi as ti

from ...config.streams import LAUNCH
from ..randomness import uniform01
from ..world import FENDER, FLAP, FWD, HALF_L, SPIN, TIRE_R, VEL, IPar, Par

NAME = "tread"
PARAMS = ("WETNESS", "GRAVITY", "SPREAD", "GROOVE", "GRIP", "GRIP_RELAX", "GRIP_SPREAD", "ADHESION", "TRANSFER",
          "RESTITUTION", "DENSITY")
# the draws of steps 1 (carried?), 2 (where a pinched stone leaves), 3 (xi) and 4 (beta)
S_CAPTURE, S_PINCH, S_GRIP, S_SPREAD = (LAUNCH.id(k) for k in range(10, 14))
STREAMS = (S_CAPTURE, S_PINCH, S_GRIP, S_SPREAD)
MARCH, BISECT = 32, 24
FLAP_DISTANCE = 1.1  # tire radii behind the axle
PI_HI = float(np.float32(math.pi))
PI_LO = math.pi - PI_HI


@ti.func
def patch_angle(half_length, radius):
    """alpha_patch = asin(min(1, L / 2R)), the angle of the contact patch's exit."""
    return ti.asin(ti.min(1.0, half_length / radius))


@ti.func
def carry_probability(w: ti.template(), r, mu):
    q = r / w.par[Par.GROOVE]
    return ti.min(1.0, mu) / (1.0 + q * q * q * q)


@ti.func
def hold_minus_pull(w: ti.template(), alpha, alpha_p, r, mu, xi, centripetal):
    """H(alpha) - P(alpha) of the force balance (per unit contact area, Pa); centripetal = omega^2 R."""
    hold = mu * w.par[Par.GRIP] * xi * ti.exp(-(alpha - alpha_p) / w.par[Par.GRIP_RELAX]) \
        + w.par[Par.WETNESS] * w.par[Par.ADHESION]
    pull = 4.0 * w.par[Par.DENSITY] * r * (centripetal + w.par[Par.GRAVITY] * ti.cos(alpha)) / 3.0
    return hold - pull


@ti.func
def release_angle(w: ti.template(), alpha_p, r, mu, xi, centripetal):
    """The first alpha in [alpha_p, pi] where the hold no longer beats the pull (pi: never)."""
    top = ti.cast(PI_HI, w.real) + ti.cast(PI_LO, w.real)  # pi in the World's precision (literals are f32)
    alpha = alpha_p
    if hold_minus_pull(w, alpha_p, alpha_p, r, mu, xi, centripetal) > 0.0:
        alpha = top
        h = (top - alpha_p) / MARCH
        lo = alpha_p
        hi = alpha_p
        found = False
        for k in range(1, MARCH + 1):
            if not found:
                a = alpha_p + h * k
                if k == MARCH:
                    a = top
                if hold_minus_pull(w, a, alpha_p, r, mu, xi, centripetal) <= 0.0:
                    found = True
                    hi = a
                else:
                    lo = a
        if found:
            for _ in range(BISECT):
                mid = 0.5 * (lo + hi)
                if hold_minus_pull(w, mid, alpha_p, r, mu, xi, centripetal) <= 0.0:
                    hi = mid
                else:
                    lo = mid
            alpha = hi
    return alpha


@ti.func
def tread_velocity(wheel_vel, forward, spin, alpha, beta, k):
    """k (v_wheel_xy - spin cos(alpha) Rot(beta) f, |spin| sin(alpha))."""
    cb, sb = ti.cos(beta), ti.sin(beta)
    back = -spin * ti.cos(alpha)
    fx = cb * forward[0] - sb * forward[1]
    fy = sb * forward[0] + cb * forward[1]
    return k * ti.Vector([wheel_vel[0] + back * fx, wheel_vel[1] + back * fy, ti.abs(spin) * ti.sin(alpha)])


@ti.func
def hits_flap(v, wheel_vel, forward, alpha, radius, clearance):
    """Does the straight path from the tread point at alpha, in the vehicle's frame, cross the flap plane
    (FLAP_DISTANCE R behind the axle) above the flap's lower edge?"""
    rel = v - ti.Vector([wheel_vel[0], wheel_vel[1], 0.0])
    u = -(rel[0] * forward[0] + rel[1] * forward[1])  # backwards speed
    x0 = radius * ti.sin(alpha)
    z0 = radius * (1.0 - ti.cos(alpha))
    gap = FLAP_DISTANCE * radius - x0
    hit = False
    if u > 0.0 and gap >= 0.0:
        hit = z0 + rel[2] * gap / u > clearance
    return hit


@ti.func
def guarded(w: ti.template(), v, wheel_vel, forward, spin, alpha, radius, fender, clearance):
    """v, or e (v_xy, -|v_z|) if the stone hits the fender or the mud flap (no flap: clearance < 0)."""
    stop = alpha > fender
    if not stop and clearance >= 0.0 and spin > 0.0:
        stop = hits_flap(v, wheel_vel, forward, alpha, radius, clearance)
    out = v
    if stop:
        out = w.par[Par.RESTITUTION] * ti.Vector([v[0], v[1], -ti.abs(v[2])])
    return out


@ti.func
def throw_angle(w: ti.template(), r, mu, spin, radius, half_length, seed, rock, step):
    """The release angle of a stone run over by the tread (steps 1-3 of the module docstring)."""
    alpha_p = patch_angle(half_length, radius)
    alpha = alpha_p * uniform01(seed, rock, step, S_PINCH)
    if uniform01(seed, rock, step, S_CAPTURE) < carry_probability(w, r, mu):
        xi = ti.exp(w.par[Par.GRIP_SPREAD] * (2.0 * uniform01(seed, rock, step, S_GRIP) - 1.0))
        alpha = release_angle(w, alpha_p, r, mu, xi, spin * spin / radius)
    return alpha


@ti.func
def throw_velocity(w: ti.template(), t, r, mu, rock, step, fenders: ti.template()):
    """Launch velocity of a stone (radius r, friction mu, id rock) run over by tire t (its ray row)."""
    v, _, _ = throw(w, t, r, mu, rock, step, fenders)
    return v


@ti.func
def throw(w: ti.template(), t, r, mu, rock, step, fenders: ti.template()):
    """:func:`throw_velocity`, the velocity the tread gave before a fender or flap stopped it, and the release
    angle."""
    seed = w.ipar[IPar.SEED]
    radius = w.ray[t, TIRE_R]
    spin = w.ray[t, SPIN]
    wheel_vel = ti.Vector([w.ray[t, VEL], w.ray[t, VEL + 1], w.ray[t, VEL + 2]])
    forward = ti.Vector([w.ray[t, FWD], w.ray[t, FWD + 1]])
    alpha = throw_angle(w, r, mu, spin, radius, w.ray[t, HALF_L], seed, rock, step)
    beta = w.par[Par.SPREAD] * (2.0 * uniform01(seed, rock, step, S_SPREAD) - 1.0)
    k = ti.min(1.0, w.par[Par.TRANSFER] * mu)
    free = tread_velocity(wheel_vel, forward, spin, alpha, beta, k)
    v = free
    if ti.static(fenders):
        v = guarded(w, free, wheel_vel, forward, spin, alpha, radius, w.ray[t, FENDER], w.ray[t, FLAP])
    return v, free, alpha


@ti.func
def launch(w: ti.template(), plan: ti.template(), t, i, step):
    """The launch models' interface (engine/launch/__init__.py): rock i thrown by tire t at ``step``."""
    return throw(w, t, w.radius[i], w.friction[i], w.rock_id[i], step, plan.fenders)


@ti.func
def launch_velocity(w: ti.template(), plan: ti.template(), t, i, step):
    """The launch velocity alone (:func:`launch`)."""
    v, _, _ = launch(w, plan, t, i, step)
    return v
