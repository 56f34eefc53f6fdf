"""Recorded drives: the text format of docs/drives.md, read and checked (:func:`read_drive`) and written
(:func:`drive_text`). A recorded drive is the poses of one vehicle over time, as ``taichi-rocks view --drive
NAME --record-drive FILE`` writes them and as a scene's ``path = { kind = "recorded", file = "FILE" }`` replays
them (motion/live.py). Stdlib only: C++ and other hosts read the same text.

The file:

    taichi-rocks drive 1
    # any number of comment lines, here and between rows
    t x y heading speed yaw_rate wheel_spin
    0 0 0 0 20 0 -
    0.03333333333333333 0.6666666666666666 0 0 20 0 -

Line 1 names the format and its version; the first line after it that is not a comment names the columns, in
this order; then one row per pose, whitespace-separated: t (s, >= 0, strictly increasing), x, y (m, world),
heading (rad, counter-clockwise from +x), speed (m/s along the heading, negative reversing), yaw_rate (rad/s),
wheel_spin (rad/s of the rear wheels, or ``-``: rolling, the engine's rule). Numbers are written with the
shortest text that reads back to the same float64 (Python's ``repr``), so a replay has the bits of the drive.
"""

from __future__ import annotations

import math
import os
from typing import Union

__all__ = ["HEADER", "COLUMNS", "ROLLING", "DriveFileError", "read_drive", "drive_text", "is_drive_file"]

HEADER = "taichi-rocks drive 1"
COLUMNS = ("t", "x", "y", "heading", "speed", "yaw_rate", "wheel_spin")
ROLLING = "-"  # the wheel_spin of a row whose rear wheels roll (the engine's rule: speed / R (1 + slip))
MAX_BYTES = 256 * 1024 * 1024  # a drive of a day at 60 poses a second is ~0.5 GB: refuse the absurd, not the long


class DriveFileError(ValueError):
    """A drive file that cannot be used; the message is one line naming the file (and the line)."""


def is_drive_file(path: Union[str, os.PathLike]) -> bool:
    """True for a file named ``*.drive`` or whose first line names this format, in any version (``taichi-rocks
    check`` tells drives from scenes so)."""
    if str(path).endswith(".drive"):
        return True
    try:
        with open(path, "rb") as f:
            return f.readline(64).decode("utf-8", "replace").startswith(HEADER.rsplit(" ", 1)[0])
    except OSError:
        return False


def read_drive(path: Union[str, os.PathLike], shown: str | None = None) -> tuple:
    """The rows of the drive file ``path``: a tuple of (t, x, y, heading, speed, yaw_rate, wheel_spin) float
    tuples, wheel_spin NaN where the file says ``-``. ``shown``: how messages name the file (default: the path).

    Raises:
        DriveFileError: unreadable, not this format (line 1), a missing or wrong column line, a row of the wrong
            width, a value that is not a finite number, times not strictly increasing or negative, no rows;
            one line ``FILE:LINE: what``.
    """
    name = str(path) if shown is None else shown
    try:
        if os.path.getsize(path) > MAX_BYTES:
            raise DriveFileError(f"{name}: larger than {MAX_BYTES // 2 ** 20} MB: not a drive")
        with open(path, "rb") as f:
            data = f.read()
    except OSError as e:
        raise DriveFileError(f"{name}: cannot read: {e.strerror or e}") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise DriveFileError(f"{name}: not UTF-8 text (byte {e.start})") from None
    return _rows(text.splitlines(), name)


def _rows(lines: list, name: str) -> tuple:
    if not lines or lines[0].strip() != HEADER:
        got = lines[0].strip()[:40] if lines else "an empty file"
        raise DriveFileError(f"{name}:1: expected the header {HEADER!r}, got {got!r}")
    rows, columns_seen = [], False
    for n, raw in enumerate(lines[1:], start=2):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        words = line.split()
        if not columns_seen:
            if tuple(words) != COLUMNS:
                raise DriveFileError(f"{name}:{n}: expected the columns {' '.join(COLUMNS)!r}, got {line[:60]!r}")
            columns_seen = True
            continue
        rows.append(_row(words, name, n, rows[-1][0] if rows else None))
    if not columns_seen:
        raise DriveFileError(f"{name}: no column line ({' '.join(COLUMNS)!r})")
    if not rows:
        raise DriveFileError(f"{name}: no poses (at least one row after the column line)")
    return tuple(rows)


def _row(words: list, name: str, n: int, t_prev) -> tuple:
    if len(words) != len(COLUMNS):
        raise DriveFileError(f"{name}:{n}: expected {len(COLUMNS)} values ({' '.join(COLUMNS)}), got {len(words)}")
    values = []
    for col, word in zip(COLUMNS, words):
        if col == "wheel_spin" and word == ROLLING:
            values.append(math.nan)
            continue
        try:
            v = float(word)
        except ValueError:
            raise DriveFileError(f"{name}:{n}: {col}: expected a number, got {word[:30]!r}") from None
        if not math.isfinite(v):
            raise DriveFileError(f"{name}:{n}: {col}: must be finite, got {word[:30]!r}")
        values.append(v)
    t = values[0]
    if t < 0.0:
        raise DriveFileError(f"{name}:{n}: t: must be >= 0, got {t!r}")
    if t_prev is not None and not t > t_prev:
        raise DriveFileError(f"{name}:{n}: t: times must increase, got {t!r} after {t_prev!r}")
    return tuple(values)


def drive_text(rows, comments=()) -> str:
    """The file's text for ``rows`` (t, x, y, heading, speed, yaw_rate, wheel_spin; NaN wheel spin: rolling),
    with ``comments`` (lines, without their '#') after the header."""
    out = [HEADER] + [f"# {c}" for c in comments] + [" ".join(COLUMNS)]
    for row in rows:
        vals = [float(v) for v in row]
        out.append(" ".join(ROLLING if (c == "wheel_spin" and math.isnan(v)) else repr(v)
                            for c, v in zip(COLUMNS, vals)))
    return "\n".join(out) + "\n"
