"""The uniform launch model ([launch] model = "uniform"): rolling-wheel kinematics at a release angle drawn
uniformly in [launch] release_angle.

A tread point at angle alpha up the back of a wheel with centre velocity V (along the heading f), spin omega
and radius R moves in the ground frame at
    (V - omega R cos(alpha)) f  +  omega R sin(alpha) z,    omega R = V (1 + slip) for a driven wheel.
A rock caught by the tread leaves with
    v_xy = v_wheel_xy - omega R cos(alpha) Rot(beta) f      (v_wheel includes the yaw rate: the rear wheels
                                                            of a turning vehicle slide outwards)
    v_z  = mu_s |omega R| sin(alpha)                        (lift needs grip: static friction mu_s)
with alpha uniform in the release-angle range and beta uniform in [-spread, spread]. Relative to the wheel
the rock always leaves backwards (against the wheel's travel, also when reversing).
"""

import taichi as ti

from ...config.streams import LAUNCH
from .. import tirerow
from ..randomness import uniform01
from ..world import IPar, Par

NAME = "uniform"
PARAMS = ("ANGLE_MIN", "ANGLE_MAX", "SPREAD")
S_ANGLE, S_SPREAD = LAUNCH.id(0), LAUNCH.id(1)  # the release angle, the lateral scatter
STREAMS = (S_ANGLE, S_SPREAD)


@ti.func
def release_angle(w: ti.template(), seed, rock, step):
    """alpha, uniform in the release-angle range."""
    u_alpha = uniform01(seed, rock, step, S_ANGLE)
    return w.par[Par.ANGLE_MIN] + (w.par[Par.ANGLE_MAX] - w.par[Par.ANGLE_MIN]) * u_alpha


@ti.func
def wheel_throw(w: ti.template(), wheel_vel, forward, spin, mu, seed, rock, step):
    """Velocity of a rock thrown by a tread (see the module docstring). spin = omega * R, signed."""
    return throw_at(w, wheel_vel, forward, spin, mu, release_angle(w, seed, rock, step), seed, rock, step)


@ti.func
def throw_at(w: ti.template(), wheel_vel, forward, spin, mu, alpha, seed, rock, step):
    """:func:`wheel_throw` at the release angle alpha."""
    u_beta = uniform01(seed, rock, step, S_SPREAD)
    beta = w.par[Par.SPREAD] * (2.0 * u_beta - 1.0)
    cb, sb = ti.cos(beta), ti.sin(beta)
    back = -spin * ti.cos(alpha)
    fx = cb * forward[0] - sb * forward[1]
    fy = sb * forward[0] + cb * forward[1]
    return ti.Vector([wheel_vel[0] + back * fx, wheel_vel[1] + back * fy, mu * ti.abs(spin) * ti.sin(alpha)])


@ti.func
def launch(w: ti.template(), plan: ti.template(), t, i, step):
    """The launch models' interface (engine/launch/__init__.py): rock i thrown by tire t at ``step``: (its
    velocity, the same (nothing stops it), the release angle)."""
    forward = tirerow.forward(w, t)
    wheel_vel = tirerow.wheel_velocity(w, t)
    seed = w.ipar[IPar.SEED]
    alpha = release_angle(w, seed, w.rock_id[i], step)
    v = throw_at(w, wheel_vel, forward, tirerow.spin(w, t), w.friction[i], alpha, seed, w.rock_id[i], step)
    return v, v, alpha


@ti.func
def launch_velocity(w: ti.template(), plan: ti.template(), t, i, step):
    """The launch velocity alone (:func:`launch`)."""
    v, _, _ = launch(w, plan, t, i, step)
    return v
