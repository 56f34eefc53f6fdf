"""The view's clock: which frame of the simulation is shown, playing, stepping and scrubbing.

The simulation only ever stands at frame times k / fps and goes from one to the next as ``render`` does
(``sim.advance_to((k + 1) / fps)``, then the camera rig's ``view()``), so frame k in the window is frame k of
``render`` (``advance_to`` is not path-independent when dt does not divide 1 / fps: the frame boundaries are
part of the run). Going back restores the newest state saved in memory at or before the wanted frame
(``sim.checkpoint()`` plus the rig's smoothed heading and clock, as ``render --resume`` saves them, output/resume.py)
and simulates forward from there without drawing.

States are saved every ``every`` frames; when more than ``keep`` are held, ``every`` doubles and the states
off the new grid are dropped, so memory stays bounded (``keep`` states) however long a session plays, and a
scrub replays at most ``every`` frames. A changed runtime parameter invalidates the future: the states after
the current frame are dropped (:meth:`forget_after`); going back then replays with the new settings.

Driving (app/driving.py): ``before_advance`` is called with each frame about to be simulated (playing, stepping
and the replays of a seek alike), and an ``endless`` timeline grows by a second whenever playing reaches its end.
"""

import math

__all__ = ["Timeline", "SPEEDS", "MAX_CATCH_UP"]

SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0)  # playback speeds, simulated seconds per second of wall time
MAX_CATCH_UP = 8  # frames simulated at most per frame shown (a slow machine plays slower than asked)
MAX_WALL_STEP = 0.1  # s: a longer pause between two frames shown (a blocking seek, a recompile) counts as this


class Timeline:
    """Frame ``frame`` of a simulation at ``fps`` frames per second, ``frames`` frames long (the scene's
    duration; playing past the end starts again at frame 0). See the module docstring."""

    def __init__(self, fps: float, frames: int, every: int = 30, keep: int = 40):
        self.fps = float(fps)
        self.frames = max(int(frames), 1)
        self.every = max(int(every), 1)
        self.keep = max(int(keep), 2)
        self.frame = 0
        self.playing = True
        self.speed = 1.0
        self.loop = True
        self.saved = {}  # frame -> (sim checkpoint, rig heading, rig clock)
        self.replayed = 0  # frames simulated by seeks (tests, the HUD)
        self.before_advance = None  # called with the frame about to be simulated (a drive: app/driving.py)
        self.endless = False  # playing past the last frame makes the timeline longer (a drive has no end)
        self._clock = 0.0  # s of simulated time wanted by the playback

    # ------------------------------------------------------------------------------------------ states
    def save(self, sim, rig) -> None:
        """Remember the state at the current frame if it is on the grid."""
        if self.frame % self.every or self.frame in self.saved:
            return
        self.saved[self.frame] = (sim.checkpoint(), rig.heading, rig.t)
        if len(self.saved) > self.keep:
            self.every *= 2
            self.saved = {k: v for k, v in self.saved.items() if k % self.every == 0}

    def forget_after(self, frame: int) -> None:
        self.saved = {k: v for k, v in self.saved.items() if k <= frame}

    def _restore(self, frame: int, sim, rig) -> None:
        state, heading, t = self.saved[frame]
        sim.restore(state)
        rig.heading, rig.t = heading, t
        self.frame = frame

    # ------------------------------------------------------------------------------------------ moving
    def advance(self, sim, view) -> None:
        """One frame forward: simulate to the next frame time and advance the camera (``view()``)."""
        self.frame += 1
        if self.before_advance is not None:
            self.before_advance(self.frame)
        sim.advance_to(self.frame / self.fps)
        view()

    def seek(self, target: int, sim, rig, view) -> None:
        """Go to frame ``target`` (clamped to the scene's frames): forward by simulating, back (or far
        forward) from the nearest saved state at or before it."""
        target = min(max(int(target), 0), self.frames - 1)
        base = max((k for k in self.saved if k <= target), default=None)
        if target < self.frame or (base is not None and base > self.frame):
            if base is None:
                raise RuntimeError("no saved state before the wanted frame (frame 0 is always saved)")
            self._restore(base, sim, rig)
        while self.frame < target:
            self.advance(sim, view)
            self.replayed += 1
            self.save(sim, rig)
        self._clock = self.frame / self.fps

    def tick(self, wall_dt: float, sim, rig, view) -> int:
        """Playing: advance the clock by ``speed`` x ``wall_dt`` and the simulation to it (at most
        MAX_CATCH_UP frames), starting again at frame 0 after the last frame. Return the frames advanced."""
        if not self.playing:
            self._clock = self.frame / self.fps
            return 0
        self._clock += self.speed * min(max(wall_dt, 0.0), MAX_WALL_STEP)
        want = int(math.floor(self._clock * self.fps + 1e-9))
        want = min(want, self.frame + MAX_CATCH_UP)
        n = 0
        while self.frame < want:
            if self.frame >= self.frames - 1 and self.endless:
                self.frames += max(1, int(round(self.fps)))  # one more second
            if self.frame >= self.frames - 1:
                if not self.loop:
                    self.playing = False
                    break
                self.seek(0, sim, rig, view)
                self._clock = 0.0
                return n + 1
            self.advance(sim, view)
            self.save(sim, rig)
            n += 1
        if self.frame < want or n == MAX_CATCH_UP:
            self._clock = self.frame / self.fps  # behind: play slower rather than pile up
        return n

    def faster(self, up: bool) -> None:
        i = min(range(len(SPEEDS)), key=lambda k: abs(SPEEDS[k] - self.speed))
        self.speed = SPEEDS[min(max(i + (1 if up else -1), 0), len(SPEEDS) - 1)]

    @property
    def time(self) -> float:
        return self.frame / self.fps
