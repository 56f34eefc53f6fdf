"""The optional effects' kernels and host sides (config/effects/ declares each effect): one module per effect,
each with

    NAME                      the declaration's name
    specs(table)              its fields (engine/world.py FieldSpec), from the declaration's FIELDS
    <Class>(scene, real)      named in :data:`RUNTIMES`: its pool (leased; allocated only when the effect runs)
                              and its hooks: ``after_step(poses, origin, step, dt)`` (HOOK "after_step"),
                              ``coast(...)`` (steps taken as one), ``reset(origin)`` (start),
                              ``arrays(origin)`` (what is drawn and exported); its checkpoint part:
                              ``saved()`` (keys "<name>_..."), ``problem(data)`` (one line or None),
                              ``load(data, origin)`` (restore; without its keys it starts again)

:class:`Effects` is what a Simulation holds: the runtimes of ``plan.effects``, nothing when none runs.
"""

from __future__ import annotations

from . import dust

__all__ = ["RUNTIMES", "Effects", "effect_specs"]

RUNTIMES = {dust.NAME: (dust, dust.Dust)}


def effect_specs(scene, plan) -> list:
    """The fields of every effect the plan runs (the memory estimate's share, engine/layout.py)."""
    return [s for name in plan.effects for s in RUNTIMES[name][0].specs(getattr(scene, name))]


class Effects:
    """The runtimes of the effects that run (``plan.effects``), each called at its hook."""

    def __init__(self, scene, plan, real):
        self.on = {name: RUNTIMES[name][1](scene, real) for name in plan.effects}

    def __bool__(self) -> bool:
        return bool(self.on)

    def after_step(self, host, dt: float) -> None:
        for e in self.on.values():
            e.after_step(host.poses, host.origin, host.step_count, dt)

    def coast(self, host, dt: float) -> None:
        for e in self.on.values():
            e.coast(host.poses, host.origin, host.step_count, dt)

    def reset(self, host) -> None:
        for e in self.on.values():
            e.reset(host.origin)

    def saved(self) -> dict:
        """What a checkpoint holds of the effects that run, by key (each key starts with its effect's name)."""
        return {k: v for e in self.on.values() for k, v in e.saved().items()}

    def problem(self, data: dict):
        """The first thing wrong with the effects' part of checkpoint ``data``, or None."""
        return next((p for p in (e.problem(data) for e in self.on.values()) if p), None)

    def load(self, data: dict, host) -> None:
        for e in self.on.values():
            e.load(data, host.origin)

    def arrays(self, origin) -> dict:
        return {name: e.arrays(origin) for name, e in self.on.items()}
