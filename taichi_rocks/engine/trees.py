"""SNode trees of one element size each, for every field the engine allocates (World, event buffers).

Taichi's SPIR-V backends (Vulkan) pack the fields of a tree end to end with no alignment padding; a tree per
element size keeps every offset a multiple of that size (see :class:`_Trees`).
"""

import numpy as np
import taichi as ti
from taichi.lang.util import to_numpy_type

__all__ = ["_Trees"]


class _Trees:
    """Allocates fields in SNode trees of one element size each (a tree per size: 4-byte, 8-byte, ...).

    Why not all in one tree: Taichi's SPIR-V backends (Vulkan) pack the fields of a tree end to end, sorted
    by size, with no alignment padding, and index a 64-bit element at byte offset o as element o >> 3. A
    64-bit field landing at 4 mod 8 (after fields of an odd number of 32-bit words) is thus read and
    written 4 bytes too low, over its neighbour, silently (Taichi 1.7.4; the LLVM backends, CPU and CUDA,
    align their layouts). The i64 launch counter did: in minimal.toml's layout it shared 8 bytes with the
    last ``ray_cell_count`` entry, so on Vulkan launches_total read that ray's cell count plus the step's
    launches, and each launch bumped the count. In a tree whose fields all have one element size every
    offset is a multiple of that size."""

    def __init__(self):
        self._builders: dict[int, ti.FieldsBuilder] = {}

    def _place(self, f, dtype, shape):
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        size = np.dtype(to_numpy_type(dtype)).itemsize
        if size not in self._builders:
            self._builders[size] = ti.FieldsBuilder()
        fb = self._builders[size]
        fb.dense(ti.axes(*range(len(shape))), shape).place(f)
        return f

    def field(self, dtype, shape):
        """A scalar field of a Taichi ``dtype`` over ``shape`` (fields outside a World's layout: test buffers)."""
        return self._place(ti.field(dtype), dtype, shape)

    def place(self, spec, real):
        """The field of a :class:`FieldSpec` (``real``: the World's Taichi precision)."""
        dtype = real if spec.dtype == "real" else {"i32": ti.i32, "i64": ti.i64, "f64": ti.f64}[spec.dtype]
        f = ti.field(dtype) if spec.n == 1 else ti.Vector.field(spec.n, dtype)
        return self._place(f, dtype, spec.shape)

    def finalize(self) -> None:
        for fb in self._builders.values():
            fb.finalize()
