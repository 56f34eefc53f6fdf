"""The checks of what a caller hands a Simulation (engine/simulation.py): a step count, a time, rock values
(``set_rocks``) and a checkpoint (``restore``). Each check raises a ValueError or TypeError whose one line names
the parameter (or the checkpoint's key) and what was expected, before anything of the simulation changes; it
returns the value in the form the simulation uses.

The limits: the kernels count steps in an i32 (the random streams and a rock's ``hit_step`` take the step's
number), so a simulation stops short of ``STEP_LIMIT`` steps; a rock's values are those a rock can have (finite
numbers, a radius > 0, a friction >= 0, a phase code of engine/rockfields.py, a unit quaternion); a checkpoint's
rock arrays hold one row per rock of this simulation and its ids are 0 .. N-1, each once.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .rockfields import FLYING, ID, RESTING, SLIDING

__all__ = ["STEP_LIMIT", "whole_steps", "target_time", "rock_values", "checked_rock_fields", "checkpoint_data",
           "host_problem"]

STEP_LIMIT = 2 ** 31 - 1  # steps a simulation may take: the kernels count them in an i32
PHASES = (RESTING, FLYING, SLIDING)
UNIT = 1e-3  # how far from 1 a quaternion's length may be


def whole_steps(n, taken: int) -> int:
    """``n`` for ``Simulation.step(n)``: a whole number >= 0 that keeps the step count under STEP_LIMIT."""
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, numbers.Integral):
        raise TypeError(f"n must be a whole number of steps, got {n!r}")
    n = int(n)
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    if n > STEP_LIMIT - taken:
        raise ValueError(f"n = {n} would take the simulation past {STEP_LIMIT} steps, the most its kernels count "
                         f"({taken} taken)")
    return n


def target_time(t, now: float, dt: float, taken: int) -> float:
    """``t`` for ``Simulation.advance_to(t)``: a finite number of seconds that keeps the step count under
    STEP_LIMIT (a time at or before ``now`` is fine: it takes no step)."""
    if isinstance(t, (bool, np.bool_)) or not isinstance(t, numbers.Real):
        raise TypeError(f"t must be a time in seconds (a number), got {t!r}")
    t = float(t)
    if not math.isfinite(t):
        raise ValueError(f"t must be a finite time in seconds, got {t}")
    if (t - now) / dt > STEP_LIMIT - taken - 1:
        raise ValueError(f"t = {t:g} s is past the last step the kernels count ({STEP_LIMIT} steps of "
                         f"{dt:g} s from the start)")
    return t


def _array(name: str, value) -> np.ndarray:
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as e:
        raise TypeError(f"{name} must be an array of numbers, got {value!r}") from e
    if a.dtype.kind not in "biuf":
        raise TypeError(f"{name} must hold numbers, got {a.dtype} values")
    return a


def _first(a: np.ndarray, bad: np.ndarray):
    """The first of the values ``a[bad]``, as Python shows it."""
    return a[bad].flat[0].item()


def _value_problem(name: str, field: str, a: np.ndarray, vehicles: int):
    """What is wrong with the values ``a`` of rock field ``field`` (the parameter ``name``), or None."""
    if field == "phase" and not np.isin(a, PHASES).all():
        return f"{name} must hold phase codes 0 (resting), 1 (flying) or 2 (sliding), got " \
               f"{_first(a, ~np.isin(a, PHASES))}"
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        return f"{name} must be finite, got {_first(a, ~np.isfinite(a))}"
    if field == "radius" and (a <= 0).any():
        return f"{name} must be > 0 m, got {_first(a, a <= 0)}"
    if field == "friction" and (a < 0).any():
        return f"{name} must be >= 0, got {_first(a, a < 0)}"
    if field == "hit_step" and (a < -1).any():
        return f"{name} must be a step number, or -1 (never launched), got {_first(a, a < -1)}"
    if field == "thrower" and ((a < -1) | (a >= vehicles)).any():
        return f"{name} must be a vehicle's index (0 .. {vehicles - 1}) or -1 (none)"
    if field == "orient" and a.size and (np.abs(np.linalg.norm(a.reshape(-1, 4), axis=1) - 1.0) > UNIT).any():
        return f"{name} must hold unit quaternions (x, y, z, w)"
    return None


def _whole(name: str, a: np.ndarray, kind: str) -> np.ndarray:
    """``a`` for an integer field: whole numbers only."""
    if kind == "i" and a.dtype.kind == "f":
        if not (np.isfinite(a).all() and (a == np.round(a)).all()):
            raise ValueError(f"{name} must hold whole numbers")
    return a


def rock_values(arrays: dict, n: int, ids, given: dict, origin, vehicles: int) -> tuple:
    """The rock ids and the values of ``Simulation.set_rocks``: ``arrays`` the rocks' fields now (by name,
    ``rock_arrays()``), ``given`` what to set (parameter name -> (field name, value); "positions" in world
    coordinates). Returns (ids as int64, {field: values shaped (len(ids), ...) in the field's dtype})."""
    ids_a = _array("ids", ids)
    if ids_a.dtype.kind not in "iu":
        raise TypeError(f"ids must be whole rock ids, got {ids_a.dtype} values")
    ids_a = np.atleast_1d(ids_a).astype(np.int64)
    if ids_a.ndim != 1:
        raise ValueError(f"ids must be a rock id or a list of them, got shape {ids_a.shape}")
    bad = (ids_a < 0) | (ids_a >= n)
    if bad.any():
        raise ValueError(f"ids must be rock ids 0 .. {n - 1}, got {int(ids_a[bad][0])}")
    if len(np.unique(ids_a)) != len(ids_a):
        raise ValueError("ids must name each rock once")
    out = {}
    for name, (field, value) in given.items():
        if field == ID or field not in arrays:
            known = ", ".join(k for k in arrays if k != ID)
            raise TypeError(f"set_rocks() has no rock field {field!r} (its fields: {known})")
        have = arrays[field]
        a = _array(name, value)
        shape = (len(ids_a),) + have.shape[1:]
        if a.size == math.prod(shape):
            a = a.reshape(shape)
        else:
            try:
                a = np.broadcast_to(a, shape)
            except ValueError:
                raise ValueError(f"{name} must have shape {shape} (or one value for all), got {a.shape}") from None
        if field == "pos" and name == "positions":
            a = a.astype(np.float64) - origin
        a = _whole(name, a, have.dtype.kind)
        problem = _value_problem(name, field, a, vehicles)
        if problem:
            raise ValueError(problem)
        out[field] = a.astype(have.dtype)
    return ids_a, out


def checked_rock_fields(fields, data: dict, n: int, vehicles: int) -> None:
    """Raise ValueError naming the key when the rock part of checkpoint ``data`` does not fit this simulation:
    ``fields`` the saved rock fields (engine/rockfields.py) that ``data`` must hold (or whose rest value stands
    in), each ``rock_<name>`` with one row per rock, values a rock can have; the ids 0 .. n-1, each once."""
    for f in fields:
        key = f"rock_{f.name}"
        if key not in data:
            if f.rest is None:
                raise ValueError(f"checkpoint: no {key}")
            continue
        a = _array(f"checkpoint: {key}", data[key])
        shape = (n,) + ((f.n,) if f.n > 1 else ())
        if a.shape != shape:
            raise ValueError(f"checkpoint: {key} must have shape {shape} (one row per rock), got {a.shape}")
        a = _whole(f"checkpoint: {key}", a, "i" if f.dtype == "i32" else "f")
        problem = _value_problem(f"checkpoint: {key}", f.name, a, vehicles)
        if problem:
            raise ValueError(problem)
    ids = np.asarray(data[f"rock_{ID}"])
    if n and not np.array_equal(np.sort(ids), np.arange(n)):
        raise ValueError(f"checkpoint: rock_{ID} must hold the ids 0 .. {n - 1}, each once")


def checkpoint_data(data, n: int, seed: int, orientations=None) -> dict:
    """Checkpoint ``data`` as a dict, if it is one of a simulation of ``n`` rocks and ``seed`` (else ValueError);
    ``orientations`` (a function, with tumbling): the rocks' orientations at the start, for a checkpoint of a run
    without tumbling (which has none: its rocks have not turned), and no spin."""
    try:
        data = dict(data)
        theirs = int(data["rocks"]), int(data["seed"])
    except (TypeError, ValueError, KeyError) as e:
        raise ValueError(f"checkpoint: not a checkpoint of a Simulation (its rocks and seed: {e})") from None
    if theirs != (n, seed):
        raise ValueError("checkpoint does not belong to this scene (rock count or seed differ)")
    if orientations is not None and "rock_orient" not in data:
        data.update(rock_orient=orientations(), rock_spin=np.zeros((n, 3)))
    return data


# the host part of a checkpoint (engine/host.py HostState.saved): key -> shape; a checkpoint saved before the
# origin had an anchor lacks the last three
HOST_KEYS = {"step_count": (), "time": (), "origin": (3,), "bed_center": (3,), "lead": (2,), "launches": (),
             "origin_anchor": (3,), "origin_shift": (2,), "bed_rel": (2,)}
OPTIONAL = ("origin_anchor", "origin_shift", "bed_rel", "recycles", "impacts_dropped")


def host_problem(data: dict):
    """What is wrong with the clock, frame and counters of checkpoint ``data``, or None."""
    for key, shape in HOST_KEYS.items():
        if key not in data:
            if key in OPTIONAL:
                continue
            return f"checkpoint: no {key}"
        try:
            a = np.asarray(data[key], np.float64)
        except (TypeError, ValueError):
            return f"checkpoint: {key} must be a number{'' if not shape else 's'}, got {data[key]!r}"
        if a.shape != shape:
            return f"checkpoint: {key} must have shape {shape}, got {a.shape}"
        if not np.isfinite(a).all():
            return f"checkpoint: {key} must be finite"
    for key in ("step_count", "launches", "recycles", "impacts_dropped"):
        if key in data:
            v = np.asarray(data[key])
            if v.shape != () or v.dtype.kind not in "iu" or int(v) < 0:
                return f"checkpoint: {key} must be a whole number >= 0, got {data[key]!r}"
    if int(data["step_count"]) > STEP_LIMIT:
        return f"checkpoint: step_count must be at most {STEP_LIMIT}"
    if float(data["time"]) < 0:
        return "checkpoint: time must be >= 0"
    if abs(float(np.linalg.norm(np.asarray(data["lead"], np.float64))) - 1.0) > UNIT:
        return "checkpoint: lead must be a unit vector"
    return None
