"""Export formats: one writer interface, several back-ends, one registry (``taichi-rocks export --format``).

Every format is a writer with the same four calls, as the viewers of newton-physics share one ``ViewerBase``:

* ``Writer.check_target(out, overwrite)`` (class method): refuse an output that cannot or must not be written
  (ValueError, FileExistsError; one line each), before anything is simulated;
* ``Writer(out, run)``: open, start writing ``out`` (under a temporary name beside it); ``run`` is the
  :class:`ExportRun` (the scene, frame count and rate, the selection, the vehicles' poses at any time);
* ``write(frame)``: one frame (below), in order;
* ``close()``: finish, ``out`` complete under its final name; returns its size in bytes. ``abort()`` instead,
  on a failure or Ctrl-C: remove what was written.

app/export.py runs the frames and drives the writer; output/export.py makes the frames. A frame is an
``ExportFrame`` (output/export.py; its fields, units and meanings: docs/records.md), read by attribute or as a
dict: ``frame`` (index), ``time`` (s), ``origin`` (3,) float64 (the engine's floating origin); the rocks chosen
(``--only``, ``--crop``), M of them: ``world`` (M, 3) float64 world metres, ``local`` (M, 3) float32
(``world - origin``), ``velocities``, ``radii``, ``ids`` (new after a recycle), ``proto`` (rock shape),
``orientations``, ``angular_velocities``, ``tints`` and ``tint``; ``vehicles`` (positions, headings, wheel
angles); ``camera`` (eye, target); ``cut`` (a shot starts here); and ``state``: the engine's whole state of the
frame (``Simulation.state()``: every rock, phase included).

Adding a format (impact events as CSV or PLY from the phase changes in ``frame["state"]``, per-rock
orientations as a table, ...) is one module and one line: a module ``output/<name>.py`` with a subclass of
:class:`FileWriter` (one file: implement ``write``, and ``close`` if the file needs finishing) or
:class:`FolderWriter` (a file per frame in a folder, each written under ``file_path(name)``), whose ``name`` is the ``--format`` value, and its line in
:data:`FORMATS` below. The command line lists FORMATS without importing the writers (USD's needs the optional
usd-core, slow to import); :func:`writer_class` imports one when it is used. This module needs only the
standard library.
"""

from __future__ import annotations

import importlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

from .atomic import check_place, remove_stale_in, temp_name

__all__ = ["FORMATS", "ExportRun", "ExportWriter", "FileWriter", "FolderWriter", "writer_class", "frame_file"]

# --format name -> (module in output/, its writer class); the first is the default
FORMATS = {
    "usd": ("usd", "UsdWriter"),
    "ply": ("ply", "PlyWriter"),
}


def writer_class(name: str) -> type:
    """The writer class of format ``name`` (its module imported now); ValueError for an unknown name."""
    if name not in FORMATS:
        raise ValueError(f"format must be one of {', '.join(FORMATS)}, got {name!r}")
    module, cls = FORMATS[name]
    return getattr(importlib.import_module(f"{__package__}.{module}"), cls)


def frame_file(frame: int, suffix: str) -> str:
    """The file of a frame in a folder format: ``frame_00000.ply``."""
    return f"frame_{frame:05d}{suffix}"


@dataclass(frozen=True)
class ExportRun:
    """What a writer knows of the whole export when it opens."""

    scene: Any  # the validated Scene (config/scene.py), with the run's seed
    fps: float
    frames: int
    dt: float  # s, the simulation's step
    only: str  # "all" or "flying"
    crop: Optional[float]  # m, or None
    fleet: Any  # motion/vehicles.py Fleet: ``poses(t)`` of every vehicle at any time (extents, paths)


class ExportWriter:
    """The interface of an export format (see the module docstring)."""

    name = ""  # the --format value
    default_name = ""  # the output under renders/<scene>/ when --out is not given ("{scene}" is replaced)

    @classmethod
    def check_target(cls, out, overwrite: bool) -> None:
        raise NotImplementedError

    def __init__(self, out, run: ExportRun):
        self.out = Path(out)
        self.run = run

    def write(self, frame: dict) -> None:
        raise NotImplementedError

    def close(self) -> int:
        raise NotImplementedError

    def abort(self) -> None:
        raise NotImplementedError


class FileWriter(ExportWriter):
    """A format written as one file: into a temporary file beside ``out`` (``self.tmp``, ending in
    ``temp_suffix``, for libraries that pick the format by extension), renamed over ``out`` by :meth:`close`."""

    suffixes: tuple = ()  # file name endings accepted (lower case); the first is the one named in messages
    temp_suffix = ".part"

    @classmethod
    def check_target(cls, out, overwrite: bool) -> None:
        out = Path(out)
        first, others = cls.suffixes[0], cls.suffixes[1:]
        if out.suffix.lower() not in cls.suffixes:
            raise ValueError(f"{out}: expected a {first}" + (f" (or {', '.join(others)})" if others else "")
                             + " file name")
        if out.is_dir():
            raise ValueError(f"{out}: is a directory, expected a {first} file name")
        check_place(out)
        if out.exists() and not overwrite:
            raise FileExistsError(f"{out}: exists; pass --overwrite to replace it")

    def __init__(self, out, run: ExportRun):
        super().__init__(out, run)
        self.tmp = temp_name(self.out, self.temp_suffix)

    def close(self) -> int:
        os.replace(self.tmp, self.out)
        return self.out.stat().st_size

    def abort(self) -> None:
        self.tmp.unlink(missing_ok=True)


class FolderWriter(ExportWriter):
    """A format written as a file per frame, ``frame_00000<frame_suffix>`` ..., into the folder ``out`` itself
    (made if missing; an existing folder, or a link to one, keeps its inode, owner and permissions). Each file is
    written under a hidden temporary name inside ``out`` (:meth:`file_path`) and renamed to its final name by
    :meth:`close` once every frame was written, which then removes the earlier export's files that this one did
    not replace (only with ``overwrite``, see :meth:`check_target`). :meth:`abort` removes the temporaries, and
    ``out`` if this writer made it: earlier frames stay as they were."""

    frame_suffix = ""
    label = ""  # the format's name in messages ("PLY")

    @classmethod
    def check_target(cls, out, overwrite: bool) -> None:
        out = Path(out)
        if out.exists() and not out.is_dir():
            raise ValueError(f"{out}: is a file, expected a folder for the {cls.label} frames")
        check_place(out, folder=True)
        if out.is_dir():
            entries = [p for p in out.iterdir() if not p.name.startswith(".")]
            other = [p.name for p in entries if not cls.owned(p.name)]
            if other:
                raise ValueError(f"{out}: holds other files ({other[0]}); export {cls.label} frames into a new or "
                                 "empty folder")
            if entries and not overwrite:
                raise FileExistsError(f"{out}: holds {cls.label} frames; pass --overwrite to replace them")

    @classmethod
    def owned(cls, name: str) -> bool:
        """Whether a file named ``name`` in the folder is one this format writes (replaced by an overwrite)."""
        return name.startswith("frame_") and name.endswith(cls.frame_suffix)

    def __init__(self, out, run: ExportRun):
        super().__init__(out, run)
        self.made = not self.out.is_dir()
        if self.made:
            self.out.mkdir(mode=0o755)
        remove_stale_in(self.out)
        self.parts: dict = {}  # final name -> its temporary in out

    def file_path(self, name: str) -> Path:
        """A new temporary inside ``out`` for the file ``name``, renamed to it by :meth:`close`."""
        tmp = temp_name(self.out / name, ".part")
        self.parts[name] = tmp
        return tmp

    def frame_path(self, frame: int) -> Path:
        return self.file_path(frame_file(frame, self.frame_suffix))

    def close(self) -> int:
        for name, tmp in self.parts.items():
            os.replace(tmp, self.out / name)
        for p in self.out.iterdir():  # an overwrite's earlier files beyond this export's (checked above)
            if p.name not in self.parts and self.owned(p.name):
                p.unlink()
        return sum((self.out / name).stat().st_size for name in self.parts)

    def abort(self) -> None:
        for tmp in self.parts.values():
            tmp.unlink(missing_ok=True)
        if self.made:
            try:
                self.out.rmdir()
            except OSError:
                pass
