"""Typed records: what crosses a boundary (the state a Simulation gives, its checkpoint, an exported frame) as a
dataclass whose every field has a unit and one line saying what it is (:func:`entry`).

A record is read by attribute (``st.positions``). It also reads as the dict it replaces: ``st["positions"]``,
``"orientations" in st``, ``np.savez(path, **st)``, ``st["positions"] = ...``, and :meth:`Record.as_dict` gives that dict (the ``.npz``
writers, and callers written before the records). A field that is None is absent from the dict: the optional
parts (tumbling's arrays, the rocks left out of ``state(rocks=False)``). ``tools/gen_docs.py`` writes every
record's table into docs/records.md from these declarations.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, field, fields

__all__ = ["Record", "entry", "describe"]


def entry(unit: str, doc: str, optional: bool = False):
    """A record's field: its ``unit`` ("" for a count or a name; "-" for a code or a flag) and one line ``doc``.
    ``optional``: it may be None (then absent from the dict)."""
    return field(default=None if optional else MISSING, metadata={"unit": unit, "doc": doc, "optional": optional})


class Record(Mapping):
    """The base of the records: a dataclass (keyword-only fields made with :func:`entry`) that reads like a dict
    of its fields that are not None."""

    _holder = None  # the name of a field that holds entries of the dict (a dict itself), not an entry
    _holders = ()  # more such fields, if any
    _extra_first = False  # the held entries come first in the dict

    def _held(self) -> tuple:
        """The fields that hold entries (``_holder`` and ``_holders``)."""
        return ((self._holder,) if self._holder else ()) + tuple(self._holders)

    def _extra(self) -> dict:
        """Entries beyond the dataclass's fields (held by the field ``_holder``), by their keys in the dict."""
        return getattr(self, self._holder) or {} if self._holder else {}

    def __getitem__(self, key: str):
        if key in self._held():
            raise KeyError(key)  # not an entry: the entries it holds are
        if key in _names(type(self)):
            value = getattr(self, key)
            if value is not None:
                return value
            raise KeyError(key)
        return self._extra()[key]

    def __setitem__(self, key: str, value) -> None:
        """Set a field (or an extra entry the record knows: a checkpoint's ``rock_<name>``), as a dict would."""
        if key in _names(type(self)):
            setattr(self, key, value)
        else:
            self._set_extra(key, value)

    def _set_extra(self, key: str, value) -> None:
        raise KeyError(f"{type(self).__name__} has no entry {key!r}")

    def __iter__(self):
        own = (n for n in _names(type(self)) if n not in self._held() and getattr(self, n) is not None)
        parts = (self._extra(), own) if self._extra_first else (own, self._extra())
        for part in parts:
            yield from part

    def __len__(self) -> int:
        return sum(1 for _ in self)

    __eq__ = object.__eq__  # arrays compare element-wise: no value equality for records
    __hash__ = object.__hash__

    def as_dict(self) -> dict:
        """The plain dict of this record (its fields that are not None, then its extra entries)."""
        return {k: self[k] for k in self}


def _names(cls) -> tuple:
    return tuple(f.name for f in fields(cls))


def describe(cls) -> list[tuple[str, str, str, bool]]:
    """(name, unit, what it is, optional) of each field of record class ``cls``, in order."""
    return [(f.name, f.metadata["unit"], f.metadata["doc"], f.metadata["optional"]) for f in fields(cls)]
