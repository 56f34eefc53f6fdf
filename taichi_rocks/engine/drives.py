"""The live vehicles of a Simulation (motion/live.py): which vehicle a ``drive()`` names, the advance its pose is
bound to, and their keyframes in a checkpoint. A checkpoint holds, per live vehicle, its keyframes from the last one at or before the checkpoint's
time on (the segment under way and any pose set for later), as rows (vehicle index, t, x, y, heading, speed,
yaw_rate, wheel_spin): a restore, in this Simulation or a new one of the same scene, continues the drive with
the same bits; the pending ``drive()`` pose, not yet bound to a time, is not kept."""

import numpy as np

from ..motion.live import clock_tolerance

__all__ = ["live_index", "bind_to", "bind_steps", "saved", "load"]


def bind_to(fleet, now: float, t: float) -> None:
    """``advance_to(t)`` starts at time ``now``: the pending drive() poses are for t (nothing without a step)."""
    if fleet.live and t - now > clock_tolerance(t):
        fleet.bind(now, t)


def bind_steps(fleet, now: float, n: int, dt: float) -> None:
    """``step(n)`` starts at time ``now``: the pending drive() poses are for the clock after n steps of dt (added
    step by step, as the clock is)."""
    if fleet.live and n > 0:
        end = now
        for _ in range(n):
            end += dt
        fleet.bind(now, end)


def live_index(fleet, name) -> int:
    """The index of live vehicle ``name``; ValueError naming it if there is none or it follows a path."""
    if name not in fleet.names:
        raise ValueError(f"drive({name!r}): no vehicle of that name (the vehicles: {', '.join(fleet.names)})")
    i = fleet.names.index(name)
    if i not in fleet.live:
        kind = fleet.specs[i].path.kind
        raise ValueError(f"drive({name!r}): a scripted vehicle (path kind {kind!r}); only a vehicle with "
                         f'path = {{ kind = "live" }} is driven at run time')
    return i


def saved(fleet, t: float):
    """The live vehicles' keyframes for a checkpoint at time t, (K, 8) float64, or None without live vehicles."""
    if not fleet.live:
        return None
    parts = [np.column_stack([np.full(len(r), float(i)), r]) for i in fleet.live
             for r in (fleet.paths[i].saved(t),)]
    return np.concatenate(parts)


def load(fleet, data, t: float) -> None:
    """The live vehicles' keyframes of checkpoint ``data`` (at time t) back; a checkpoint without them (of a
    scene run before, or saved before they were kept) leaves each live vehicle's track as it is, its pending
    pose dropped."""
    rows = np.asarray(data["drives"], np.float64).reshape(-1, 8) if "drives" in data else np.zeros((0, 8))
    for i in fleet.live:
        fleet.paths[i].load(rows[rows[:, 0] == i, 1:], t)
