"""The stepping modes (``[sim] stepping``), each a stepper behind one interface: what a step, coasting, loading
rocks, moving the origin and the runtime guard do to the World's fields.

* :class:`FullStepper` ("full", the reference): every rock every step. A step is the fused rock pass
  (engine/kernels.py ``rock_pass``: flight -> recycle -> count for the hash) and, with splashing tires, the hash
  build and the tire pass in one launch (``hash_and_tires``); every ``reorder_every`` steps the rocks are
  re-sorted in memory by slot between the scatter and the tire pass (the next steps' scattered writes stay
  local).
* :class:`ActiveStepper` ("active", engine/active.py): resting rocks wait in ground tiles; a step is one
  launch over the active list (``active_step``: tiles classified and gathered, the rock pass, hash, tires,
  settling, compaction) whose arguments are three integers: the step's inputs are on the device, uploaded
  once per lookahead batch (engine/stepdata.py); the hash's slots in use fitted to the list.

Both get the same host input (engine/host.py ``StepInput``) and give the same results; only where the rocks
are in memory differs, which ``rock_arrays`` (id order) hides. Coasting (every vehicle that matters stopped
for good) is one ``coast_pass`` launch in both.
"""

from __future__ import annotations

import numpy as np

from . import active, changes, hashgrid, origin, rocks, stepdata, tilestore, tires
from .impact_pass import time_row
from .kernels import coast_pass, hash_and_tires, health, reorder_rocks, rock_pass, switches
from .launcher import Launcher
from .rockfields import ID
from .runtime import current_arch, on_cpu, threads_in_use
from .variant import VariantChoice, loops_from_env
from .world import LAUNCHED, IPar, next_prime

__all__ = ["Stepper", "FullStepper", "ActiveStepper", "stepper_for", "TABLE_EVERY", "TABLE_MIN", "TABLE_LOAD"]

# active stepping fits the hash's slots in use to the active list every TABLE_EVERY steps (and after the first): a
# prime about TABLE_LOAD times its length, at least TABLE_MIN (ActiveStepper._fit)
TABLE_EVERY, TABLE_MIN, TABLE_LOAD = 32, 1024, 1.5


class Stepper:
    """The interface (and what both modes share). ``world``: the fields; ``plan``: the Plan; ``sizing``: the
    HashSizing; ``host``: the
    simulation's HostState (engine/host.py; the frame the tiles are keyed by); ``table_auto``: the hash table
    is sized "auto"; ``timer``: the timing hook (engine/timing.py), kept current by the Simulation."""

    mode = ""

    def __init__(self, world, plan, sizing, host, table_auto: bool, timer):
        self.world, self.plan, self.sizing, self.host = world, plan, sizing, host
        self.n_rocks = int(world.n)
        self.table_auto = bool(table_auto)
        self.timer = timer
        p = plan
        self.moves = bool(self.n_rocks and (p.flight or p.recycle or p.splash))  # a step runs kernels
        # the step's variants (engine/loops.py): what each kernel reads of the plan, serial or parallel loops,
        # chosen from the backend, the CPU pool and the work (engine/variant.py)
        self._variants = {False: switches(plan, False), True: switches(plan, True)}
        self.variant = VariantChoice(on_cpu(), threads_in_use() if on_cpu() else 0, loops_from_env())
        # the kernels a step launches, each at the cost of its launch alone on the CPU (engine/launcher.py)
        self._launch = {k.__name__: Launcher(k) for k in (rock_pass, hash_and_tires, changes.note_listed,
                                                           active.active_step, active.active_finish,
                                                           stepdata.load_batch)}

    @property
    def switches(self) -> dict:
        """Kernel name -> the Switches its launch takes now (engine/kernels.py), in the current variant."""
        return self._variants[self.variant.serial]

    def set_loops(self, mode: str) -> None:
        """The step's variant from now on: "auto" (the engine's choice), "serial" or "parallel"."""
        self.variant = VariantChoice(self.variant.on_cpu, self.variant.threads, mode)
        self.variant.update(self.work())

    def work(self) -> int:
        """The rocks a step's loops visit now (a read of the device with active stepping)."""
        return self.active_count

    # -------------------------------------------------------------------------------------------- rocks
    def start(self) -> None:
        """The initial rocks were just written into the rock arrays (every rock, id order)."""

    def load(self, arrays: dict) -> None:
        """Every rock from ``arrays`` (saved field -> id-ordered array, the id included): restore, set_rocks."""
        rocks.write(self.world, arrays, self.n_rocks)

    def rock_arrays(self) -> dict:
        """Every rock's saved fields but the id, in id order, wherever the rock is."""
        return rocks.in_id_order(self.n_rocks, rocks.read_listed(self.world, self.n_rocks))

    def velocities_of(self, ids: np.ndarray) -> np.ndarray:
        """The velocities of rocks ``ids`` as ``rock_arrays()`` gives them: from the rock arrays where a rock is
        listed there (O(their count)), else the rest value (a rock in the tiles rests)."""
        w = self.world
        vel = next(f for f in w.rocks if f.name == "vel")
        out = np.full((len(ids), 3), vel.rest, w.np_real())
        if len(ids):
            listed = rocks.read_listed(w, self.active_count)
            order = np.argsort(listed[ID], kind="stable")
            have = listed[ID][order]
            at = np.minimum(np.searchsorted(have, ids), max(len(have) - 1, 0))
            hit = (have[at] == ids) if len(have) else np.zeros(len(ids), bool)
            out[hit] = listed["vel"][order[at[hit]]]
        return out

    @property
    def active_count(self) -> int:
        """Rocks in the World's rock arrays (the active list; every rock with full stepping)."""
        return int(self.world.ipar[IPar.N_ROCKS])

    def tile_shift(self) -> np.ndarray:
        """The floating origin's shift in tiles of the store (whole numbers, float64; zeros without tiles)."""
        return np.zeros(2)

    def grid_origin(self, centre: np.ndarray) -> np.ndarray:
        """The corner of the tire mask's tiles (XY, local frame; full stepping): the mask is centred on the bed."""
        return centre - self.sizing.grid_half

    def with_bodies(self, frame: np.ndarray, s) -> np.ndarray:
        """The step's frame rows and, with impacts, the impacts pass's rows after them: the step's start time
        relative to the event buffer's reference time, the poses of the vehicles hit (engine/impact_pass.py)."""
        if s.bodies is None:
            return frame
        t0 = self.host.time - s.dt - self.world.events.t_ref
        return np.concatenate([frame, time_row(t0), s.bodies])

    def put_rays(self, rays: np.ndarray) -> None:
        """The tires' rays (World.ray layout, kernels' frame) into the World, outside a step."""
        if self.world.n_tires:
            self.world.ray.from_numpy(rays.astype(self.world.np_real()))

    # -------------------------------------------------------------------------------------------- steps
    def step(self, s) -> bool:
        """One step's kernels for the host input ``s`` (engine/host.py StepInput); return whether a tire pass
        ran (its launch count stays on the device: :meth:`launched`)."""
        raise NotImplementedError

    def launched(self) -> int:
        """Rocks launched by the last tire pass (a read of the device)."""
        return int(self.world.tire_counts[LAUNCHED])

    def coast(self, n: int, dt: float, centre: np.ndarray, lead: np.ndarray, step0: int) -> None:
        """``n`` steps of a bed standing still with no tire launching, as one launch (engine/kernels.py)."""
        with self.timer("coast"):
            for s in range(0, n, 1 << 30):
                coast_pass(self.world, self.switches["coast_pass"], min(n - s, 1 << 30), dt, centre, lead,
                           step0 + s)
        self.note_all()

    def note_all(self) -> None:
        """What changed for changes() (engine/changes.py), over every rock of the rock arrays: full stepping's
        steps and coasts (active stepping notes inside its settling loop instead)."""
        if self.world.drawn and not self.world.stored:
            with self.timer("note changes"):
                self._launch["note_listed"](self.world, self.switches["note_listed"])

    def sync_drawn(self) -> None:
        """Every rock was just loaded into the rock arrays: the mirror of changes() from them, every rock listed."""
        if self.world.drawn:
            changes.sync_drawn(self.world)

    def shift_origin(self, d: np.ndarray) -> None:
        """The local frame's origin moved by ``d`` (XY, whole multiples of ORIGIN_SNAP): every rock moves by -d, in
        the rock arrays, the tiles and the mirror of changes() (engine/origin.py); the host's origin has already
        moved by ``d``."""
        with self.timer("origin shift"):
            h = self.host
            before = h.anchor[:2] + (h.shift - np.asarray(d, np.float64))  # as HostState.set_shift adds them
            origin.put_move(self.world, d, before, h.origin[:2])
            origin.move_origin(self.world, self.exact)

    @property
    def exact(self) -> bool:
        """The backend computes the mirror's float64 sums exactly (engine/origin.py ``move_origin``)."""
        return on_cpu() or current_arch() == "cuda"

    # -------------------------------------------------------------------------------------------- guard
    def health(self, centre: np.ndarray, slack: float):
        """The runtime guard's counts (engine/kernels.py ``health``): the World's ``health_out`` as NumPy."""
        health(self.world, self.switches["health"], centre, slack)
        return self.world.health_out.to_numpy()

    def locate(self, i: int):
        """Rock (id, local position, velocity) at index ``i`` of the guard's report."""
        w = self.world
        return int(w.rock_id[i]), np.asarray(w.pos[i]), np.asarray(w.vel[i])


class FullStepper(Stepper):
    """Every rock, every step (module docstring)."""

    mode = "full"

    def start(self) -> None:
        """With splashing tires: sort the rocks in memory by slot once (scope "all"), and clear the counts."""
        self.variant.update(self.n_rocks)  # every rock, every step
        if not self.plan.splash:
            return
        w, p = self.world, self.plan
        hashgrid.clear_counts(w)
        if p.reorder_every:
            g = self.grid_origin(self.host.local_centre())
            hashgrid.count_all(w, p.center, float(g[0]), float(g[1]))
            hashgrid.inclusive_scan(w)
            hashgrid.scatter(w, p.center)
            self.reorder()
            hashgrid.clear_counts(w)

    def reorder(self) -> None:
        """Re-sort the rocks in memory by slot (after a scatter; entries is then the identity)."""
        reorder_rocks(self.world)

    def step(self, s) -> bool:
        if self.moves:
            with self.timer("rock pass"):
                frame = np.array([s.centre, s.move, s.lead, self.grid_origin(s.centre)])  # kernels.CENTRE..GRID
                frame = self.with_bodies(frame, s)
                self._launch["rock_pass"](self.world, self.switches["rock_pass"], s.rays, frame, s.dt, s.step)
        if self.plan.splash:
            self._hash_and_tires(s.step)
        if self.moves:
            self.note_all()
        return self.plan.splash

    def _hash_and_tires(self, step: int) -> None:
        """Everything after the rock pass. The entry capacity is an upper bound of the (rock, cell) pairs by
        construction (engine/setup.py), so the scatter cannot lose a rock."""
        w, p, timer = self.world, self.plan, self.timer
        if p.reorder_every and step % p.reorder_every == 0:
            with timer("hash scan"):
                hashgrid.inclusive_scan(w)
            with timer("hash scatter"):
                hashgrid.scatter(w, p.center)
            with timer("reorder"):
                self.reorder()
            with timer("tire pass"):
                tires.tire_pass(w, self.switches["hash_and_tires"], step)
            with timer("hash clear"):
                hashgrid.clear_counts(w)
            return
        with timer("hash + tires"):
            self._launch["hash_and_tires"](w, self.switches["hash_and_tires"], step)


class ActiveStepper(Stepper):
    """Resting rocks in tiles, a step over the active list (module docstring, engine/active.py)."""

    mode = "active"

    def __init__(self, *args):
        super().__init__(*args)
        self.check_all = True  # the next step tests every rim tile's rocks (rocks were just loaded)
        self._on_device = None  # the Frames (engine/host.py) whose rows step_frame and step_rays hold
        self._t_ref = None  # the event buffer's reference time body_rows holds (engine/stepdata.py)

    def tile_shift(self) -> np.ndarray:
        return self.host.shift / self.world.store_tile

    def start(self) -> None:
        self._all_active()

    def load(self, arrays: dict) -> None:
        """Into the rock arrays, the tiles emptied: every rock active until the next step settles."""
        self.world.ts_count.fill(0)
        super().load(arrays)
        self._all_active()

    def _all_active(self) -> None:
        """Every rock is in the active list (just loaded). The next step takes them all through its rock pass
        and its finish settles the resting ones into the tiles (steps 5 and 6, as for rocks that land): full
        stepping's step of every rock, so the same bits, and no kernel of its own to compile with every World."""
        self.world.ipar[IPar.N_ROCKS] = self.n_rocks
        self.check_all = True
        self._fit(self.n_rocks)

    def _fit(self, active: int) -> None:
        """The coming steps fitted to the active list's length ``active``: the step's variant (engine/variant.py)
        and, with an "auto" table, the hash's slots in use (a prime about 1.5 times its length, at least 1024, at
        most the table allocated; a different table size changes which rocks share a slot, never which ones a
        tire finds)."""
        self.variant.update(active)
        if self.plan.splash and self.table_auto:
            want = next_prime(max(TABLE_MIN, int(TABLE_LOAD * active)))
            self.world.ipar[IPar.TABLE] = min(want, self.world.table_size)

    def rock_arrays(self) -> dict:
        w = self.world
        m = self.active_count
        listed = rocks.read_listed(w, m)
        if m == self.n_rocks:
            return rocks.in_id_order(self.n_rocks, listed)
        return rocks.in_id_order(self.n_rocks, listed, rocks.read_stored(w))

    def step(self, s) -> bool:
        if not self.moves:
            return False
        row = self._upload(s)
        if s.bodies is not None and self._t_ref != self.world.events.t_ref:  # changed by a drain or a reset
            self._t_ref = self.world.events.t_ref
            stepdata.put_t_ref(self.world, self._t_ref)
        with self.timer("active step"):
            self._launch["active_step"](self.world, self.switches["active_step"], row, s.step, int(self.check_all))
            self._launch["active_finish"](self.world, self.switches["active_finish"], row, s.step)
        if self.check_all or s.step % TABLE_EVERY == 0:  # and after the first step: the loaded rocks have settled
            self._fit(self.active_count)
        self.check_all = False
        return self.plan.splash

    def _upload(self, s) -> int:
        """The step's inputs on the device (engine/stepdata.py): its lookahead batch's rows, uploaded with the
        batch's first step, or this step alone into row 0 (with impacts: its start time and pose rows too);
        returns the step's row."""
        f = s.frames
        if f is not None and self._on_device is f:
            return s.row
        with self.timer("batch upload"):
            if f is None:
                start = None if s.bodies is None else np.array([self.host.time - s.dt])
                rows = (s.centre[None], s.move[None], s.lead[None], np.asarray(s.shift)[None], np.array([s.dt]),
                        s.rays[None] if self.world.n_tires else None, start,
                        None if s.bodies is None else s.bodies[None])
            else:
                rows = (f.local, f.move, f.lead, f.shift, np.full(len(f.local), f.dt), f.rays, f.start, f.bodies)
            centre, move, lead, shift, dt, rays, start, bodies = rows
            data, frame, poses = stepdata.batch_arrays(centre, move, lead, centre - self.sizing.grid_half, shift,
                                                       dt, self.world.store_tile, rays, start, bodies)
            self._launch["load_batch"](self.world, self.switches["load_batch"],
                                       stepdata.packed(self.world, data, frame, poses))
        self._on_device = f
        return 0 if f is None else s.row

    def coast(self, n: int, dt: float, centre: np.ndarray, lead: np.ndarray, step0: int) -> None:
        super().coast(n, dt, centre, lead, step0)
        with self.timer("settle"):
            active.settle(self.world, self.tile_shift())

    def health(self, centre: np.ndarray, slack: float):
        health(self.world, self.switches["health"], centre, slack)
        tilestore.store_health(self.world, centre, slack, self.tile_shift())
        return self.world.health_out.to_numpy()

    def locate(self, i: int):
        if i >= 0:
            return super().locate(i)
        j = -1 - i  # a rock in the tiles (engine/tilestore.py: store_health)
        w = self.world
        return int(w.ts_rock_id[j]), np.asarray(w.ts_pos[j]), np.zeros(3)


def stepper_for(plan):
    """The stepper class of a plan's stepping mode."""
    return ActiveStepper if plan.active else FullStepper
