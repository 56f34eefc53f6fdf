"""The frames of a command: how many and how fast (``--frames``, ``--fps``, else the scene's duration and
[render] fps), refused up front when they would take more steps than any run may (config/limits.py), and the
loop that advances a simulation to each frame time."""

from __future__ import annotations

import numpy as np

from ..config.limits import MAX_STEPS, steps_estimate

__all__ = ["frame_count", "frame_states", "frame_mirrors", "check_steps"]


def frame_count(scene, frames=None, fps=None) -> tuple[int, float]:
    """(frames, fps): ``fps`` or the scene's [render] fps; ``frames`` or round(duration x fps), at least 1.
    ValueError (:func:`check_steps`) for a run of more than MAX_STEPS steps."""
    given_frames, given_fps = frames, fps
    fps = fps or float(scene.render.fps)
    frames = frames or max(1, int(round(scene.duration * fps)))
    check_steps(scene, frames, fps, given_frames, given_fps)
    return frames, fps


def check_steps(scene, frames: int, fps: float, given_frames=None, given_fps=None) -> None:
    """Refuse (ValueError, one line naming the flag) ``frames`` frames at ``fps`` whose last frame time,
    (frames - 1) / fps, is more than MAX_STEPS steps of the scene's dt."""
    seconds = (frames - 1) / fps
    if seconds / scene.sim.dt > MAX_STEPS:
        flag = (f"--fps {given_fps:g}" if given_fps is not None else f"--frames {given_frames}"
                if given_frames is not None else f"render.fps = {fps:g}")
        raise ValueError(f"{flag}: {frames} frames at {fps:g} frames/s are {seconds:.3g} s of simulated time, "
                         f"{steps_estimate(seconds, scene.sim.dt)}")


def frame_states(sim, frames: int, fps: float, guard: bool = True, progress=None):
    """Yield (f, state) for frames f = 0 .. frames - 1: ``sim`` advanced to exactly f / fps, checked by the runtime
    guard with ``guard`` (a HealthError propagates), its ``state()``; ``progress`` ticks once a frame is done."""
    for f in range(frames):
        sim.advance_to(f / fps)
        if guard:
            sim.check_health()
        yield f, sim.state()
        if progress is not None:
            progress.update(1)


def frame_mirrors(sim, frames: int, fps: float, guard: bool = True, progress=None):
    """As :func:`frame_states`, but the rocks come from ``Simulation.changes()``: frame 0 reads every rock once,
    later frames only the rows that changed, applied to copies of the rock arrays kept here (positions,
    velocities, phase: bit for bit what ``state()`` would give). Each state also holds "changed": the ids of
    the rocks whose position or phase changed since the previous frame (every rock at frame 0)."""
    mirror = None
    for f in range(frames):
        sim.advance_to(f / fps)
        if guard:
            sim.check_health()
        if mirror is None:
            st = sim.state()
            sim.changes()  # every rock: the state just read
            mirror = {k: np.array(st[k], copy=True) for k in ("positions", "velocities", "phase", "radii")}
            changed = np.arange(sim.n_rocks, dtype=np.int32)
        else:
            rows = sim.changes(velocities=True)
            changed = np.sort(rows["ids"])
            ids = rows["ids"]
            mirror["positions"][ids] = rows["positions"]
            mirror["velocities"][ids] = rows["velocities"]
            mirror["phase"][ids] = rows["phase"]
            st = sim.state(rocks=False)
        yield f, {**st, **mirror, "changed": changed}
        if progress is not None:
            progress.update(1)
