"""The rocks as NumPy arrays, both ways: every function here loops over the World's rock fields (the declaration
in engine/rockfields.py), so a new per-rock quantity needs nothing here.

* :func:`initial_arrays` - the rocks before the first step (the set-up gives the "given" fields);
* :func:`read_listed` / :func:`read_stored` - the rocks of the World's rock arrays (the active list with active
  stepping) and of the tile store, each as arrays in memory order plus their ids;
* :func:`in_id_order` - such pieces merged into one array per field in rock-id order (``rock_arrays``);
* :func:`write` - id-ordered arrays into the rock arrays, padded to the World's capacity (restore, set_rocks);
* :func:`checkpoint_fields` / :func:`from_checkpoint` - the rock part of a checkpoint (``rock_<name>`` keys);
* :func:`state_arrays` - the rock part of ``Simulation.state()``.
"""

from __future__ import annotations

import numpy as np

from .rockfields import ID

__all__ = ["initial_arrays", "read_listed", "read_stored", "in_id_order", "write", "checkpoint_fields",
           "from_checkpoint", "state_arrays", "saved_fields"]


def saved_fields(w) -> list:
    """The World's rock fields that checkpoints and rock_arrays carry (the id included)."""
    return [f for f in w.rocks if f.saved]


def initial_arrays(w, n: int, given: dict) -> dict:
    """Every saved rock field of ``w`` for rocks 0 .. n-1 before the first step, in id order: the fields the
    declaration marks "given" from ``given`` (name -> array of n), "id" the rock's id, the others their
    initial value."""
    out = {}
    for f in saved_fields(w):
        shape = (n,) + ((f.n,) if f.n > 1 else ())
        if f.initial == "given":
            a = np.asarray(given[f.name])[:n]
        elif f.initial == "id":
            a = np.arange(n)
        else:
            a = np.full(shape, f.initial)
        out[f.name] = np.asarray(a).reshape(shape).astype(w.np_dtype(f))
    return out


def read_listed(w, m: int) -> dict:
    """The saved rock fields of the first ``m`` entries of the World's rock arrays (memory order)."""
    return {f.name: getattr(w, f.name).read(0, m) for f in saved_fields(w)}


def read_stored(w) -> dict:
    """The saved rock fields of every rock in the tile store (active stepping), in store order: stored fields
    as the tiles hold them, the others at their rest value."""
    counts = w.ts_count.to_numpy()
    cap = w.store_capacity
    taken = (np.arange(cap)[None, :] < counts[:, None]).ravel()
    k = int(taken.sum())
    out = {}
    for f in saved_fields(w):
        if f.stored:
            out[f.name] = getattr(w, f.store_name).read(0, len(taken))[taken]
        else:
            out[f.name] = np.full((k,) + ((f.n,) if f.n > 1 else ()), f.rest, w.np_dtype(f))
    return out


def in_id_order(n: int, *pieces: dict) -> dict:
    """Pieces of rocks (read_listed, read_stored: together each rock once) as one array per saved field but
    the id, indexed by rock id."""
    out = {}
    for name in pieces[0]:
        if name == ID:
            continue
        a = pieces[0][name]
        full = np.empty((n,) + a.shape[1:], a.dtype)
        for p in pieces:
            full[p[ID]] = p[name]
        out[name] = full
    return out


def write(w, arrays: dict, n: int) -> None:
    """Rocks 0 .. n-1 (``arrays``: saved field name -> id-ordered array, the id included) into the World's rock
    arrays, each padded to the World's capacity with its field's padding value."""
    for f in saved_fields(w):
        field = getattr(w, f.name)
        cap = field.shape[0]
        a = np.asarray(arrays[f.name])[:n]
        if len(a) < cap:  # an empty World has one padding slot
            a = np.concatenate([a, np.full((cap - len(a),) + a.shape[1:], f.pad, a.dtype)])
        field.write(0, a.astype(w.np_dtype(f)))


def checkpoint_fields(w, rock_arrays: dict, n: int) -> dict:
    """The rock part of a checkpoint: every saved field by name (the id: 0 .. n-1); a checkpoint's dict names
    them ``rock_<name>`` (engine/records.py Checkpoint)."""
    return {f.name: np.arange(n, dtype=np.int32) if f.name == ID else rock_arrays[f.name] for f in saved_fields(w)}


def from_checkpoint(w, data: dict) -> dict:
    """The saved rock fields of a checkpoint (``rock_<name>``), by field name. A field with a rest value that
    the checkpoint lacks (saved by a simulation without it: a thrower's id before impacts) takes that value."""
    n = len(data[f"rock_{ID}"])
    out = {}
    for f in saved_fields(w):
        key = f"rock_{f.name}"
        if key not in data and f.rest is not None:
            out[f.name] = np.full((n,) + ((f.n,) if f.n > 1 else ()), f.rest, w.np_dtype(f))
        else:
            out[f.name] = np.asarray(data[key])
    return out


def state_arrays(w, rock_arrays: dict, origin: np.ndarray) -> dict:
    """The rock part of ``Simulation.state()``: each field with a ``state`` key, as its ``state_dtype``; points
    in the local frame (``local``) moved to world coordinates by ``origin``."""
    out = {}
    for f in w.rocks:
        if f.state is None:
            continue
        a = rock_arrays[f.name]
        a = a.astype(f.state_dtype) if f.state_dtype else a
        out[f.state] = a + origin if f.local else a
    return out
