"""What a Simulation gives: its impact events, its rocks (``rock_arrays``, ``set_rocks``, ``state``), what changed
since the last read (``changes``: engine/changes.py) and what its optional effects hold: the readers of
engine/simulation.py's ``Simulation``, which takes them from this mixin (the class was one file of 660 lines).
They read the simulation's World, stepper, host state and plan, which ``Simulation.__init__`` makes."""

import numpy as np

from . import arguments, changes
from .events import EVENT_DTYPE
from .records import Changes, State
from .rockfields import ID
from .rocks import state_arrays
from .runtime import on_cpu

__all__ = ["Reads"]


class Reads:
    """The readers of a Simulation (module docstring)."""
    # ------------------------------------------------------------------------------------------ impacts
    def impacts(self) -> np.ndarray:
        """The impact events since the last call (all of them the first time), a structured array of
        engine/events.py ``EVENT_DTYPE`` in (step, rock, vehicle) order: time, step, vehicle, part (an index into
        ``motion.bodies.LABELS``), damage (into ``DAMAGE_CLASSES``), point and normal (the hit vehicle's frame),
        speed, normal_speed, normal_momentum, energy, radius, rock, thrower. A game loop calls it every frame.

        Returns:
            The events as a structured NumPy array (empty without ``[effects] impacts``). Events lost to a full
            buffer are counted in ``impacts_dropped``.
        """
        if self._impacts is None:
            return np.empty(0, EVENT_DTYPE)
        return self._impacts.take(self.time)

    @property
    def impacts_dropped(self) -> int:
        """Events lost so far: more between two drains than the device buffer holds ([impacts] capacity), or more
        than the host keeps waiting for ``impacts()`` (engine/impact_pass.py KEEP)."""
        return 0 if self._impacts is None else self._impacts.dropped

    def effect_arrays(self) -> dict:
        """What the optional effects that run ([effects], config/effects/) hold now, by effect name: dust's
        "positions" (K, 3) world m and "opacity" (K,) in (0, 1]. Empty when none runs.

        Returns:
            A dict of dicts of NumPy arrays.
        """
        return self._effects.arrays(self.origin)

    # ------------------------------------------------------------------------------------------ rocks
    def rock_arrays(self) -> dict:
        """Every rock's fields in id order, wherever the rock is (active list or tiles): every rock field the
        checkpoints carry (engine/rockfields.py) but the id: "pos" (local frame), "vel", "radius", "friction"
        (the World's precision), "phase", "hit_step" (splashing scenes: the step it was last launched at,
        -1 if never), and with tumbling (``tumble``) "spin" (rad/s) and "orient" (quaternions x, y, z, w).

        Returns:
            A dict of NumPy arrays, one row per rock (N rows), by rock id.
        """
        return self._stepper.rock_arrays()

    def set_rocks(self, ids, positions=None, velocities=None, phase=None, **fields) -> None:
        """Set rocks ``ids``' positions (world coordinates, m), velocities (m/s) and phases (engine/world.py
        codes), or any rock field by its name (``fields``; "pos" in the local frame), whichever are given, in
        either stepping mode (tests and probes put rocks in flight this way; O(N): every rock is reloaded).

        Args:
            ids: rock ids (an int or an array of them).
            positions: (len(ids), 3) world coordinates, m, or None.
            velocities: (len(ids), 3) m/s, or None.
            phase: phase codes (0 resting, 1 flying, 2 sliding), or None.
            **fields: any rock field of ``rock_arrays()`` by its name, one value per id or one for all.

        Raises:
            TypeError: ids that are not whole numbers, values that are not numbers, a field this simulation has not.
            ValueError: an id outside 0 .. N-1 or given twice, values of the wrong shape, or values no rock can
                have (not finite, a radius <= 0, a phase code that is none, ...; engine/arguments.py). Nothing is
                set then.
        """
        r = self.rock_arrays()
        given = {name: (name, value) for name, value in fields.items()}
        for name, field, value in (("positions", "pos", positions), ("velocities", "vel", velocities),
                                   ("phase", "phase", phase)):
            if value is not None:
                given[name] = (field, value)
        ids, values = arguments.rock_values(r, self.n_rocks, ids, given, self.origin, len(self.scene.vehicles))
        for field, v in values.items():
            r[field][ids] = v
        r[ID] = np.arange(self.n_rocks, dtype=np.int32)
        self._stepper.load(r)
        self._stepper.sync_drawn()

    def state(self, rocks: bool = True) -> dict:
        """The current state of every rock and vehicle, rocks in their original order (by rock id). It reads the
        whole bed from the device: for a check or a save, not for every frame of a game.

        Args:
            rocks: False leaves out the rocks' arrays (nothing is read from the device): the clock, the bed and
                the vehicles alone, for a reader that takes the rocks from ``changes()``.

        Returns:
            A :class:`~taichi_rocks.engine.records.State` (its fields and their units: docs/records.md): "time"
            (s), "step", "positions" (N, 3) float64 world m, "velocities" (N, 3) m/s, "radii" (N,) m, "phase" (N,)
            int8 (0 resting, 1 flying, 2 sliding), with tumbling "angular_velocities" and "orientations"
            (quaternions x, y, z, w), "bed_center" (3,), "vehicle_positions" (V, 3), "vehicle_headings" (V,) rad,
            "vehicle_names" (V,), "launches_total", "recycles_total". Read as attributes (``st.positions``) or
            as a dict (``st["positions"]``, ``st.as_dict()``).
        """
        poses = self._host.poses
        return State.with_rocks(
            state_arrays(self.world, self.rock_arrays(), self.origin) if rocks else {},
            time=self.time, step=self.step_count, bed_center=self.bed_center.copy(),
            vehicle_positions=np.array([p.position for p in poses]).reshape(-1, 3),
            vehicle_headings=np.array([p.heading for p in poses]),
            vehicle_names=np.array(self.fleet.names),
            launches_total=self.launches_total, recycles_total=self.recycles_total)

    def changes(self, velocities: bool = False) -> dict:
        """The rocks whose drawn state changed since the previous call (every rock the first time, and after
        ``restore`` or ``set_rocks``), one row per rock, in no particular order.

        Args:
            velocities: also give each row's velocity ("velocities", m/s, as ``state()``), read from the rocks
                that move (the active list: O(rocks in it); every rock with full stepping).

        Returns:
            A :class:`~taichi_rocks.engine.records.Changes`, arrays with one row per rock: "ids" (int32), "positions" (float64, world coordinates: the
            numbers ``state()`` gives), "phase" (int8) and, when the simulation tumbles, "orientations"
            (quaternions x, y, z, w, as ``rock_arrays()["orient"]``). Applied to a mirror of the bed
            (``mirror[ids] = positions``), the rows reproduce ``state()`` exactly at every call.

        Its cost follows the rows it returns, not the bed (engine/changes.py). Needs ``track_changes`` (the
        default). Example::

            sim = Simulation.from_scene("scenes/convoy.toml")
            for f in range(600):
                sim.advance_to(f / 60)
                rows = sim.changes()
                positions[rows["ids"]] = rows["positions"]
        """
        if not self.plan.drawn:
            if self.n_rocks:
                raise RuntimeError("changes() needs a Simulation made with track_changes=True")
            return self._rows(np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 4)))
        w = self.world
        if not on_cpu():  # a device: the count, then exactly its rows back to the host
            k = int(changes.listed_count(w))
            ints = np.empty((k, 2), np.int32)
            reals = np.empty((k, 7 if self.plan.spin else 3), w.np_real())
            if k:
                changes.gather(w, k, ints, reals)
            return self._rows(ints[:, 0], ints[:, 1], reals[:, :3], reals[:, 3:], velocities)
        buf = self._changes_buf  # the CPU: one launch writing into this array in place
        k = int(self._gather(w, buf))
        if k > len(buf):
            buf = self._changes_buf = np.empty((max(k, 2 * len(buf)), buf.shape[1]))
            self._gather(w, buf)
        return self._rows(buf[:k, 0], buf[:k, 1], buf[:k, 2:5], buf[:k, 5:9], velocities)

    def _rows(self, ids, phase, local, orient, velocities: bool = False) -> Changes:
        ids = ids.astype(np.int32)
        origin, positions = self.origin, np.empty((len(ids), 3))
        for j in range(3):  # a column at a time: NumPy broadcasts (k, 3) + (3,) row by row, 3x slower here
            np.add(local[:, j], origin[j], out=positions[:, j], dtype=np.float64)
        return Changes(ids=ids, positions=positions, phase=phase.astype(np.int8),
                       orientations=orient.astype(self.world.np_real()) if self.plan.spin else None,
                       velocities=self._stepper.velocities_of(ids) if velocities else None)
