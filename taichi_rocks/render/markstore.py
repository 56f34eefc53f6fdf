"""The marks of a run's hits, made once each (host, NumPy): every windscreen mark and paint chip of the hits seen
(render/marks.py ``Hits``), its shape computed when its hit first shows and kept, in the hits' time order.

A mark is rows of one of two tables, in the hit vehicle's body frame, which only grow at their end:

* ``glass``: the segments of a windscreen mark (render/glassmarks.py ``mark_segments``), a row each: the ends in
  glass coordinates (y0, v0, y1, v1), the vehicle and the row's rank among that vehicle's (:data:`GLASS_ROW`);
  segments of no length are left out (they draw nothing);
* ``chips``: the triangles of a paint chip (render/paintchips.py ``paint_chip``), a row each: three corners and
  the face's outward normal, body frame, the vehicle and the rank (:data:`CHIP_ROW`).

The hits are in time order, so the marks shown at time t are the first marks of the store, and their rows the first
rows of each table (:meth:`MarkStore.shown`, with how many of them each vehicle has): a scrub back shows fewer of
them and a scrub forward more, with nothing made again. :meth:`MarkStore.sync` makes the marks of the hits shown
that it does not hold; when the hits changed otherwise (hits forgotten, one older than the newest sorted in:
``Hits.changes``), it keeps its marks before the first hit changed and makes the rest again.
:meth:`MarkStore.changed_from` tells the device's copy (render/markmesh.py) from which rows on to upload.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .glassmarks import cabin_for, mark_segments
from .marks import WINDSCREEN, severity
from .paintchips import body_faces, paint_chip

__all__ = ["MarkStore", "Shown", "GLASS_ROW", "CHIP_ROW"]

GLASS_ROW = ("y0", "v0", "y1", "v1", "vehicle", "rank")
CHIP_ROW = ("ax", "ay", "az", "bx", "by", "bz", "cx", "cy", "cz", "nx", "ny", "nz", "vehicle", "rank")
_MARK = 6  # a mark's row: time, step, rock, vehicle, the glass and chip rows up to it; then per vehicle both again


class Shown(NamedTuple):
    """The rows of the marks shown: the first ``glass`` and ``chips`` rows of the tables, ``glass_of[i]`` and
    ``chips_of[i]`` of them vehicle i's."""

    glass: int
    chips: int
    glass_of: np.ndarray
    chips_of: np.ndarray


class _Table:
    """Rows of ``width`` float64 columns in a buffer that grows in powers of two."""

    def __init__(self, width: int):
        self._buf, self.n = np.empty((64, width)), 0

    @property
    def rows(self) -> np.ndarray:
        return self._buf[:self.n]

    def append(self, rows: np.ndarray) -> None:
        if self.n + len(rows) > len(self._buf):
            cap = len(self._buf)
            while cap < self.n + len(rows):
                cap *= 2
            grown = np.empty((cap, self._buf.shape[1]))
            grown[:self.n] = self._buf[:self.n]
            self._buf = grown
        self._buf[self.n:self.n + len(rows)] = rows
        self.n += len(rows)


class MarkStore:
    """The marks of the hits of a run on ``vehicles`` (the scene's specs): see the module docstring. ``made``
    counts the marks whose shapes were computed (each once, unless the hits changed under them)."""

    def __init__(self, vehicles):
        self.cabins = [cabin_for(v) for v in vehicles]
        self._vehicles = vehicles
        self._faces = {}
        self.glass, self.chips = _Table(len(GLASS_ROW)), _Table(len(CHIP_ROW))
        self._n = len(vehicles)
        self._marks = _Table(_MARK + 2 * self._n)  # per mark: see _MARK
        self._ranks = np.zeros((2, self._n), np.int64)  # each vehicle's glass and chip rows so far
        self._seen_changes = 0  # the entries of Hits.changes taken into account
        self._changed = [0, 0]  # the first glass and chip rows changed since changed_from() last answered
        self.made = 0

    def __len__(self) -> int:
        return self._marks.n

    def _body_faces(self, i: int):
        if i not in self._faces:
            self._faces[i] = body_faces(self._vehicles[i])
        return self._faces[i]

    def sync(self, hits) -> int:
        """Make the marks of ``hits`` (render/marks.py Hits) shown at its time that are not held; return how
        many were made."""
        marked = hits.marked
        keep = min([self._marks.n] + hits.changes[self._seen_changes:])  # before what the hits changed since
        self._seen_changes = len(hits.changes)
        self._truncate(keep)
        upto = int(np.searchsorted(marked["time"], hits.t, side="right"))
        for e in marked[keep:upto]:
            self._make(e, hits)
        return max(upto - keep, 0)

    def _truncate(self, keep: int) -> None:
        if keep < self._marks.n:
            last = self._marks.rows[keep - 1] if keep else np.zeros(self._marks.rows.shape[1])
            g, c = int(last[4]), int(last[5])
            self._marks.n, self.glass.n, self.chips.n = keep, g, c
            self._ranks = last[_MARK:].reshape(2, self._n).astype(np.int64)
            self._changed = [min(self._changed[0], g), min(self._changed[1], c)]

    def _make(self, e, hits) -> None:
        """The shape of the mark of hit ``e``, appended to its table."""
        i = int(e["vehicle"])
        s = severity(e, hits.thresholds, hits.measure)
        glass = int(e["part"]) == WINDSCREEN
        if glass:
            seg = mark_segments(e, s, self.cabins[i])
            rows = seg[np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) > 1e-9].reshape(-1, 4)  # no length: nothing
        else:
            tris, n = paint_chip(e, s, self._body_faces(i))
            rows = np.concatenate([tris.reshape(-1, 9), np.tile(n, (len(tris), 1))], 1)
        k = 0 if glass else 1
        rank = self._ranks[k, i] + np.arange(len(rows))
        (self.glass if glass else self.chips).append(np.concatenate([rows, np.full((len(rows), 1), i),
                                                                     rank[:, None]], 1))
        self._ranks[k, i] += len(rows)
        self._marks.append(np.concatenate([[float(e["time"]), int(e["step"]), int(e["rock"]), i, self.glass.n,
                                            self.chips.n], self._ranks.ravel()])[None])
        self.made += 1

    def shown(self, t: float) -> Shown:
        """The rows of the marks made at or before time ``t``: the first rows of each table."""
        m = int(np.searchsorted(self._marks.rows[:, 0], float(t), side="right"))
        if m == 0:
            return Shown(0, 0, np.zeros(self._n, np.int64), np.zeros(self._n, np.int64))
        row = self._marks.rows[m - 1]
        of = row[_MARK:].reshape(2, self._n).astype(np.int64)
        return Shown(int(row[4]), int(row[5]), of[0], of[1])

    def changed_from(self) -> tuple:
        """The first (glass, chip) rows that changed since the last call (the tables' lengths if none did)."""
        out = (min(self._changed[0], self.glass.n), min(self._changed[1], self.chips.n))
        self._changed = [self.glass.n, self.chips.n]
        return out

    def segments(self, vehicle: int, t: float) -> np.ndarray:
        """The windscreen marks' segments (K, 2, 2, glass coordinates) of ``vehicle`` shown at time ``t``."""
        rows = self.glass.rows[:self.shown(t).glass]
        return rows[rows[:, 4] == vehicle, :4].reshape(-1, 2, 2)

    def paint_chips(self, vehicle: int, t: float) -> tuple:
        """The paint chips of ``vehicle`` shown at time ``t``: triangles (K, 3, 3) and their normals (K, 3),
        body frame."""
        rows = self.chips.rows[:self.shown(t).chips]
        rows = rows[rows[:, 12] == vehicle]
        return rows[:, :9].reshape(-1, 3, 3), rows[:, 9:12]
