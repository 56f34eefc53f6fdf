"""Where a frame's time goes: the stages of the renderer's frame, timed by laps of one clock.

:class:`Stages` adds the wall time since the last lap to the stage a lap names, so that the stages of a frame add
up to the frame (render/renderer.py ``render_frame``), and the process's CPU time with it (every thread's: the
kernels' and lavapipe's threads count, what other programs on the machine take does not; on a shared machine
it is the steadier measure); ``taichi-rocks render --profile`` reports them (app/render.py) and
docs/rendering.md shows a committed run's (tools/readme_tables.py). A stage may be lapped several times a frame
(GGUI's declaration, around the marks'). :data:`STAGES` names them in the frame's order, with what each holds.
"""

import resource
import time

__all__ = ["STAGES", "Stages", "cpu_seconds"]

STAGES = {
    "camera": "the camera and the sun",
    "culling": "the rock pass: culling, splatting the resting rocks, compacting the flying ones",
    "marks": "the hits: new impacts, their flashes, the marks made and posed",
    "declare": "declaring GGUI's scene: vehicles, flying rocks, overlays",
    "readback": "GGUI draws (lavapipe on a CPU) and hands back the image (get_image_buffer_as_numpy)",
    "sky_ground": "sky and ground under what GGUI drew: one ray a pixel, the shadows, the splatted rocks blended in",
    "dust": "the dust's puffs, summed and blended over the frame",
    "window": "the hidden window opened anew (every window_every frames)",
}


def cpu_seconds() -> float:
    """The CPU time this process has used so far, every thread's, user and system."""
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime


class Stages:
    """Seconds per stage (``seconds``: wall time, ``cpu``: the process's CPU time; STAGES' names), laps of one
    clock: :meth:`start` a frame, :meth:`lap` at the end of each stage."""

    def __init__(self):
        self.seconds = dict.fromkeys(STAGES, 0.0)
        self.cpu = dict.fromkeys(STAGES, 0.0)
        self._t = self._c = None

    def start(self) -> None:
        self._t, self._c = time.perf_counter(), cpu_seconds()

    def lap(self, stage: str) -> None:
        """The time since the last lap (or the start) goes to ``stage``."""
        now, cpu = time.perf_counter(), cpu_seconds()
        self.seconds[stage] += now - self._t
        self.cpu[stage] += cpu - self._c
        self._t, self._c = now, cpu
