"""Impact events made by hand for the tests of the hits' drawing: the engine's record (engine/events.py
``EVENT_DTYPE``), one per row."""

import numpy as np


def event_rows(rows, **columns) -> np.ndarray:
    """One event per dict of ``rows`` (its fields; the rest zero), then every event's ``columns`` (a value each, or
    one for all)."""
    from taichi_rocks.engine.events import EVENT_DTYPE

    ev = np.zeros(len(rows), EVENT_DTYPE)
    for k, row in enumerate(rows):
        for name, value in row.items():
            ev[k][name] = value
    for name, value in columns.items():
        ev[name] = value
    return ev
