"""A scratch launch model ([launch] model = "straight"): the rock leaves straight backwards at the tread
speed, lifted by an angle uniform in [0, spread]: v = v_wheel_xy - |spin| cos(a) f + |spin| sin(a) z."""

import taichi as ti

from ...config.streams import LAUNCH
from ..randomness import uniform01
from ..world import FWD, SPIN, VEL, IPar, Par

NAME = "straight"
PARAMS = ("SPREAD",)
S_LIFT = LAUNCH.id(20)  # the lift angle
STREAMS = (S_LIFT,)


@ti.func
def launch_velocity(w: ti.template(), plan: ti.template(), t, i, step):
    """The launch models' interface (engine/launch/__init__.py): rock i thrown by tire t at ``step``."""
    a = w.par[Par.SPREAD] * uniform01(w.ipar[IPar.SEED], w.rock_id[i], step, S_LIFT)
    s = ti.abs(w.ray[t, SPIN])
    back = s * ti.cos(a)
    return ti.Vector([w.ray[t, VEL] - back * w.ray[t, FWD], w.ray[t, VEL + 1] - back * w.ray[t, FWD + 1], s * ti.sin(a)])
