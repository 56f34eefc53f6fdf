"""PLY export: one binary little-endian point file per frame, ``DIR/frame_00000.ply``, ...

Each vertex is a rock written in that frame: ``double x, y, z`` (world metres: doubles keep millimetres and
better at any distance), ``float radius``, ``float vx, vy, vz`` (m/s) and ``uint id`` (the export's instance
id, output/instances.py: new after a recycle). Comments in the header give the frame, its time and the scene.
Houdini (File SOP), Blender (File > Import > Stanford PLY), MeshLab and NumPy read it; with NumPy::

    header, _, body = data.partition(b"end_header\\n")
    rocks = np.frombuffer(body, dtype=VERTEX)

A run that records impacts (``[effects] impacts``: frames carry ``impacts``, app/export.py) also writes
``DIR/impacts.ply``, one file of every event of the run, one vertex each (:data:`IMPACT`): ``double x, y, z``
(world metres: the contact point, the vehicle placed at the time of the hit), ``float nx, ny, nz`` (the body's
outward normal there), ``double time`` (s), ``uint frame`` (the exported frame it shows in: the first at or after
its time), ``int vehicle`` (the vehicle hit, scene order), ``uchar part`` (index into motion/bodies.py LABELS),
``uchar damage`` (into config/impacts.py DAMAGE_CLASSES: mark, chip, crack), ``float speed, normal_speed``
(m/s), ``float normal_momentum`` (N s), ``float energy`` (J), ``float radius`` (m), ``int rock`` and ``int
thrower`` (-1: unknown). Comments in its header name the labels, the classes and the vehicles; read it as
above with ``dtype=IMPACT``.

With ``[effects] dust`` (frames carry ``dust``), each frame's dust particles are ``DIR/dust_00000.ply``, ...:
``double x, y, z`` (world metres), ``float width`` (the drawn diameter, m) and ``float opacity`` (output/dust.py
:data:`~taichi_rocks.output.dust.DUST_VERTEX`); read them with ``dtype=DUST_VERTEX``.
"""

from __future__ import annotations


import numpy as np

from ..config.impacts import DAMAGE_CLASSES
from ..motion.bodies import LABELS
from .dust import DUST_VERTEX, dust_rows
from .formats import FolderWriter, frame_file

__all__ = ["PlyWriter", "VERTEX", "IMPACT", "IMPACTS_FILE", "DUST_FRAME", "ply_name"]

VERTEX = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("radius", "<f4"), ("vx", "<f4"), ("vy", "<f4"),
                   ("vz", "<f4"), ("id", "<u4")])
IMPACT = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4"),
                   ("time", "<f8"), ("frame", "<u4"), ("vehicle", "<i4"), ("part", "u1"), ("damage", "u1"),
                   ("speed", "<f4"), ("normal_speed", "<f4"), ("normal_momentum", "<f4"), ("energy", "<f4"),
                   ("radius", "<f4"), ("rock", "<i4"), ("thrower", "<i4")])
IMPACTS_FILE = "impacts.ply"
DUST_FRAME = "dust_{:05d}.ply"  # a frame's dust particles
_TYPES = {"<f8": "double", "<f4": "float", "<u4": "uint", "<i4": "int", "|u1": "uchar"}


def _header(element: str, dtype: np.dtype, n: int, comments) -> bytes:
    props = "".join(f"property {_TYPES[dtype[k].str]} {k}\n" for k in dtype.names)
    lines = "".join(f"comment {c}\n" for c in comments)
    return (f"ply\nformat binary_little_endian 1.0\n{lines}element {element} {n}\n{props}end_header\n").encode("ascii")


def _ascii(text) -> str:
    return " ".join(str(text).split()).encode("ascii", "backslashreplace").decode("ascii")


def ply_name(frame: int) -> str:
    return frame_file(frame, ".ply")


class PlyWriter(FolderWriter):
    """``--format ply``: the frames into a folder (output/formats.py FolderWriter: each file written under a
    temporary name in the folder, renamed into place when all are complete)."""

    name = "ply"
    default_name = "ply"
    frame_suffix = ".ply"
    label = "PLY"

    @classmethod
    def owned(cls, name: str) -> bool:
        # the run's impacts and the frames' dust beside its frames are ours too
        dust = name.startswith("dust_") and name.endswith(".ply") and name[5:-4].isdigit()
        return name == IMPACTS_FILE or dust or super().owned(name)

    def __init__(self, out, run):
        super().__init__(out, run)
        self.scene = _ascii(run.scene.name)
        self.vehicles = [_ascii(v.name) for v in run.scene.vehicles]
        self.impacts = None  # the run's events (IMPACT rows), once a frame has brought impacts
        self.dust_table = run.scene.dust

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
        header = _header("vertex", VERTEX, len(rows), (f"taichi-rocks scene {self.scene}",
                                                       f"frame {fr['frame']} time {fr['time']!r} s"))
        with open(self.frame_path(fr["frame"]), "xb") as f:
            f.write(header)
            f.write(rows.tobytes())
        if "impacts" in fr:
            self._add_impacts(fr["impacts"], int(fr["frame"]))
        if "dust" in fr:
            rows = dust_rows(fr["dust"], self.dust_table)
            header = _header("vertex", DUST_VERTEX, len(rows), (f"taichi-rocks scene {self.scene} dust",
                                                                f"frame {fr['frame']} time {fr['time']!r} s"))
            with open(self.file_path(DUST_FRAME.format(int(fr["frame"]))), "xb") as f:
                f.write(header)
                f.write(rows.tobytes())

    def _add_impacts(self, imp: dict, frame: int) -> None:
        ev = imp["events"]
        rows = np.zeros(len(ev), IMPACT)
        for axis, key in enumerate("xyz"):
            rows[key] = imp["world"][:, axis]
            rows["n" + key] = imp["normals"][:, axis]
        rows["frame"] = frame
        for key in ("time", "vehicle", "part", "damage", "speed", "normal_speed", "normal_momentum", "energy",
                    "radius", "rock", "thrower"):
            rows[key] = ev[key]
        self.impacts = rows if self.impacts is None else np.concatenate([self.impacts, rows])

    def close(self) -> int:
        if self.impacts is not None:
            header = _header("vertex", IMPACT, len(self.impacts), (
                f"taichi-rocks scene {self.scene} impacts", "part: " + " ".join(LABELS),
                "damage: " + " ".join(DAMAGE_CLASSES), "vehicle: " + " ".join(self.vehicles)))
            with open(self.file_path(IMPACTS_FILE), "xb") as f:
                f.write(header)
                f.write(self.impacts.tobytes())
        return super().close()
