"""Taichi 1.7.4's Python front end, made cheaper to run: the same kernels, compiled from the same source.

Every instantiation of a kernel (each new template argument: a World layout, a renderer's buffers), and every
``ti.func`` call inlined into it, makes Taichi read the function's source again (``inspect.getsourcelines``,
which tokenizes the file from the top) and format, for *each* AST node it visits, the message a compile error
at that node would print (``ASTTransformerContext.get_pos_info``: two ``textwrap`` passes per source line).
Measured with cProfile on tests/engine/test_robustness.py (645 kernel instantiations): 25 s of 89 s in the
front end, 12 s of them in ``get_pos_info`` and 3 s in ``getsourcelines``.

:func:`install` memoizes both, keyed by everything their results depend on:

* the source of a function object (its code object does not change while the process runs);
* a node's message by the file, the function, its first line, indentation, the node's kind and span and the text
  of the lines the message quotes.

The strings are the ones Taichi would have built (tests/engine/test_frontend.py compares them), so compile
errors read the same. Idempotent; undone by :func:`uninstall` (tests).
"""

from __future__ import annotations

import functools

from taichi.lang import kernel_impl
from taichi.lang.ast import ast_transformer_utils as _ast_utils

__all__ = ["install", "uninstall", "installed"]

_BODY_KINDS = ("For", "While", "FunctionDef", "If")  # their message quotes only the lines before the body
_original = {"pos": _ast_utils.ASTTransformerContext.get_pos_info, "lines": kernel_impl.getsourcelines}
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


def install() -> None:
    """Memoize the front end's source reads and error-position messages (see the module docstring)."""
    _ast_utils.ASTTransformerContext.get_pos_info = _cached_pos_info
    kernel_impl.getsourcelines = _cached_source_lines


def uninstall() -> None:
    _ast_utils.ASTTransformerContext.get_pos_info = _original["pos"]
    kernel_impl.getsourcelines = _original["lines"]
    _messages.clear()
    _source_lines.cache_clear()


def installed() -> bool:
    return _ast_utils.ASTTransformerContext.get_pos_info is _cached_pos_info
