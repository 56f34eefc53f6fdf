"""The records a Simulation hands out (config/records.py: a dataclass per record, a unit and a line per field,
read by attribute or as the dict it replaces): :class:`State` (``state()``), :class:`Changes` (``changes()``) and
:class:`Checkpoint` (``checkpoint()``, what ``restore()`` takes back).

N rocks, V vehicles, k rows of changes. World coordinates are float64 metres, z up; rocks are in id order."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.effects import EFFECTS
from ..config.records import Record, entry

__all__ = ["State", "Changes", "Checkpoint"]


@dataclass(kw_only=True, eq=False)
class State(Record):
    """``Simulation.state()``: the clock, every rock by id, the bed and the vehicles."""

    time: float = entry("s", "the simulation's clock")
    step: int = entry("", "steps taken since the start")
    positions: np.ndarray = entry("m", "(N, 3) float64: each rock's centre, world coordinates", optional=True)
    velocities: np.ndarray = entry("m/s", "(N, 3): each rock's velocity", optional=True)
    radii: np.ndarray = entry("m", "(N,) float64: each rock's radius", optional=True)
    phase: np.ndarray = entry("-", "(N,) int8: 0 resting, 1 flying, 2 sliding", optional=True)
    angular_velocities: np.ndarray = entry("rad/s", "(N, 3): each rock's spin, with tumbling", optional=True)
    orientations: np.ndarray = entry("-", "(N, 4): unit quaternions (x, y, z, w), with tumbling", optional=True)
    bed_center: np.ndarray = entry("m", "(3,): the bed's centre, world coordinates")
    vehicle_positions: np.ndarray = entry("m", "(V, 3): each vehicle's body centre at ground level")
    vehicle_headings: np.ndarray = entry("rad", "(V,): each vehicle's heading, counter-clockwise from +x")
    vehicle_names: np.ndarray = entry("", "(V,): the vehicles' names, in the scene's order")
    launches_total: int = entry("", "rocks launched by the tires since the start")
    recycles_total: int = entry("", "rocks moved to the bed's leading edge since the start")
    others: dict = entry("", "the rock fields declared with a state key beyond these (engine/rockfields.py), "
                             "by that key: entries of the dict", optional=True)

    @classmethod
    def with_rocks(cls, arrays: dict, **given) -> "State":
        """A State of the rock arrays by state key (rocks.state_arrays) and the ``given`` fields."""
        names = {f for f in cls.__dataclass_fields__ if f != "others"}
        own = {k: v for k, v in arrays.items() if k in names}
        others = {k: v for k, v in arrays.items() if k not in names}
        return cls(**own, **given, others=others or None)

    _holder = "others"


@dataclass(kw_only=True, eq=False)
class Changes(Record):
    """``Simulation.changes()``: one row per rock whose drawn state changed since the previous call."""

    ids: np.ndarray = entry("", "(k,) int32: the rocks' ids (rows of state())")
    positions: np.ndarray = entry("m", "(k, 3) float64: each rock's centre, world coordinates")
    phase: np.ndarray = entry("-", "(k,) int8: 0 resting, 1 flying, 2 sliding")
    orientations: np.ndarray = entry("-", "(k, 4): unit quaternions (x, y, z, w), with tumbling", optional=True)
    velocities: np.ndarray = entry("m/s", "(k, 3): each rock's velocity, when asked for", optional=True)


@dataclass(kw_only=True, eq=False)
class Checkpoint(Record):
    """``Simulation.checkpoint()``: everything a simulation of the same scene needs to continue bit-identically.
    As a dict, the rock fields come first, one entry ``rock_<name>`` each (:attr:`rock_fields`)."""

    rock_fields: dict = entry("", "every saved rock field (engine/rockfields.py) by name, in id order: "
                                  "the dict's rock_<name> entries")
    step_count: np.int64 = entry("", "steps taken since the start")
    time: np.float64 = entry("s", "the simulation's clock")
    origin: np.ndarray = entry("m", "(3,): the floating origin, world coordinates (the rocks' frame)")
    origin_anchor: np.ndarray = entry("m", "(3,): the fixed point the origin's shifts are counted from")
    origin_shift: np.ndarray = entry("m", "(2,): the origin's shift from its anchor, whole tiles")
    bed_center: np.ndarray = entry("m", "(3,): the bed's centre, world coordinates")
    bed_rel: np.ndarray = entry("m", "(2,): the bed's centre relative to the anchor")
    lead: np.ndarray = entry("-", "(2,): unit vector, the bed's direction of travel")
    launches: np.int64 = entry("", "rocks launched since the start")
    recycles: np.int64 = entry("", "rocks recycled since the start")
    impacts_dropped: np.int64 = entry("", "impact events dropped before the checkpoint (Simulation.impacts_dropped)")
    scene: np.ndarray = entry("", "the scene's name")
    seed: np.int64 = entry("", "the scene's random seed")
    rocks: np.int64 = entry("", "the number of rocks N")
    effects: dict = entry("", "the state of each optional effect that runs (engine/effects/), by key: the dict's "
                              "<effect>_<name> entries (dust: its ring's fields, the emission's carried fractions, "
                              "particle count and pending time, the origin of its positions)", optional=True)

    _holder, _holders, _extra_first = "rock_fields", ("effects",), True

    def _extra(self) -> dict:
        return {**{f"rock_{name}": a for name, a in self.rock_fields.items()}, **(self.effects or {})}

    def _set_extra(self, key: str, value) -> None:
        if key.startswith("rock_"):
            self.rock_fields[key[len("rock_"):]] = value
        elif any(key.startswith(f"{name}_") for name in EFFECTS):
            self.effects = {**(self.effects or {}), key: value}
        else:
            super()._set_extra(key, value)


RECORDS = (State, Changes, Checkpoint)
