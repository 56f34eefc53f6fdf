"""The game's frame budget: wall time per part of each frame, medians and 95th percentiles over the frames after
the first WARMUP (the first frame compiles the rock system's kernels and uploads every rock).

Parts: ``rocks`` the rock system's calls (drive, advance_to, impacts, changes), ``mirror`` the mirror's update
(the changed rows into the mirror and the vertex buffer), ``game`` the rest of the game's frame (its car, the
vehicles, the camera, the hits, the HUD), ``draw`` the engine's frame (Panda3D's task step: cull, draw, and in
a window the swap); ``png`` writing a frame offscreen (outside the frame: a recording's cost, not the game's).
A frame is rocks + mirror + game + draw; fps = 1000 / its median in ms. ``bare`` (with --bare): a frame of the
engine alone, the scene hidden and the same number of points re-uploaded whole, drawn from the same camera
between two game frames.
"""

from __future__ import annotations

import json

import numpy as np

WARMUP = 3
FRAME_PARTS = ("rocks", "mirror", "game", "draw")


class Budget:
    def __init__(self):
        self.ms = {}
        self.frames = 0

    def add(self, name: str, ms: float) -> None:
        self.ms.setdefault(name, []).append(ms)

    def series(self, name: str) -> np.ndarray:
        return np.asarray(self.ms.get(name, [])[WARMUP:], np.float64)

    def frame_series(self) -> np.ndarray:
        n = min(len(self.ms.get(p, [])) for p in FRAME_PARTS)
        return sum(np.asarray(self.ms[p][:n]) for p in FRAME_PARTS)[WARMUP:]

    def median(self, name: str) -> float:
        s = self.frame_series() if name == "frame" else self.series(name)
        return float(np.median(s)) if len(s) else float("nan")

    def table(self) -> str:
        """The budget per part, one line each: median and 95th percentile, ms."""
        lines = [f"frame budget over {max(len(self.frame_series()), 0)} frames (the first {WARMUP} left out), ms:",
                 f"  {'part':<8} {'median':>8} {'p95':>8}"]
        for name in (*FRAME_PARTS, "frame", "png", "bare"):
            s = self.frame_series() if name == "frame" else self.series(name)
            if len(s):
                lines.append(f"  {name:<8} {np.median(s):8.2f} {np.percentile(s, 95):8.2f}")
        return "\n".join(lines)

    def summary(self, frames: int, rocks: int, hits: int, **extra) -> str:
        """The last line: one JSON object, medians (NaN, as null, when no frame was measured)."""
        frame = self.median("frame")
        out = {"frames": int(frames), "fps": _num(1e3 / frame if frame > 0 else float("nan")),
               "rocks_ms": _num(self._median_sum("rocks", "mirror")), "draw_ms": _num(self.median("draw")),
               "rocks": int(rocks), "hits": int(hits)}
        if len(self.series("bare")):
            out["bare_fps"] = _num(1e3 / self.median("bare"))
            out["bare_ms"] = _num(self.median("bare"))
        out.update(extra)
        return json.dumps(out)

    def _median_sum(self, *names) -> float:
        n = min(len(self.series(p)) for p in names)
        if not n:
            return float("nan")
        return float(np.median(sum(self.series(p)[:n] for p in names)))


def _num(x: float):
    return None if x != x else round(float(x), 3)
