"""PLY export: one binary little-endian point file per frame, ``DIR/frame_00000.ply``, ...

Each vertex is a rock written in that frame: ``double x, y, z`` (world metres: doubles keep millimetres and
better at any distance), ``float radius``, ``float vx, vy, vz`` (m/s) and ``uint id`` (the export's instance
id, output/instances.py: new after a recycle). Comments in the header give the frame, its time and the scene.
Houdini (File SOP), Blender (File > Import > Stanford PLY), MeshLab and NumPy read it; with NumPy::

    header, _, body = data.partition(b"end_header\\n")
    rocks = np.frombuffer(body, dtype=VERTEX)
"""

from __future__ import annotations

import numpy as np

from .formats import FolderWriter, frame_file

__all__ = ["PlyWriter", "VERTEX", "ply_name"]

VERTEX = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("radius", "<f4"), ("vx", "<f4"), ("vy", "<f4"),
                   ("vz", "<f4"), ("id", "<u4")])
_TYPES = {"<f8": "double", "<f4": "float", "<u4": "uint"}


def ply_name(frame: int) -> str:
    return frame_file(frame, ".ply")


class PlyWriter(FolderWriter):
    """``--format ply``: the frames into a folder (output/formats.py FolderWriter: written in a temporary
    folder, renamed into place when complete)."""

    name = "ply"
    default_name = "ply"
    frame_suffix = ".ply"
    label = "PLY"

    def __init__(self, out, run):
        super().__init__(out, run)
        self.scene = " ".join(str(run.scene.name).split()).encode("ascii", "backslashreplace").decode("ascii")

    def write(self, fr: dict) -> None:
        ids = np.asarray(fr["ids"], np.int64)
        if len(ids) and int(ids.max()) >= 2 ** 32:
            raise ValueError(f"frame {fr['frame']}: rock id {int(ids.max())} does not fit the PLY id (uint32)")
        rows = np.empty(len(ids), VERTEX)
        for axis, key in enumerate("xyz"):
            rows[key] = fr["world"][:, axis]
        rows["radius"] = fr["radii"]
        for axis, key in enumerate(("vx", "vy", "vz")):
            rows[key] = fr["velocities"][:, axis]
        rows["id"] = ids
        props = "".join(f"property {_TYPES[VERTEX[k].str]} {k}\n" for k in VERTEX.names)
        header = (f"ply\nformat binary_little_endian 1.0\ncomment taichi-rocks scene {self.scene}\n"
                  f"comment frame {fr['frame']} time {fr['time']!r} s\nelement vertex {len(rows)}\n{props}"
                  "end_header\n")
        with open(self.frame_path(fr["frame"]), "xb") as f:
            f.write(header.encode("ascii"))
            f.write(rows.tobytes())
