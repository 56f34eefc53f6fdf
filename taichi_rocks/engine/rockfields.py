"""The per-rock quantities, declared once (no Taichi here: dtypes are names).

A :class:`RockField` says what a quantity is (name, dtype, components), where it lives (which stepping modes
hold it, under which Plan switch it exists, whether the tiles of active stepping store it) and how it travels
(what a rock coming out of a tile gets if the tiles do not store it, whether it moves with its rock and whether
checkpoints carry it). Everything that allocates, copies, saves or reports rocks is derived from
:data:`ROCK_FIELDS`:

* the World's rock arrays and the tile store's copies ``ts_<name>`` (engine/layout.py, engine/world.py);
* the copies between the active list and the tiles and within each (engine/active.py, ``ti.static`` loops);
* the re-sort of the rocks in memory (engine/steppers.py);
* initial rocks, checkpoints and restore, ``rock_arrays``, ``state`` and ``set_rocks`` (engine/rocks.py);
* the memory estimate (engine/layout.py).

Adding a quantity (a spin, a thrower's id) is one line below plus the physics that uses it.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["RESTING", "FLYING", "SLIDING", "RockField", "ROCK_FIELDS", "ID", "present", "DTYPES"]

# Rock phases (the values of the "phase" field).
RESTING, FLYING, SLIDING = 0, 1, 2

#: dtype names a rock field may have: "real" is the World's precision (f32 or f64)
DTYPES = ("real", "i32")

#: the field holding each rock's id: rock_arrays, checkpoints and state are in the order of its values
ID = "rock_id"


@dataclass(frozen=True)
class RockField:
    """One per-rock quantity (a field of ``n`` components per rock; 1: a scalar field)."""

    name: str
    dtype: str  # "real" | "i32"
    n: int = 1
    when: str = "always"  # the Plan switch it exists under ("always", or a Plan attribute such as "splash")
    modes: tuple = ("full", "active")  # stepping modes that hold it
    stored: bool = True  # the tiles keep it (as ``ts_<name>``); else a rock out of a tile gets ``rest``
    rest: float | int | None = None
    carried: bool = True  # moves with its rock (compaction, re-sort); False: scratch a pass rewrites before use
    saved: bool = True  # checkpoints and rock_arrays carry it
    initial: float | int | str = 0  # a new rock's value: a number, "id" (its id) or "given" (by the set-up)
    pad: float | int = 0  # the padding slot of an empty World
    state: str | None = None  # its key in Simulation.state(), if it is there
    state_dtype: str | None = None  # the NumPy dtype of that key (None: as the World holds it)
    local: bool = False  # a point in the kernels' local frame: state() and set_rocks() add / take the origin

    def __post_init__(self):
        if self.dtype not in DTYPES:
            raise ValueError(f"rock field {self.name}: dtype must be one of {DTYPES}, got {self.dtype!r}")
        if self.carried and not self.stored and self.rest is None:
            raise ValueError(f"rock field {self.name}: not stored by the tiles, so it needs a rest value")
        if self.carried and not self.stored and self.initial != self.rest:
            raise ValueError(f"rock field {self.name}: a new rock rests, so its initial value must be its rest value")
        if self.saved and not self.carried:
            raise ValueError(f"rock field {self.name}: a scratch field (not carried) cannot be saved")

    @property
    def store_name(self) -> str:
        """The tile store's copy of this field."""
        return "ts_" + self.name


ROCK_FIELDS = (
    RockField("pos", "real", 3, initial="given", state="positions", state_dtype="float64", local=True),
    RockField("vel", "real", 3, stored=False, rest=0.0, state="velocities"),
    RockField("radius", "real", initial="given", pad=1, state="radii", state_dtype="float64"),
    RockField("friction", "real", initial="given"),  # static friction coefficient against the tread
    RockField(ID, "i32", initial="id"),
    RockField("phase", "i32", stored=False, rest=RESTING, initial=RESTING, state="phase", state_dtype="int8"),
    RockField("hit_step", "i32", when="splash", initial=-1),  # the step it was last launched at (-1: never)
    RockField("slot", "i32", when="splash", stored=False, carried=False, saved=False),  # its hash slot (centre)
    # the vehicle whose tire launched it (engine/tires.py try_launch; -1: none): a resting rock has none
    RockField("thrower", "i32", when="impacts", stored=False, rest=-1, initial=-1, pad=-1),
    # tumbling (engine/tumble.py): angular velocity (rad/s, world axes; none at rest) and orientation (x, y, z, w)
    RockField("spin", "real", 3, when="spin", stored=False, rest=0.0, state="angular_velocities"),
    RockField("orient", "real", 4, when="spin", initial="given", state="orientations"),
)


def present(switches, mode: str, fields=None) -> tuple:
    """The rock fields a World of stepping ``mode`` ("full" | "active") holds: those of ``fields`` (default
    :data:`ROCK_FIELDS`) whose ``when`` is "always" or a true attribute of ``switches`` (a Plan, or anything
    with those attributes)."""
    fields = ROCK_FIELDS if fields is None else fields
    return tuple(f for f in fields if mode in f.modes and (f.when == "always" or bool(getattr(switches, f.when))))
