"""The World's data on the device: a few ndarrays (engine/view.py ``GROUPS``), a table of where each field lies in
them, and the host's handles on each field.

* :class:`Layout` - which fields, in which group, with how many components and dimensions, plus the World's
  compile-time attributes (precision, tire count, switches of its shape): hashable, the key kernels compile
  by. Sizes are not in it.
* :class:`Placement` - the sizes: each field's offset in its group and its dimensions, the groups' lengths and the
  head of the int32 group (the table the kernels read, engine/view.py ``HEAD``).
* :class:`HostField` - a field from Python: ``to_numpy``, ``from_numpy``, ``fill``, ``[i]`` (read and write),
  ``shape``, as Taichi's fields had, each a copy kernel compiled once per group kind and process (a serial one
  for a few entries: :data:`SERIAL_COPY`).
"""

import math
from dataclasses import dataclass

import numpy as np
import taichi as ti

from .launcher import Launcher
from .view import GROUP_NAMES, GROUPS, HEAD, REAL_SIZES, SIZES

__all__ = ["Layout", "Placement", "HostField", "group_of", "NP_TYPES"]

NP_TYPES = {"i32": np.int32, "f64": np.float64, "i64": np.int64, "f32": np.float32}


def group_of(dtype: str, n: int) -> tuple[str, int]:
    """The group of a field of ``n`` components of ``dtype`` ("real", "i32", "f64", "i64"), and its row width (0:
    one element of the group per entry; else the scalars of the group that make one entry)."""
    if dtype == "real":
        if n in (3, 4):
            return f"r{n}", 0
        return "r1", 0 if n == 1 else n
    kind = {"i32": "i1", "f64": "d1", "i64": "l1"}[dtype]
    return kind, 0 if n == 1 else n


@dataclass(frozen=True)
class Layout:
    """Which fields a World holds and how a kernel reads them: ``fields`` (name, group, row width, dimensions,
    the dimensions past the first when the layout fixes them, else None) in table order and ``statics`` (name,
    value): the compile-time attributes a kernel reads as ``w.<name>``."""

    fields: tuple
    statics: tuple

    def index(self, name: str) -> int:
        return next(k for k, f in enumerate(self.fields) if f[0] == name)


class Placement:
    """Where each field of ``specs`` (world.FieldSpec list) lies for this World's sizes: per field its group,
    row width, offset (in its entries: elements of its group, or rows of ``row`` of them) and shape; each
    group's length; the int32 head."""

    def __init__(self, specs, sizes: dict, real_sizes: dict):
        used = {g: 0 for g in GROUP_NAMES}
        used["i1"] = HEAD * len(specs) + len(SIZES)
        used["r1"] = len(REAL_SIZES)
        self.at = {}
        head = np.zeros(used["i1"], np.int64)
        for k, s in enumerate(specs):
            group, row = group_of(s.dtype, s.n)
            entries = math.prod(s.shape) if s.shape else 1
            r = max(row, 1)
            used[group] = -(-used[group] // r) * r  # a field of rows starts at a whole row: its offset in rows
            offset = used[group] // r
            self.at[s.name] = (group, row, offset, tuple(s.shape))
            dims = (tuple(s.shape) + (1, 1, 1))[:3]
            head[HEAD * k:HEAD * k + HEAD] = (offset,) + dims
            used[group] += max(entries, 1) * r
        for j, name in enumerate(SIZES):
            head[HEAD * len(specs) + j] = int(sizes.get(name, 0))
        if np.abs(head).max(initial=0) > np.iinfo(np.int32).max:
            raise ValueError("a World past 2^31 entries of one group: more than the int32 indices of its kernels")
        self.head = head.astype(np.int32)
        self.real_head = np.array([float(real_sizes.get(n, 0.0)) for n in REAL_SIZES])
        self.lengths = {g: max(n, 1) for g, n in used.items()}

    def nbytes(self, real: str) -> int:
        """Bytes of the groups on the device, in precision ``real`` ("f32" or "f64")."""
        size = {"real": 8 if real == "f64" else 4, "i32": 4, "f64": 8, "i64": 8}
        return sum(n * GROUPS[g][1] * size[GROUPS[g][0]] for g, n in self.lengths.items())


class HostField:
    """Field ``name`` of a World from Python: its group ``arr`` (a ti.ndarray of elements of ``width``
    components), its offset (in entries), row width (0: an element per entry) and shape; NumPy dtype
    ``np_dtype``. Reads and writes copy through one kernel per group kind (compiled once per process; serial for
    at most :data:`SERIAL_COPY` elements)."""

    def __init__(self, name: str, arr, offset: int, row: int, shape: tuple, np_dtype, width: int, copies=None):
        self.name, self.arr, self.offset, self.row, self.shape = name, arr, offset, row, tuple(shape)
        # the copy kernels, launched at the cost of their launch (engine/launcher.py: one set per World, shared by
        # its fields), or Taichi's own call
        self._copy = copies or COPIES
        self.np_dtype, self.width = np.dtype(np_dtype), width
        self.entries = math.prod(self.shape) if self.shape else 1
        self.n = row or width  # components per entry
        self.dtype = self.np_dtype

    def _elements(self, first: int, count: int) -> tuple:
        """The group elements of entries first .. first + count: (start, count)."""
        r = max(self.row, 1)
        return (self.offset + first) * r if self.row else self.offset + first, count * r

    def _entry_shape(self) -> tuple:
        return () if self.n == 1 else (self.n,)

    def read(self, first: int, count: int) -> np.ndarray:
        """Entries first .. first + count (flat, row-major), as (count,) or (count, components)."""
        start, k = self._elements(first, count)
        out = np.empty((k, self.width) if self.width > 1 else (k,), self.np_dtype)
        if k:
            if self.width > 1:
                self._copy["read_vec"](self.arr, start, k, out, self.width, k <= SERIAL_COPY)
            else:
                self._copy["read"](self.arr, start, k, out, k <= SERIAL_COPY)
        return out.reshape((count,) + self._entry_shape())

    def write(self, first: int, a) -> None:
        """Entries first .. first + len(a) from ``a`` ((count,) or (count, components)), as they are."""
        a = np.ascontiguousarray(a, self.np_dtype)
        count = len(a) if a.ndim else 1
        start, k = self._elements(first, count)
        if k:
            flat = a.reshape((k, self.width) if self.width > 1 else (k,))
            if self.width > 1:
                self._copy["write_vec"](self.arr, start, k, flat, self.width, k <= SERIAL_COPY)
            else:
                self._copy["write"](self.arr, start, k, flat, k <= SERIAL_COPY)

    def to_numpy(self) -> np.ndarray:
        return self.read(0, self.entries).reshape(self.shape + self._entry_shape())

    def from_numpy(self, a) -> None:
        a = np.asarray(a)
        want = self.shape + self._entry_shape()
        if a.shape != want:
            raise ValueError(f"{self.name}: an array of shape {a.shape} for a field of shape {want}")
        self.write(0, a.reshape((self.entries,) + self._entry_shape()))

    def fill(self, value) -> None:
        self.from_numpy(np.broadcast_to(np.asarray(value, self.np_dtype), self.shape + self._entry_shape()))

    def _flat(self, idx) -> int:
        if ti.lang.impl.get_runtime().compiling_callable is not None:  # else a kernel would bake the value read
            # now into its code as a constant, and read it at every launch
            raise TypeError(f"{self.name}: a World's field indexed inside a Taichi kernel that is not a world "
                            "kernel: take the World as a parameter of an @world_kernel (engine/view.py)")
        if idx is None:
            idx = ()
        if not isinstance(idx, tuple):
            idx = (idx,)
        if len(idx) != len(self.shape):
            raise IndexError(f"{self.name}: {len(idx)} indices for a field of {len(self.shape)} dimensions")
        flat = 0
        for i, d in zip(idx, self.shape):
            i = int(i)
            if not -d <= i < d:
                raise IndexError(f"{self.name}: index {i} out of range {d}")
            flat = flat * d + (i % d)
        return flat

    def __getitem__(self, idx):
        v = self.read(self._flat(idx), 1)[0]
        return v if self.n > 1 else v.item()

    def __setitem__(self, idx, value) -> None:
        self.write(self._flat(idx), np.asarray(value, self.np_dtype).reshape((1,) + self._entry_shape()))

    def nbytes(self) -> int:
        return self.entries * self.n * self.np_dtype.itemsize


# copies of at most this many elements run as one serial task: one entry (``w.ipar[IPar.TABLE] = m``) or a few,
# where a parallel loop would wake the CPU's thread pool for nothing (and the step's serial variant, engine/loops.py,
# launches no parallel task between its kernels either)
SERIAL_COPY = 64


@ti.kernel
def _read(g: ti.types.ndarray(ndim=1), off: ti.i32, k: ti.i32, out: ti.types.ndarray(ndim=1), serial: ti.template()):
    if ti.static(serial):
        ti.loop_config(serialize=True)
    for i in range(k):
        out[i] = g[off + i]


@ti.kernel
def _write(g: ti.types.ndarray(ndim=1), off: ti.i32, k: ti.i32, a: ti.types.ndarray(ndim=1), serial: ti.template()):
    if ti.static(serial):
        ti.loop_config(serialize=True)
    for i in range(k):
        g[off + i] = a[i]


@ti.kernel
def _read_vec(g: ti.types.ndarray(ndim=1), off: ti.i32, k: ti.i32, out: ti.types.ndarray(ndim=2),
              width: ti.template(), serial: ti.template()):
    if ti.static(serial):
        ti.loop_config(serialize=True)
    for i in range(k):
        for c in ti.static(range(width)):
            out[i, c] = g[off + i][c]


@ti.kernel
def _write_vec(g: ti.types.ndarray(ndim=1), off: ti.i32, k: ti.i32, a: ti.types.ndarray(ndim=2),
               width: ti.template(), serial: ti.template()):
    if ti.static(serial):
        ti.loop_config(serialize=True)
    for i in range(k):
        for c in ti.static(range(width)):
            g[off + i][c] = a[i, c]


def group_dtype(group: str, real) -> object:
    """The Taichi element type of a group in a World of precision ``real``."""
    kind, width = GROUPS[group]
    base = {"real": real, "i32": ti.i32, "f64": ti.f64, "i64": ti.i64}[kind]
    return base if width == 1 else ti.types.vector(width, base)


def np_group_dtype(group: str, real_np):
    kind, _ = GROUPS[group]
    return real_np if kind == "real" else NP_TYPES[kind]


COPIES = {"read": _read, "write": _write, "read_vec": _read_vec, "write_vec": _write_vec}  # Taichi's own calls


def copy_launchers() -> dict:
    """The copy kernels behind launchers (engine/launcher.py), for the fields of one World."""
    return {name: Launcher(k) for name, k in COPIES.items()}
