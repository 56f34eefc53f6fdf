"""Counting Taichi compiles in a test: :func:`compiled` records the kernels that compile a new instance while it is
open (Taichi 1.7.4 compiles in ``Kernel.materialize``, once per kernel and key of template arguments; a key it
holds already returns at once)."""

import contextlib

from taichi.lang.kernel_impl import Kernel


@contextlib.contextmanager
def compiled():
    """A list, filled while the block runs, of the names of the kernels compiled in it (one per new instance)."""
    names: list = []
    original = Kernel.materialize

    def counting(self, key=None, args=None, arg_features=None):
        k = (self.func, 0, self.autodiff_mode) if key is None else key
        if k not in self.compiled_kernels:
            names.append(self.func.__name__)
        return original(self, key, args, arg_features)

    Kernel.materialize = counting
    try:
        yield names
    finally:
        Kernel.materialize = original
