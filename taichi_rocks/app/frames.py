"""The frames of a command: how many and how fast (``--frames``, ``--fps``, else the scene's duration and
[render] fps), and the loop that advances a simulation to each frame time."""

from __future__ import annotations

__all__ = ["frame_count", "frame_states"]


def frame_count(scene, frames=None, fps=None) -> tuple[int, float]:
    """(frames, fps): ``fps`` or the scene's [render] fps; ``frames`` or round(duration x fps), at least 1."""
    fps = fps or float(scene.render.fps)
    frames = frames or max(1, int(round(scene.duration * fps)))
    return frames, fps


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
