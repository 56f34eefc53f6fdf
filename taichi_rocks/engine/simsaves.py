"""A Simulation's checkpoints (``checkpoint``, ``restore``: continue bit-identically, in this or another
Simulation of the scene), its runtime guard (``check_health``) and what the renderer's overlays ask of its tires
(``tire_rays``, ``queried_cells``): the part of engine/simulation.py's ``Simulation`` that saves and checks,
which it takes from this mixin."""

import numpy as np

from . import arguments, drives, rocks
from .records import Checkpoint
from .setup import initial_orientations
from .world import Par

__all__ = ["HealthError", "Saves"]


class HealthError(RuntimeError):
    """The runtime guard found a rock in an impossible state."""


class Saves:
    """Checkpoints, the runtime guard and the tires' overlays of a Simulation (module docstring)."""
    # ------------------------------------------------------------------------------------------ checkpoints
    def checkpoint(self) -> dict:
        """Everything needed to continue bit-identically: every rock's fields in id order (the same for both
        stepping modes: a checkpoint of one restores into the other), clock, origin. The events recorded so far
        are drained first (a checkpoint holds none: a restore records the steps after it again).

        Returns:
            A :class:`~taichi_rocks.engine.records.Checkpoint` for ``restore``: NumPy arrays and scalars that
            read as a dict (``np.savez(path, **cp)`` stores it; ``restore`` takes it or the file's ``np.load``).
        """
        if self._impacts is not None:
            self._impacts.drain(self.time)
        return Checkpoint(rock_fields=rocks.checkpoint_fields(self.world, self.rock_arrays(), self.n_rocks),
                          **self._host.saved(), launches=np.int64(self.launches_total),
                          recycles=np.int64(self.recycles_total), impacts_dropped=np.int64(self.impacts_dropped),
                          scene=np.array(self.scene.name), seed=np.int64(self.scene.seed),
                          rocks=np.int64(self.n_rocks), effects=self._effects.saved() or None,
                          drives=drives.saved(self.fleet, self.time))

    def restore(self, data: dict) -> None:
        """Continue from a checkpoint() of a simulation of the same scene (either stepping mode; a checkpoint
        without orientations, of a simulation without tumbling, restores them as they were at the start).

        Args:
            data: what ``checkpoint()`` returned (or its ``np.load``).

        Raises:
            ValueError: the checkpoint belongs to another scene (rock count or seed differ), or a key is missing or
                holds what no checkpoint of this simulation can hold (the message names it). Nothing changes then.
        """
        data = self._checked(data)
        self._host_side.ahead.clear()
        w, h = self.world, self._host
        h.load(data)
        w.launches[None] = int(data["launches"])
        w.recycles[None] = int(data["recycles"]) if "recycles" in data else 0
        par = self._par.copy()
        par[Par.GROUND_Z] = self.scene.world.ground_z - self.origin[2]
        w.set_params(par)
        self._stepper.load(rocks.from_checkpoint(w, data))  # after the origin: the tiles are keyed by its shift
        self._stepper.sync_drawn()
        drives.load(self.fleet, data, h.time)  # the live vehicles' keyframes, before their poses are asked
        self._host_side.resume(h)
        if self.plan.splash:
            self._put_rays()
        if self._impacts is not None:  # the events of the steps after the checkpoint come again
            self._impacts.restore(h.step_count, h.time, int(data.get("impacts_dropped", 0)))
        self._effects.load(data, h)  # a checkpoint saved before the effects were in them: they start again, empty

    def _checked(self, data) -> dict:
        """Checkpoint ``data`` as a dict that fits this simulation (engine/arguments.py), or ValueError."""
        orient = (lambda: initial_orientations(self.scene.seed, self.n_rocks)) if self.plan.spin else None
        data = arguments.checkpoint_data(data, self.n_rocks, self.scene.seed, orient)
        problem = arguments.host_problem(data) or self._effects.problem(data)
        if problem:
            raise ValueError(problem)
        arguments.checked_rock_fields(rocks.saved_fields(self.world), data, self.n_rocks, len(self.scene.vehicles))
        return data

    # ------------------------------------------------------------------------------------------ guard, probes
    def check_health(self) -> None:
        """The runtime guard: raise HealthError naming the step, the rock and the value when a rock is
        non-finite, outside the bed (with recycling) or below the ground (with ground contact).

        Raises:
            HealthError: a rock in an impossible state (the message is one line).
        """
        if not self.n_rocks:
            return
        lc = self._host.local_centre()
        # 1 mm, or a few float spacings at the bed's distance from the kernel origin ("world" origin, f32)
        eps = float(np.finfo(self.world.np_real()).eps)
        slack = 1e-3 + 8.0 * eps * (float(np.max(np.abs(lc))) + self.scene.bed.radius)
        out = self._stepper.health(lc, slack)
        if not out[:3].any():
            return
        kind = int(np.flatnonzero(out[:3])[0])
        rid, p, v = self._stepper.locate(int(out[3 + kind]))
        p = p.astype(np.float64) + self.origin
        what = ("non-finite state", "outside the bed", "below the ground")[kind]
        raise HealthError(
            f"step {self.step_count} (t = {self.time:.4f} s): {int(out[kind])} rock(s) {what}; "
            f"first: rock {rid} at position {np.array2string(p, precision=4)} m, velocity "
            f"{np.array2string(v, precision=4)} m/s")

    def tire_rays(self) -> np.ndarray:
        """The rear tires' rays now.

        Returns:
            (T, 2, 3) float64: each splashing rear tire's centre and bottom, world coordinates, m.
        """
        t = self._host.tires_prev
        return np.stack([t.center, t.bottom], axis=1) + self.anchor if len(t.spin) else np.zeros((0, 2, 3))

    def queried_cells(self) -> np.ndarray:
        """The hash cells the tire rays visited in the last step (the renderer's overlay).

        Returns:
            (K, 3) int64 cell indices; empty without splashing tires or with swept detection.
        """
        w = self.world
        if not self.plan.splash or self.plan.swept:
            return np.zeros((0, 3), np.int64)
        counts = w.ray_cell_count.to_numpy()
        cells = w.ray_cells.to_numpy()
        return np.concatenate([cells[r, :counts[r]] for r in range(len(counts))]).astype(np.int64)
