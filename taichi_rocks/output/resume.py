"""Resuming an interrupted render: saved simulation states next to the frames.

A render writes ``out_dir/.resume/render.json`` (a fingerprint of what decides the pictures: the scene, the
frame rate, the resolution and the rock drawing mode) when it starts, and every ``every`` frames the state
after frame k: ``out_dir/.resume/frame_0000k.npz`` = ``Simulation.checkpoint()`` + the chase camera's
smoothed heading and clock. Each file is written under a temporary name and renamed, and the last two are
kept (the newest may be ahead of the frames on disk: PNGs are encoded in a background thread). The states are
written without time stamps (recording.write_npz): the same state gives the same bytes. A render that
finishes removes the folder, and so does one that fails or is interrupted before its first finished frame
(there is nothing to resume).

``render --resume`` restores the newest state of a frame before the first missing one and simulates only
from there (without it, from t = 0); the simulation and the camera are deterministic, so the frames equal an
uninterrupted render's. A fingerprint that differs (the scene file was edited, another --fps) is refused.
"""

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np

from ..config.scene import scene_to_dict
from .atomic import remove_stale_temporaries, write_atomically
from .npz import write_npz

CHECKPOINT_EVERY = 30  # frames between saved states (~10 MB for 200,000 rocks, ~20 ms to write)
KEEP = 2


def resume_dir(out_dir) -> Path:
    return Path(out_dir) / ".resume"


def fingerprint(scene, fps: float, resolution, rocks: str) -> str:
    blob = json.dumps({"scene": scene_to_dict(scene), "fps": float(fps), "resolution": [int(x) for x in resolution],
                       "rocks": rocks}, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


class RenderCheckpoints:
    """The ``.resume`` folder of one render (see the module docstring)."""

    def __init__(self, out_dir, print_: str, every: int = CHECKPOINT_EVERY):
        self.dir = resume_dir(out_dir)
        self.print = print_
        self.every = int(every)

    # ------------------------------------------------------------------------------------------------
    def start(self, resume: bool, first_missing: int = 0) -> None:
        """A new render forgets older states; a resumed one (which has called :meth:`check_same_render`)
        drops the temporaries of a killed render and the states of frames it will draw again (at or after
        ``first_missing``)."""
        if not resume:
            shutil.rmtree(self.dir, ignore_errors=True)
        else:
            for tmp in self.dir.glob(".*.*.*"):  # temporaries of a killed render: .frame_00029.npz.PID.XXX.part
                for ext in (".npz.", ".json."):
                    if ext in tmp.name:
                        remove_stale_temporaries(self.dir / (tmp.name[1:].split(ext)[0] + ext[:-1]))
            for path in self.saved():
                if int(path.stem.split("_")[1]) >= first_missing:
                    path.unlink(missing_ok=True)
        self.dir.mkdir(parents=True, exist_ok=True)
        meta = self.dir / "render.json"
        write_atomically(meta, lambda f: f.write(json.dumps({"fingerprint": self.print}).encode()))

    def check_same_render(self) -> None:
        meta = self.dir / "render.json"
        if not meta.is_file():
            return
        try:
            theirs = json.loads(meta.read_text()).get("fingerprint")
        except (OSError, ValueError):
            return
        if theirs != self.print:
            raise ValueError(f"cannot resume: the frames in {self.dir.parent} were rendered from another scene, "
                             f"frame rate, resolution or rock mode; render again with --overwrite")

    def due(self, k: int, n_frames: int) -> bool:
        return self.every > 0 and (k + 1) % self.every == 0 and k + 1 < n_frames

    def save(self, k: int, sim, rig) -> Path:
        """Save the state after frame ``k``; keep the newest KEEP."""
        data = sim.checkpoint().as_dict()
        data.update(frame=np.int64(k), camera_heading=np.float64(rig.heading if rig.heading is not None else np.nan),
                    camera_t=np.float64(rig.t if rig.t is not None else np.nan), fingerprint=np.array(self.print))
        final = self.dir / f"frame_{k:05d}.npz"
        write_atomically(final, lambda f: write_npz(f, data))  # the same state, the same bytes
        for old in self.saved()[:-KEEP]:
            old.unlink(missing_ok=True)
        return final

    def saved(self) -> list:
        return sorted(self.dir.glob("frame_*.npz"))

    def latest_before(self, frame: int):
        """The newest saved state of a frame < ``frame`` as a dict, or None."""
        for path in reversed(self.saved()):
            try:
                with np.load(path) as z:
                    data = {k: z[k] for k in z.files}
            except (OSError, ValueError, KeyError):  # not ours or damaged: simulate from further back
                continue
            if str(data.get("fingerprint")) == self.print and int(data["frame"]) < frame:
                return data
        return None

    @staticmethod
    def restore(data: dict, sim, rig) -> int:
        """Put ``sim`` and the camera ``rig`` in the saved state; return the frame it was saved after."""
        sim.restore(data)
        h, t = float(data["camera_heading"]), float(data["camera_t"])
        rig.heading = None if np.isnan(h) else h
        rig.t = None if np.isnan(t) else t
        return int(data["frame"])

    def finish(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)
