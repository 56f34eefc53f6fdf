"""The optional effects: one module per effect, each declaring everything about it (no Taichi here). The scene
model (config/models.py) takes each effect's switch (``[effects] <NAME>``, default off) and its table
(``[<NAME>]``) from :data:`EFFECTS`; the Plan (config/plan.py ``Plan.effects``) the names of those that run.

Each module declares:

    NAME      its name: the switch ``[effects] <NAME>`` and its table ``[<NAME>]``
    SWITCH    the switch's description (docs/scene-format.md)
    Table     its table: a frozen pydantic model (config/values.py ``_Table``), defaults and ranges
    STREAM    its random streams (config/streams.py: one line there, on ids no other stream takes)
    FIELDS    its Taichi fields: (name, dtype, components) each, over ``capacity(table)`` slots; allocated
              only when it runs, counted by the memory estimate (engine/layout.py)
    PARAMS    the table keys its kernels read (packed into its own small parameter field)
    HOOK      where in a step it runs ("after_step": after the stepper's kernels, from the poses at t + dt)
    DRAWS     what the renderer draws of it (its module in render/)
    EXPORTS   the keys it adds to an exported frame (its writer function in output/)
    capacity(table)    the slots of its fields
    runs(scene)        whether it runs in this scene (its switch and what it needs)
    idle(scene)        why it does not run although the scene asks for it (words for ``check``), else None

Its kernels are the engine's (engine/effects/: one module of the same NAME). A new effect is a module here,
its line in :data:`EFFECTS`, a module in engine/effects/ and its line there, and its stream in
config/streams.py (docs/architecture.md, "Where to make a change").
"""

from __future__ import annotations

from . import dust

__all__ = ["EFFECTS", "effects_on"]

EFFECTS = {m.NAME: m for m in (dust,)}


def effects_on(scene) -> tuple:
    """The names of the effects that run in ``scene``, in registry order."""
    return tuple(name for name, m in EFFECTS.items() if m.runs(scene))
