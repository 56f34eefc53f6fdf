"""The launch models ([launch] model): how a tread throws a rock it runs over. One module per model, each
with the same interface:

    NAME             its name in scene files (one of the choices of ``launch.model``: the
                     ``Launch`` model's ``Literal`` in config/models.py)
    PARAMS           the rows of engine/params.py it reads (``w.par[Par.X]``)
    STREAMS          the random-stream ids it draws, from the launch models' block (config/streams.py LAUNCH)
    launch(w, plan, t, i, step)
                     a ``ti.func``: (v, v_tread, alpha) of rock i (an index of the rock arrays) run over by
                     tire t (its row of ``World.ray``) at step ``step``: its launch velocity, the velocity the
                     tread gave it before a fender or mud flap stopped it (v when nothing did) and the release
                     angle up the back of the tire (rad; the spin of a stone rolling off the tread follows
                     from them, engine/tumble.py); ``plan``: the tire pass's switches (engine/kernels.py
                     Switches: ``plan.fenders``, ...)
    launch_velocity(w, plan, t, i, step)
                     the same call's v alone
    its docstring    the physics: what it computes, the equations, the sources

The tire pass (engine/tires.py ``try_launch``) picks the model at compile time: ``MODELS[plan.throw].launch``. A new
model is a module here, its line in :data:`MODELS` and its name among the choices of ``Launch.model``
(config/models.py).
"""

from . import tread, uniform

__all__ = ["MODELS"]

MODELS = {m.NAME: m for m in (tread, uniform)}
