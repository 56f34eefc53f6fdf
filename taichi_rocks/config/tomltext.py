"""TOML text to plain data, every failure as one ``line L, column C: what was wrong`` message.

tomllib reads arrays and inline tables recursively, so a value nested a few hundred levels deep
(``a = [[[[...]]]]``) ends in a RecursionError. :func:`nesting_overflow` finds such a value first, by a scan of
the text that does not recurse, and :func:`loads` reports it with its line like any other syntax error.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Optional, Union

try:
    import tomllib
except ModuleNotFoundError:  # Python < 3.11
    import tomli as tomllib

__all__ = ["MAX_NESTING", "TomlTextError", "loads", "nesting_overflow", "read_toml"]

MAX_NESTING = 32   # arrays and inline tables inside one another; a scene needs 5 at most


class TomlTextError(ValueError):
    """Text that cannot be read as TOML; the message reads ``line L, column C: what`` where the place is known."""


# what the scan stops at, and where each kind of string ends (TOML 1.0: a closing triple quote may be
# followed by one or two quotes that belong to the string; a one-line string also ends at the line's end)
_TOKEN = re.compile(r'"""|\'\'\'|["\'#\[\]{}=\n]')
_STRING_END = {
    '"': re.compile(r'(?:[^"\\\n]|\\.)*"?'),
    "'": re.compile(r"[^'\n]*'?"),
    '"""': re.compile(r'(?:[^"\\]|\\.|"(?!""))*"""(?:"{0,2})', re.S),
    "'''": re.compile(r"(?:[^']|'(?!''))*'''(?:'{0,2})", re.S),
}


def _place(text: str, pos: int) -> str:
    """``line L, column C`` of a character offset, counted as tomllib counts them."""
    line, column = text.count("\n", 0, pos) + 1, pos - text.rfind("\n", 0, pos)
    return f"line {line}, column {column}"


def nesting_overflow(text: str, limit: int = MAX_NESTING) -> Optional[tuple[int, str]]:
    """(offset, key) of the first ``[`` or ``{`` opened more than ``limit`` levels deep, outside strings and
    comments, or None. ``key`` is the key of that top-level statement as written ("" if none). Does not recurse;
    table headers (``[a]``, ``[[a]]``) count as the one or two levels they open and close."""
    depth, pos, statement, key = 0, 0, 0, ""
    while m := _TOKEN.search(text, pos):
        token, pos = m[0], m.end()
        if token in _STRING_END:
            end = _STRING_END[token].match(text, pos)
            pos = end.end() if end else len(text)
        elif token == "#":
            pos = len(text) if (eol := text.find("\n", pos)) < 0 else eol
        elif depth:
            if token in "[{":
                depth += 1
                if depth > limit:
                    return m.start(), key
            elif token in "]}":
                depth -= 1
        elif token == "\n":
            statement, key = pos, ""
        elif token == "=":
            key = text[statement:m.start()].strip()
        elif token in "[{":
            depth = 1
    return None


def loads(text: str) -> dict:
    """Parse TOML text; raise TomlTextError (one line) for anything that is not valid or is nested too deeply."""
    overflow = nesting_overflow(text)
    if overflow:
        pos, key = overflow
        raise TomlTextError(f"{_place(text, pos)}: arrays and inline tables nested deeper than {MAX_NESTING} "
                            f"levels" + (f" in the value of {key}" if key else ""))
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        msg = str(e)
        m = re.search(r"\s*\(at line (\d+), column (\d+)\)$", msg)
        if m:
            raise TomlTextError(f"line {m[1]}, column {m[2]}: {msg[:m.start()]}") from None
        msg = re.sub(r"\s*\(at end of document\)$", "", msg)
        raise TomlTextError(f"{_place(text, len(text))}: {msg}") from None
    except RecursionError:   # the scan above keeps values shallower than this needs, on any ordinary stack
        raise TomlTextError("nested too deeply to read") from None


def read_toml(path: Union[str, os.PathLike], what: str, error) -> dict:
    """The data of the TOML file ``path`` (a scene, a sweep: ``what``), read one way for every kind: UTF-8, a
    byte-order mark (Windows editors write one; TOML has none) dropped. Raises ``error([line])`` (a SceneError
    class), the line starting with the file: cannot be read, not UTF-8, not TOML."""
    source = str(path)
    try:
        text = Path(path).read_bytes().decode("utf-8").removeprefix("\ufeff")
    except OSError as e:
        raise error([f"{source}: cannot read {what}: {e.strerror or e}"]) from None
    except UnicodeDecodeError as e:
        raise error([f"{source}: cannot read {what}: not UTF-8 text ({e.reason} at byte {e.start})"]) from None
    try:
        return loads(text)
    except TomlTextError as e:
        raise error([f"{source}: {e}"]) from None
