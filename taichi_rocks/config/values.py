"""The value types of scene files: strict numbers, names, ranges, colours, either-or unions, the settings every
table shares (:class:`_Table`: frozen, unknown keys refused, no inf or nan), and how a value is shown in a message
(:func:`_show`). The scene models (config/models.py, config/impacts.py) are built from them. No Taichi."""

from __future__ import annotations

import json
import warnings
from typing import Annotated, Any, Literal, Union

from pydantic import AfterValidator, BaseModel, ConfigDict, Discriminator, Field, Strict, Tag
from pydantic_core import PydanticCustomError

from .resolution import MIN_SIDE, SIDE_MULTIPLE


# ---------------------------------------------------------------------------------------------- value types
# Strict leaves: no bool-as-number, no number-as-string; ints are still accepted where floats are expected.
Float = Annotated[float, Strict()]
Int = Annotated[int, Strict()]
Bool = Annotated[bool, Strict()]
Name = Annotated[str, Strict(), Field(min_length=1)]
Vec2 = tuple[Float, Float]
Vec3 = tuple[Float, Float, Float]
SEED_MAX = 2**63 - 1  # run files and checkpoints store the seed as an int64


def _f(default: Any, description: str, **constraints) -> Any:
    return Field(default, description=description, **constraints)


def _ordered(pair: tuple[float, float]) -> tuple[float, float]:
    if pair[0] > pair[1]:
        raise ValueError(f"min must be <= max, got {_show(pair)}")
    return pair


def Range(**bounds) -> Any:
    """A [min, max] pair: each value within ``bounds`` (ge/gt/le), and min <= max."""
    item = Annotated[float, Strict(), Field(**bounds)]
    return Annotated[tuple[item, item], AfterValidator(_ordered)]


# An interrupt (Ctrl-C, SIGTERM) raised inside a discriminator while pydantic serialises a model is swallowed
# there (it becomes a serializer warning and the dump goes on: a sweep ignored Ctrl-C for a minute): the picker
# keeps it here, and dumped() raises it once the dump returns.
_CAUGHT: list = []


def _picker(pick_a):
    def pick(v):
        try:
            return "@a" if pick_a(v) else "@b"
        except BaseException as e:  # noqa: BLE001 - only an interrupt can come from pick_a
            _CAUGHT.append(e)
            raise
    return pick


def dumped(model: BaseModel, **kwargs) -> dict:
    """``model.model_dump(**kwargs)`` with an interrupt raised inside it re-raised (see :data:`_CAUGHT`)."""
    _CAUGHT.clear()  # one kept while validating went up by itself
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        data = model.model_dump(**kwargs)
    if _CAUGHT:
        raise _CAUGHT.pop()
    if any("discriminator" in str(w.message) for w in seen):  # raised before the picker's try could hold it
        raise KeyboardInterrupt
    return data


def _either(a: Any, b: Any, pick_a) -> Any:
    """A union that picks its member by the input's type, so a bad value gets one error, not one per member."""
    return Annotated[Union[Annotated[a, Tag("@a")], Annotated[b, Tag("@b")]], Discriminator(_picker(pick_a))]


def _is_str(v: Any) -> bool:
    return isinstance(v, str)


def _is_list(v: Any) -> bool:
    return isinstance(v, (list, tuple))


HEX_COLOR = r"^#[0-9a-fA-F]{6}$"
Unit = Annotated[float, Strict(), Field(ge=0, le=1)]
HexColor = Annotated[str, Strict(), Field(pattern=HEX_COLOR),
                     AfterValidator(lambda s: tuple(int(s[i:i + 2], 16) / 255 for i in (1, 3, 5)))]
Color = _either(HexColor, tuple[Unit, Unit, Unit], _is_str)   # always a tuple of 3 floats once validated
Speed = Annotated[float, Strict(), Field(ge=0)]
CellSize = _either(Literal["auto", "min_radius", "max_diameter"], Annotated[float, Strict(), Field(gt=0)], _is_str)
TableSize = _either(Literal["auto"], Annotated[int, Strict(), Field(ge=1)], _is_str)
Pixels = Annotated[int, Strict(), Field(ge=MIN_SIDE, multiple_of=SIDE_MULTIPLE)]


class _Table(BaseModel):
    """What every table of a scene file is: frozen, unknown keys refused, numbers finite."""
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


def _vehicle_name_schema(schema: dict) -> None:
    schema.pop("default", None)
    schema.pop("anyOf", None)
    schema.update(type="string", minLength=1)


def _follow(description: str) -> Any:
    return Field(None, description=description, json_schema_extra=_vehicle_name_schema)


def _raise_problems(problems: list[tuple[tuple, str]]) -> None:
    """Report several cross-field problems of one table at once; locations are relative to the table."""
    if problems:
        raise PydanticCustomError("scene_checks", "{problems}", {"problems": problems})


def _show(v: Any, room: int = 60) -> str:
    """A value as the user wrote it (TOML-ish), in the messages of scene and sweep files alike (a float as
    Python writes it: 10.0 is not the integer 10); a list is cut to ``room`` characters, looking only at what
    fits."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, (list, tuple)):
        text = "["
        for i, x in enumerate(v):
            if len(text) > room:
                break
            text += (", " if i else "") + _show(x, room - len(text) - 2 * bool(i))
        text += "]"
        return text if len(text) <= room else text[:max(room - 4, 0)] + " ...]"
    return "nothing" if v is None else str(v)
