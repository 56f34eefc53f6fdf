"""What the scene's types say about a dotted scene key ("sim.integrator", "world.wetness", "vehicle.kind"):
its choices, its range and its value in a scene.

The scene models (config/scene.py) are the one source of every choice list and every range. A choice field's
choices are ``typing.get_args`` of its ``Literal`` annotation, in the order the model lists them (a bool:
false, true); a number's range is its pydantic constraints (ge, gt, le, lt; a [min, max] pair: its items').
Other rooms take the lists from here instead of writing them again, so a new choice is one word in the model.
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass

from pydantic import BaseModel

from .scene import Scene

__all__ = ["Bounds", "bounds", "choices", "scene_value"]


def _named(model: type[BaseModel], name: str):
    """The field of ``model`` called ``name`` in scene files (its alias) or in Python."""
    for attr, f in model.model_fields.items():
        if name in (attr, f.alias):
            return f
    raise KeyError(f"no key {name!r} in the scene's [{model.__name__.lower()}] table")


def _table(annotation) -> type[BaseModel]:
    """The model of a table, or of the tables of a list of them ([[vehicle]])."""
    for a in (annotation, *typing.get_args(annotation)):
        if isinstance(a, type) and issubclass(a, BaseModel):
            return a
    raise KeyError(f"{annotation!r} is not a table")


def _field(key: str):
    model = Scene
    *tables, leaf = key.split(".")
    for part in tables:
        model = _table(_named(model, part).annotation)
    return _named(model, leaf)


def choices(key: str) -> tuple:
    """The values a choice key may take, in the scene model's order: a ``Literal`` field's, or (False, True)."""
    ann = _field(key).annotation
    if ann is bool:
        return (False, True)
    if typing.get_origin(ann) is typing.Literal:
        return typing.get_args(ann)
    raise KeyError(f"{key} is not a choice (its type is {ann!r})")


@dataclass(frozen=True)
class Bounds:
    """A key's range: [lo, hi], each end open or closed; unbounded ends are infinite."""

    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False

    def __contains__(self, x: float) -> bool:
        above = x > self.lo if self.lo_open else x >= self.lo
        below = x < self.hi if self.hi_open else x <= self.hi
        return above and below


def _constraints(field) -> list:
    """The numeric constraints of a field, or of the items of a [min, max] pair."""
    found = [m for m in field.metadata if any(hasattr(m, k) for k in ("ge", "gt", "le", "lt"))]
    if found:
        return found
    for item in typing.get_args(field.annotation)[:1]:  # a pair: both items have the same constraints
        for part in typing.get_args(item)[1:]:
            found += [m for m in getattr(part, "metadata", ()) if any(hasattr(m, k) for k in ("ge", "gt", "le", "lt"))]
    return found


def bounds(key: str) -> Bounds:
    """The range the scene schema allows for a number key (a pair: for each of its two values)."""
    lo, hi, lo_open, hi_open = -math.inf, math.inf, False, False
    for m in _constraints(_field(key)):
        if getattr(m, "ge", None) is not None:
            lo, lo_open = float(m.ge), False
        if getattr(m, "gt", None) is not None:
            lo, lo_open = float(m.gt), True
        if getattr(m, "le", None) is not None:
            hi, hi_open = float(m.le), False
        if getattr(m, "lt", None) is not None:
            hi, hi_open = float(m.lt), True
    return Bounds(lo, hi, lo_open, hi_open)


def scene_value(scene, key: str):
    """The value of a dotted key of the tables (e.g. "world.wetness") in ``scene``; pairs as lists."""
    node = scene
    for part in key.split("."):
        node = getattr(node, part)
    return list(node) if isinstance(node, tuple) else node
