"""Scene problems in the house's words: a pydantic error becomes ``key.path: what was expected, got X`` lines,
with the close match of an unknown key or value. No Taichi."""

from __future__ import annotations

import difflib
import re
from typing import Any

from .models import Scene, _TABLES, _TAGS
from .resolution import SIDE_MULTIPLE
from .values import _is_list, _show


def _num(x: Any) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


def _unknown(what: str, value: Any, choices: list[str], list_all: bool = True) -> str:
    msg = f"unknown {what} {_show(value)}"
    close = difflib.get_close_matches(value, choices, n=1) if isinstance(value, str) else []
    if close:
        msg += f', did you mean "{close[0]}"?'
    if list_all or not close:
        msg += " (expected one of " + ", ".join(f'"{c}"' for c in choices) + ")"
    return msg


def _choices(expected: str) -> list[str]:
    return re.findall(r"'([^']*)'", expected)


_SIMPLE = {   # pydantic error type -> what was expected
    "float_type": "expected a number", "float_parsing": "expected a number",
    "int_type": "expected an integer", "int_parsing": "expected an integer", "int_from_float": "expected an integer",
    "bool_type": "expected true or false", "bool_parsing": "expected true or false",
    "string_type": "expected a string", "string_too_short": "must not be empty",
    "model_type": "expected a table", "model_attributes_type": "expected a table", "dict_type": "expected a table",
    "tuple_type": "expected a list", "list_type": "expected a list",
    "finite_number": "must be finite",
    "greater_than": "must be > {gt}", "greater_than_equal": "must be >= {ge}",
    "less_than": "must be < {lt}", "less_than_equal": "must be <= {le}",
    "multiple_of": "must be a multiple of {multiple_of}",
    "too_short": "expected at least {min_length} items", "too_long": "expected at most {max_length} items",
    "string_pattern_mismatch": 'expected a "#rrggbb" colour',
}


def _messages(err: dict) -> list[tuple[tuple, str]]:
    """One pydantic error as (location, human message) pairs; [] for errors that only echo another one."""
    kind, loc, ctx, value = err["type"], tuple(err["loc"]), err.get("ctx") or {}, err.get("input")
    got = f", got {_show(value)}"
    if kind == "scene_checks":
        return [(loc + tuple(sub), msg) for sub, msg in ctx["problems"]]
    if kind == "too_short" and _is_list(value) and len(value) >= ctx["min_length"]:
        return []   # pydantic adds this after an item failed; the item's own error says what is wrong
    if loc == ("vehicle",) and kind in ("missing", "too_short", "tuple_type"):
        return [(loc, "at least one [[vehicle]] table is required" + (got if kind == "tuple_type" else ""))]
    if loc == ("camera", "shot") and kind == "tuple_type":
        written = "[camera.shot], a single table" if isinstance(value, dict) else _show(value)
        return [(loc, f"expected a list of [[camera.shot]] tables (double brackets), got {written}")]
    if kind == "extra_forbidden":
        parent = next((x for x in reversed(loc[:-1]) if x in _TABLES), None)
        model = _TABLES.get(parent, Scene)
        keys = [f.alias or k for k, f in model.model_fields.items()]
        return [(loc, _unknown("key", loc[-1], keys, list_all=False))]
    if kind == "missing":
        if isinstance(loc[-1], int):
            return [(loc[:-1], f"too few items{got}")]
        return [(loc, "required key is missing")]
    if kind == "literal_error":
        choices = _choices(ctx["expected"])
        if isinstance(value, str):
            return [(loc, _unknown("value", value, choices))]
        return [(loc, "expected one of " + ", ".join(f'"{c}"' for c in choices) + got)]
    if kind == "union_tag_invalid":
        key = ctx["discriminator"].strip("'")
        return [(loc + (key,), _unknown("value", ctx["tag"], _choices(ctx["expected_tags"])))]
    if kind == "multiple_of" and ctx.get("multiple_of") == SIDE_MULTIPLE:
        return [(loc, "must be even" + got)]
    if kind in _SIMPLE:
        return [(loc, _SIMPLE[kind].format(**{k: _num(v) for k, v in ctx.items()}) + got)]
    if kind == "value_error":   # raised by our own validators, already in the house style
        return [(loc, err["msg"].removeprefix("Value error, "))]
    return [(loc, err["msg"][:1].lower() + err["msg"][1:] + got)]


def _key_path(loc: tuple) -> str:
    out = ""
    for item in loc:
        if isinstance(item, int):
            out += f"[{item}]"
        elif item not in _TAGS:
            out += ("." if out else "") + str(item)
    return out


def _line(source: str, loc: tuple, msg: str) -> str:
    path = _key_path(loc)
    return f"{source}: {path}: {msg}" if path else f"{source}: {msg}"
