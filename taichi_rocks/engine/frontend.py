"""Taichi 1.7.4's Python front end, made cheaper to run: the same kernels, compiled from the same source.

Every instantiation of a kernel (each new template argument: a World layout, a renderer's buffers), and every
``ti.func`` call inlined into it, makes Taichi read the function's source again (``inspect.getsourcelines``,
which tokenizes the file from the top) and format, for *each* AST node it visits, the message a compile error
at that node would print (``ASTTransformerContext.get_pos_info``: two ``textwrap`` passes per source line).
Measured with cProfile on tests/engine/test_robustness.py (645 kernel instantiations): 25 s of 89 s in the
front end, 12 s of them in ``get_pos_info`` and 3 s in ``getsourcelines``.

:func:`install` memoizes both, keyed by everything their results depend on:

* the source of a function object (its code object does not change while the process runs), and its file;
* a node's message by the file, the function, its first line, indentation, the node's kind and span and the text
  of the lines the message quotes;
* the preparation of the source at every inlining (``kernel_impl._get_tree_and_ctx``): each line through
  ``textwrap.fill`` and the joined text through ``textwrap.dedent`` (pure functions of their strings, so keyed by
  them). Only ``ast.parse`` runs each time: the transformer writes into the tree it gets. Measured by cProfile on
  convoy's second World (581 inlinings): the fills took 0.20 s, the file lookups 0.05 s, against 1.3 s for the
  whole front end.

The strings are the ones Taichi would have built (tests/engine/test_frontend.py compares them), so compile
errors read the same. Idempotent; undone by :func:`uninstall` (tests).

Decorating costs too: ``@ti.kernel`` and ``@ti.func`` ask whether they sit in a class body
(``kernel_impl._inside_class``) by reading the caller's line through ``inspect.getframeinfo``, whose source lookup
scans every loaded module (``inspect.getmodule``) on each of the package's ~190 decorators: about 0.2 s of every
process's import (the engine, the renderer and the bench, 0.70 -> 0.50 s, best of six). :func:`install_decorators`
(run when ``taichi_rocks.engine`` is imported, before any of its kernels is decorated) reads the same line
from ``linecache`` and matches Taichi's own patterns, so every decorator gets the answer Taichi's check gives
(tests/engine/test_frontend.py compares the two on module-level and class-body kernels).
"""

from __future__ import annotations

import functools
import linecache
import sys
import textwrap

from taichi.lang import kernel_impl
from taichi.lang.ast import ast_transformer_utils as _ast_utils

__all__ = ["install", "install_decorators", "uninstall", "installed"]

_BODY_KINDS = ("For", "While", "FunctionDef", "If")  # their message quotes only the lines before the body
_original = {"pos": _ast_utils.ASTTransformerContext.get_pos_info, "lines": kernel_impl.getsourcelines,
             "file": kernel_impl.getsourcefile, "textwrap": kernel_impl.textwrap,
             "inside_class": kernel_impl._inside_class}
_messages: dict = {}
_MAX_MESSAGES = 200_000  # a bound on the memo (a few tens of MB at most); cleared when full


@functools.lru_cache(maxsize=4096)
def _source_lines(func):
    return _original["lines"](func)


def _cached_source_lines(func):
    try:
        lines, start = _source_lines(func)
    except TypeError:  # unhashable: not a plain function
        return _original["lines"](func)
    return list(lines), start  # a copy: Taichi's caller may not change ours


@functools.lru_cache(maxsize=4096)
def _source_file(func):
    return _original["file"](func)


def _cached_source_file(func):
    try:
        return _source_file(func)
    except TypeError:  # unhashable: not a plain function
        return _original["file"](func)


class _Textwrap:
    """What ``kernel_impl._get_tree_and_ctx`` calls of :mod:`textwrap` (``fill`` of each source line, ``dedent`` of
    the function's text), memoized by their arguments; the results are textwrap's own strings."""

    fill = staticmethod(functools.lru_cache(maxsize=65536)(textwrap.fill))
    dedent = staticmethod(functools.lru_cache(maxsize=4096)(textwrap.dedent))


def _cached_pos_info(self, node):
    kind = node.__class__.__name__
    first, last = node.lineno, node.end_lineno
    if first != last and kind in _BODY_KINDS:
        last = max(node.body[0].lineno - 1, first)
    key = (self.file, self.func.func.__name__, self.lineno_offset, self.indent, kind, node.lineno,
           node.end_lineno, node.col_offset, node.end_col_offset, last, tuple(self.src[first - 1:last]))
    msg = _messages.get(key)
    if msg is None:
        if len(_messages) >= _MAX_MESSAGES:
            _messages.clear()
        msg = _messages[key] = _original["pos"](self, node)
    return msg


def _inside_class(level_of_class_stackframe):
    """Taichi's ``kernel_impl._inside_class``: does the caller's frame at that level execute a line that opens a
    class (``class X...`` or ``@...data_oriented``)? The line from ``linecache`` instead of ``getframeinfo``."""
    try:
        frame = sys._getframe(level_of_class_stackframe)  # called where Taichi's is: the same depth
        line = linecache.getline(frame.f_code.co_filename, frame.f_lineno).strip()
    except (ValueError, AttributeError):  # no frame that deep
        return False
    return any(p.match(line) for p in kernel_impl._KERNEL_CLASS_STACKFRAME_STMT_RES)


def install_decorators() -> None:
    """The cheaper class-body check for ``@ti.kernel`` / ``@ti.func`` (module docstring); idempotent."""
    kernel_impl._inside_class = _inside_class


def install() -> None:
    """Memoize the front end's source reads and error-position messages (see the module docstring)."""
    install_decorators()
    _ast_utils.ASTTransformerContext.get_pos_info = _cached_pos_info
    kernel_impl.getsourcelines = _cached_source_lines
    kernel_impl.getsourcefile = _cached_source_file
    kernel_impl.textwrap = _Textwrap


def uninstall() -> None:
    kernel_impl._inside_class = _original["inside_class"]
    _ast_utils.ASTTransformerContext.get_pos_info = _original["pos"]
    kernel_impl.getsourcelines = _original["lines"]
    kernel_impl.getsourcefile = _original["file"]
    kernel_impl.textwrap = _original["textwrap"]
    _messages.clear()
    _source_lines.cache_clear()
    _source_file.cache_clear()
    _Textwrap.fill.cache_clear()
    _Textwrap.dedent.cache_clear()


def installed() -> bool:
    return _ast_utils.ASTTransformerContext.get_pos_info is _cached_pos_info
