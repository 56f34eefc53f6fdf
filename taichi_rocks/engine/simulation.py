"""The simulation: which passes run (from the scene's [effects]), the step and the clock.

One step of length dt:
  1. vehicles: poses at t + dt on the host; the bed centre follows ``bed.follow``; tire rays computed;
  2. rock pass (one fused kernel over the rocks; it takes the rays as an argument): flight -> recycle ->
     count for the hash;
  3. hash build: prefix sum over the table, scatter (and every ``reorder_every`` steps the rocks are
     re-sorted in memory by slot, which keeps the next steps' scattered writes local);
  4. tire pass: ray cells, candidate rocks, segment-sphere test, launch.
Passes nobody asked for are neither compiled nor called, and their fields are not allocated: no splashing
tire -> no hash table, no tire pass and no flight (only launched rocks ever leave the ground). The kernels
(engine/kernels.py) read which passes run from the Plan; the set-up (initial rocks, hash sizes, parameters)
is engine/setup.py.
Coasting: once every vehicle that matters has stopped for good, no tire can launch and the bed stands
still; the rocks are then independent and any number of steps runs as one ``coast_pass`` launch,
bit-identical to stepping (``Simulation.coast = False`` turns it off).
Lookahead: the host side of a step (poses, tires, ray rows) is computed ``lookahead`` steps at a time
(engine/lookahead.py), the same bits as step by step (``Simulation.lookahead = 0`` computes it per step).
Coordinates: kernels work in a local frame, world = origin + local. With ``origin = "floating"`` the origin
is anchor + shift: the anchor is the point the followed path is computed from (its first waypoint, where the
bed starts; a circle's centre), exact as the scene gives it; the shift moves in whole multiples of
ORIGIN_SNAP (exact in f32) to stay within ORIGIN_RANGE of the bed. All the kernels get (bed centre and its
move, tire rays, initial rocks) is computed relative to the anchor (``Pose.from_anchor``,
``Fleet.rear_tires(relative=True)``), never as a difference of world coordinates: the same scene moved
anywhere runs on the same bits (up to the rounding of the moved waypoints themselves), so f32 keeps
sub-millimetre precision and the same motion relative to the bed at any distance. ``origin = "world"``:
anchor and shift are 0 (world coordinates in the kernels).
"""


import math

import numpy as np
import taichi as ti

from . import active, hashgrid, tires
from ..config.plan import Plan
from ..config.scene import load_scene, scene_with
from ..motion.vehicles import Fleet
from .lookahead import Lookahead, local_rays, ray_rows, reach
from .kernels import (coast_pass, copy_field, gather_vec, hash_and_tires, health, identity_entries, rock_pass,
                      shift_origin, switches)
from .runtime import init_taichi
from .setup import hash_sizing, initial_rocks, scene_params
from .timing import NO_TIMER
from .world import RAY_FIELDS, IPar, Par, World, acquire, next_prime

__all__ = ["ORIGIN_RANGE", "ORIGIN_SNAP", "HealthError", "Simulation", "shift_origin"]

ORIGIN_SNAP = 64.0  # m: the origin moves from its anchor in whole multiples of this, so a shift is exact in f32
ORIGIN_RANGE = 128.0  # m: the origin moves when the bed centre is farther than this from it
LOOKAHEAD = 64  # at most this many steps have their host side computed at once (engine/lookahead.py)


def _snapped(xy: np.ndarray) -> np.ndarray:
    """The origin nearest to ``xy`` (XY, m): whole multiples of ORIGIN_SNAP."""
    return np.round(xy / ORIGIN_SNAP) * ORIGIN_SNAP


class HealthError(RuntimeError):
    """The runtime guard found a rock in an impossible state."""


class Simulation:
    """A rock bed following a vehicle, with splashing rear tires. See the module docstring."""

    @classmethod
    def from_scene(cls, path, arch: str = "cpu", seed=None, timer=NO_TIMER) -> "Simulation":
        return cls(load_scene(path), arch=arch, seed=seed, timer=timer)

    def __init__(self, scene, arch: str = "cpu", seed=None, timer=NO_TIMER):
        self.arch = init_taichi(arch)
        self.timer = timer  # the timing hook (engine/timing.py): PassTimer() times every pass of a step
        if seed is not None:
            scene = scene_with(scene, {"seed": int(seed)})
        self.scene = scene
        self.real = ti.f64 if scene.sim.precision == "f64" else ti.f32
        self.n_rocks = int(scene.bed.rocks)
        self.dt = float(scene.sim.dt)
        self.fleet = Fleet(scene)
        self.follow = scene.vehicle_index(scene.bed.follow)
        self.plan = plan = Plan.from_scene(scene)
        self.cell_size = plan.cell_size
        self._switches = switches(plan)  # what each kernel reads from the plan (engine/kernels.py)
        rocks = initial_rocks(scene)
        self.world = self._allocate(rocks.radius)
        self._start_clock()
        self._par, ipar = scene_params(scene, plan, self._sizing, ground_z=scene.world.ground_z - self.origin[2])
        self.world.set_params(self._par, ipar)
        self.world.load_rocks(rocks.resting_positions(self._local_centre(), scene.bed.radius,
                                                      self._par[Par.GROUND_Z]), rocks.radius, rocks.friction)
        self._tires_prev = self.fleet.rear_tires(self._poses, relative=True)
        self._upload_rays(self._tires_prev, self._tires_prev)
        self.last_launches = 0
        self._check_all = True  # active stepping: the next step tests every rim tile's rocks
        if plan.active:
            self._settle_all()
        elif plan.splash:
            self._initial_sort()
        # coasting: once these vehicles stop for good, steps run as one launch per call (False: always step)
        self.coast = True
        self._no_rays = np.zeros((1, RAY_FIELDS))
        self.steps_coasted = 0
        self._matter = sorted({self.follow, *(self.fleet.splashing if plan.splash else ())})
        # the host side of the coming steps (poses, tires, ray rows) computed this many at a time (0: per step)
        self.lookahead = LOOKAHEAD
        self._ahead = Lookahead()

    def _allocate(self, radius: np.ndarray) -> World:
        """The World of this scene's layout (a released one from the pool if there is one), sized for the
        rocks' radii ``radius``; sets the hash sizes (``_sizing``, ``table_size``)."""
        p = self.plan
        n_tires = 2 * len(self.fleet.splashing) if p.splash else 0
        self._sizing = s = hash_sizing(self.scene, p, radius, n_tires)
        self.table_size = s.table
        ray_len = max((v.tire_radius for v in self.scene.vehicles), default=1.0)
        return acquire(self, self.n_rocks, self.real, hash_table=s.table, hash_entries=s.entries, n_tires=n_tires,
                       substeps=p.substeps, ray_capacity=hashgrid.ray_capacity(ray_len, self.cell_size),
                       reorder=p.reorder_every > 0, tiles=s.tiles, tile_size=s.tile, store=self._store_layout())

    def _store_layout(self):
        """Active stepping's tile store (engine/active.py) as the World's layout argument, or None."""
        if not self.plan.active:
            return None
        st = active.store_sizing(self.n_rocks, self.scene.bed.radius)
        return (st.tile, st.grid, st.capacity, self.plan.recycle)

    def _tile_shift(self) -> np.ndarray:
        """The floating origin's shift in tiles (whole numbers, float64), for the store's keys."""
        return self._shift / self.world.store_tile

    def _settle_all(self) -> None:
        """Active stepping: every rock is in the active list (just loaded); the resting ones go to the tiles."""
        w = self.world
        w.ipar[IPar.N_ROCKS] = self.n_rocks
        active.settle(w, self._tile_shift())
        self._check_all = True
        self._fit_table()

    def _fit_table(self) -> None:
        """Active stepping with an "auto" table: the hash's slots in use follow the active list (a prime about
        1.5 times its length, at least 1024, at most the table allocated); a different table size changes which
        rocks share a slot, never which ones a tire finds."""
        if self.plan.splash and self.scene.sim.hash.table_size == "auto":
            want = next_prime(max(1024, int(1.5 * self.active_count)))
            self.world.ipar[IPar.TABLE] = min(want, self.table_size)

    @property
    def active_count(self) -> int:
        """Rocks in the active list (active stepping; all rocks with "full" stepping)."""
        return int(self.world.ipar[IPar.N_ROCKS])

    def _start_clock(self) -> None:
        """Time 0: the vehicles' poses, the bed under the followed vehicle, facing its heading, and the
        origin. Floating: the anchor is where the followed path is computed from (its first waypoint: the
        bed's start), the shift the bed's offset from it rounded to ORIGIN_SNAP (0 for waypoints); "world":
        both 0."""
        self.step_count = 0
        self.time = 0.0
        floating = self.scene.sim.origin == "floating"
        self.anchor = np.zeros(3)
        if floating:
            self.anchor[:2] = self.fleet.reference_point(self.follow)
        self.fleet.anchor = self.anchor[:2].copy()
        self._poses = poses = self.fleet.poses(0.0)
        c = poses[self.follow]
        self.bed_center = np.array([c.position[0], c.position[1], self.scene.world.ground_z])
        self._bed_rel = c.rel[:2].copy()  # bed centre - anchor, never from world coordinates
        self._set_shift(_snapped(self._bed_rel) if floating else np.zeros(2))
        self._lead = np.array([math.cos(c.heading), math.sin(c.heading)])

    def _set_shift(self, shift) -> None:
        """Put the floating origin at anchor + shift (shift: whole multiples of ORIGIN_SNAP, or 0)."""
        self._shift = np.array(shift, dtype=np.float64)
        self.origin = self.anchor.copy()
        self.origin[:2] += self._shift

    # ------------------------------------------------------------------------------------------------
    @property
    def launches_total(self) -> int:
        return int(self.world.launches[None])

    @property
    def recycles_total(self) -> int:
        """Rocks moved to the bed's leading edge so far (each time a rock leaves the bed it counts once)."""
        return int(self.world.recycles[None])

    def vehicle_poses(self):
        return self._poses

    def _upload_rays(self, prev, cur, dt: float = 0.0) -> None:
        if self.world.n_tires:
            self.world.ray.from_numpy(self._ray_data(prev, cur, dt).astype(self.world.np_real()))

    def _ray_data(self, prev, cur, dt: float = 0.0) -> np.ndarray:
        """The rays of every splashing rear tire, float64 (T, RAY_FIELDS) in the World.ray layout, in the
        kernels' frame; ``prev`` and ``cur`` are relative to the anchor (``Fleet.rear_tires(relative=True)``)."""
        if self.world.n_tires == 0:
            return np.zeros((1, RAY_FIELDS))
        return self._local_rays(*ray_rows(prev, cur, dt, self._bed_rel, reach(self.scene)))

    def _local_rays(self, rows, far) -> np.ndarray:
        """Ray rows relative to the anchor (engine/lookahead.py ``ray_rows``) in the kernels' frame now; the
        tires far from the bed parked high above it."""
        if rows is None:
            return np.zeros((1, RAY_FIELDS))
        lc = self._local_centre()
        park = np.array([lc[0], lc[1], self.bed_center[2] - self.origin[2] + 1000.0])
        return local_rays(rows, far, self._shift, park)

    def _local_centre(self) -> np.ndarray:
        """The bed centre (XY) in the kernels' local frame, from anchor-relative coordinates only."""
        return self._bed_rel - self._shift

    def _grid_origin(self) -> np.ndarray:
        """The corner of the tire mask's tiles (XY, local frame): the mask is centred on the bed."""
        return self._local_centre() - self._sizing.grid_half

    def _initial_sort(self) -> None:
        """Sort the rocks in memory by slot once at the start (scope "all"), and clear the counts."""
        w, p = self.world, self.plan
        hashgrid.clear_counts(w)
        if p.reorder_every:
            g = self._grid_origin()
            hashgrid.count_all(w, p.center, float(g[0]), float(g[1]))
            hashgrid.inclusive_scan(w)
            hashgrid.scatter(w, p.center)
            self._reorder()
            hashgrid.clear_counts(w)

    def _hash_and_tires(self) -> int:
        """Everything after the rock pass. The entry capacity is an upper bound of the (rock, cell) pairs
        by construction (engine/setup.py), so the scatter cannot lose a rock."""
        w, p = self.world, self.plan
        timer = self.timer
        if p.reorder_every and self.step_count % p.reorder_every == 0:
            with timer("hash scan"):
                hashgrid.inclusive_scan(w)
            with timer("hash scatter"):
                hashgrid.scatter(w, p.center)
            with timer("reorder"):
                self._reorder()
            if not p.swept:
                with timer("trace rays"):
                    tires.trace_rays(w)
            with timer("tire pass"):
                launched = tires.tire_pass(w, self._switches["hash_and_tires"], self.step_count)
            with timer("hash clear"):
                hashgrid.clear_counts(w)
            return launched
        with timer("hash + tires"):
            return hash_and_tires(w, self._switches["hash_and_tires"], self.step_count)

    def _reorder(self) -> None:
        """Re-sort the rocks in memory by slot (entries is then the identity)."""
        w = self.world
        for f, tmp in ((w.pos, w.tmp_vec), (w.vel, w.tmp_vec), (w.radius, w.tmp_real),
                       (w.friction, w.tmp_real), (w.rock_id, w.tmp_int), (w.phase, w.tmp_int),
                       (w.hit_step, w.tmp_int), (w.slot, w.tmp_int)):
            gather_vec(w, f, tmp)
            copy_field(w, tmp, f)
        identity_entries(w)

    def step(self, n: int = 1) -> None:
        n = int(n)
        while n > 0:
            if self._can_coast():
                self._coast(n)
                return
            self._step()
            n -= 1

    def advance_to(self, t: float) -> None:
        """Step to exactly time ``t``: whole steps of dt, then one shorter step if dt does not divide the
        interval (so frame f is the state at f / fps for any fps)."""
        tol = 1e-9 * max(1.0, abs(t))
        while self.time + self.dt <= t + tol:
            if self._can_coast():
                k, clock = 0, self.time
                while clock + self.dt <= t + tol:  # the same whole steps as the loop, same rounding
                    clock += self.dt
                    k += 1
                self._coast(k)
                break
            self._step()
        if t - self.time > tol:
            self._step(t - self.time)

    def _can_coast(self) -> bool:
        """True when the coming steps can run as one ``coast`` launch: every vehicle that matters (the one
        the bed follows, the splashing ones) has stopped for good, so the bed stands and no tire launches."""
        p = self.plan
        return bool(self.coast and self.n_rocks and (p.flight or p.recycle)
                    and self.time >= self.fleet.still_after(self._matter))

    def _coast(self, n: int) -> None:
        step0 = self.step_count
        for _ in range(n):  # the clock advances exactly as n calls of _step() advance it
            self.time += self.dt
        self.step_count += n
        self.steps_coasted += n
        with self.timer("coast"):
            for s in range(0, n, 1 << 30):
                coast_pass(self.world, self._switches["coast_pass"], min(n - s, 1 << 30), self.dt,
                           self._local_centre(), self._lead, step0 + s)
        if self.plan.active:
            with self.timer("settle"):
                active.settle(self.world, self._tile_shift())
        self._poses = self.fleet.poses(self.time)
        self._tires_prev = self.fleet.rear_tires(self._poses, relative=True)
        self.last_launches = 0

    def _step(self, dt=None) -> None:
        p = self.plan
        dt = self.dt if dt is None else float(dt)
        self.step_count += 1
        self.time += dt
        # the step's poses, tires and rays: from the lookahead's batch (the same bits), or computed here
        ahead = self._ahead.take(self, dt) if self.lookahead and dt == self.dt else None
        poses = self.fleet.poses(self.time) if ahead is None else ahead.poses
        move = self._follow(poses[self.follow])
        self._keep_origin_near()
        if ahead is None:
            tires_now = self.fleet.rear_tires(poses, relative=True)
            rays = self._ray_data(self._tires_prev, tires_now, dt) if p.splash else self._no_rays
        else:
            tires_now = ahead.tires
            rays = self._local_rays(ahead.rows, ahead.far) if p.splash else self._no_rays
        self._tires_prev = tires_now
        self._poses = poses
        if p.active and (p.flight or p.recycle or p.splash):
            frame = active.frame_rows(self._local_centre(), move, self._lead, self._grid_origin(), self._shift,
                                      self.world.store_tile)
            plan = self._switches["active_step"]
            with self.timer("active step"):
                active.active_step(self.world, plan, rays, frame, dt, self.step_count, int(self._check_all))
                self.last_launches = active.active_finish(self.world, self._switches["active_finish"], frame,
                                                          self.step_count)
            self._check_all = False
            if self.step_count % 32 == 0:
                self._fit_table()
            return
        if self.n_rocks and (p.flight or p.recycle or p.splash):
            with self.timer("rock pass"):
                frame = np.array([self._local_centre(), move, self._lead, self._grid_origin()])  # CENTRE..GRID
                rock_pass(self.world, self._switches["rock_pass"], rays, frame, dt, self.step_count)
        if p.splash:
            self.last_launches = self._hash_and_tires()

    def _follow(self, pose) -> np.ndarray:
        """Move the bed under the followed vehicle (``pose``) and turn its leading edge to the vehicle's
        travel (kept while the vehicle stands); return the bed's move (XY), anchor-relative: the same bits
        wherever the scene is."""
        c, rel = pose.position, pose.rel[:2]
        move = rel - self._bed_rel
        self.bed_center = np.array([c[0], c[1], self.bed_center[2]])
        self._bed_rel = rel.copy()
        lead = pose.velocity[:2]
        if np.hypot(*lead) > 1e-9:
            self._lead = lead / np.hypot(*lead)
        return move

    def _keep_origin_near(self) -> None:
        """With ``origin = "floating"``: once the bed centre is farther than ORIGIN_RANGE from the origin,
        move the shift to the snapped point nearest it and the rocks' local positions by the (exact, whole
        multiples of ORIGIN_SNAP) difference."""
        rel = self._bed_rel
        if self.scene.sim.origin == "floating" and np.max(np.abs(rel - self._shift)) > ORIGIN_RANGE:
            new = _snapped(rel)
            if self.n_rocks:
                with self.timer("origin shift"):
                    shift_origin(self.world, new - self._shift)
                    if self.plan.active:
                        active.shift_store(self.world, new - self._shift)
            self._set_shift(new)

    # ------------------------------------------------------------------------------------------------
    def rock_arrays(self) -> dict:
        """Every rock's fields in id order, wherever the rock is (active list or tiles): "pos" (local frame),
        "vel", "radius", "friction" (the World's precision), "phase", and "hit_step" (splashing scenes: the step
        it was last launched at, -1 if never)."""
        w, n = self.world, self.n_rocks
        m = self.active_count if self.plan.active else n
        ids = w.rock_id.to_numpy()[:m]
        names = ["pos", "vel", "radius", "friction", "phase"] + (["hit_step"] if self.plan.splash else [])
        out = {}
        for k in names:
            a = getattr(w, k).to_numpy()[:m]
            full = np.empty((n,) + a.shape[1:], a.dtype)
            full[ids] = a
            out[k] = full
        if self.plan.active and m < n:
            counts = w.ts_count.to_numpy()
            cap = w.store_capacity
            taken = (np.arange(cap)[None, :] < counts[:, None]).ravel()
            sid = w.ts_id.to_numpy()[taken]
            out["pos"][sid] = w.ts_pos.to_numpy()[taken]
            out["radius"][sid] = w.ts_radius.to_numpy()[taken]
            out["friction"][sid] = w.ts_friction.to_numpy()[taken]
            out["vel"][sid] = 0.0
            out["phase"][sid] = 0
            if "hit_step" in out:
                out["hit_step"][sid] = w.ts_hit.to_numpy()[taken]
        return out

    def set_rocks(self, ids, positions=None, velocities=None, phase=None) -> None:
        """Set rocks ``ids``' positions (world coordinates, m), velocities (m/s) and phases (engine/world.py
        codes), whichever are given, in either stepping mode (tests and probes put rocks in flight this way;
        O(N): every rock is reloaded)."""
        r = self.rock_arrays()
        ids = np.atleast_1d(np.asarray(ids, np.int64))
        if positions is not None:
            r["pos"][ids] = (np.asarray(positions, np.float64).reshape(len(ids), 3) - self.origin).astype(r["pos"].dtype)
        if velocities is not None:
            r["vel"][ids] = np.asarray(velocities, np.float64).reshape(len(ids), 3).astype(r["vel"].dtype)
        if phase is not None:
            r["phase"][ids] = phase
        data = {f"rock_{k}": v for k, v in r.items()}
        data["rock_rock_id"] = np.arange(self.n_rocks, dtype=np.int32)
        self._load_rocks(data)

    def state(self) -> dict:
        """The current state as NumPy arrays, rocks in their original order (by rock id)."""
        r = self.rock_arrays()
        poses = self._poses
        return {
            "time": self.time,
            "step": self.step_count,
            "positions": r["pos"].astype(np.float64) + self.origin,
            "velocities": r["vel"],
            "radii": r["radius"].astype(np.float64),
            "phase": r["phase"].astype(np.int8),
            "bed_center": self.bed_center.copy(),
            "vehicle_positions": np.array([p.position for p in poses]).reshape(-1, 3),
            "vehicle_headings": np.array([p.heading for p in poses]),
            "vehicle_names": np.array(self.fleet.names),
            "launches_total": self.launches_total,
            "recycles_total": self.recycles_total,
        }

    # ------------------------------------------------------------------------------------------------
    def checkpoint(self) -> dict:
        """Everything needed to continue bit-identically: every rock's fields in id order (the same for both
        stepping modes: a checkpoint of one restores into the other), clock, origin."""
        r = self.rock_arrays()
        data = {f"rock_{k}": r[k] for k in ("pos", "vel", "radius", "friction", "phase")}
        data["rock_rock_id"] = np.arange(max(self.n_rocks, 1), dtype=np.int32)[:self.n_rocks]
        if self.plan.splash:
            data["rock_hit_step"] = r["hit_step"]
        data.update(step_count=np.int64(self.step_count), time=np.float64(self.time), origin=self.origin.copy(),
                    origin_anchor=self.anchor.copy(), origin_shift=self._shift.copy(),
                    bed_center=self.bed_center.copy(), bed_rel=self._bed_rel.copy(), lead=self._lead.copy(),
                    launches=np.int64(self.launches_total), recycles=np.int64(self.recycles_total),
                    scene=np.array(self.scene.name), seed=np.int64(self.scene.seed), rocks=np.int64(self.n_rocks))
        return data

    _ROCK_FIELDS = ("pos", "vel", "radius", "friction", "rock_id", "phase")

    def _load_rocks(self, data: dict) -> None:
        """Every rock from ``data`` (checkpoint layout): into the rock arrays, and with active stepping from
        there into the emptied tiles (the resting ones)."""
        if self.plan.active:
            self.world.ts_count.fill(0)
        self._load_rock_fields(data)
        if self.plan.active:
            self._settle_all()

    def _load_rock_fields(self, data: dict) -> None:
        """The checkpoint's rock fields into the rock arrays (padded to the World's capacity)."""
        w = self.world
        for k in self._ROCK_FIELDS + (("hit_step",) if self.plan.splash else ()):
            a = np.asarray(data[f"rock_{k}"])
            f = getattr(w, k)
            if len(a) < f.shape[0]:  # checkpoints hold n rocks; an empty World has one padding slot
                pad = np.zeros((f.shape[0] - len(a),) + a.shape[1:], a.dtype)
                if k == "radius":
                    pad[:] = 1
                a = np.concatenate([a, pad])
            f.from_numpy(a.astype(f.to_numpy().dtype if k in ("pos", "vel", "radius", "friction") else np.int32))

    def restore(self, data: dict) -> None:
        """Continue from a checkpoint() of a simulation of the same scene (either stepping mode)."""
        self._ahead.clear()
        if int(data["rocks"]) != self.n_rocks or int(data["seed"]) != self.scene.seed:
            raise ValueError("checkpoint does not belong to this scene (rock count or seed differ)")
        w = self.world
        self.step_count = int(data["step_count"])
        self.time = float(data["time"])
        self.bed_center = np.array(data["bed_center"], dtype=np.float64)
        if "origin_shift" in data:
            self.anchor = np.array(data["origin_anchor"], dtype=np.float64)
            self.fleet.anchor = self.anchor[:2].copy()
            self._bed_rel = np.array(data["bed_rel"], dtype=np.float64)
            self._set_shift(data["origin_shift"])
        else:  # saved before the origin had an anchor: this simulation's anchor, the saved origin
            self._bed_rel = self.bed_center[:2] - self.anchor[:2]
            self._set_shift(np.asarray(data["origin"], dtype=np.float64)[:2] - self.anchor[:2])
        self._lead = np.array(data["lead"], dtype=np.float64)
        w.launches[None] = int(data["launches"])
        w.recycles[None] = int(data["recycles"]) if "recycles" in data else 0
        par = self._par.copy()
        par[Par.GROUND_Z] = self.scene.world.ground_z - self.origin[2]
        w.par.from_numpy(par.astype(w.np_real()))
        self._load_rocks(data)  # after the origin: the tiles are keyed by its shift
        self._poses = self.fleet.poses(self.time)
        self._tires_prev = self.fleet.rear_tires(self._poses, relative=True)
        if self.plan.splash:
            self._upload_rays(self._tires_prev, self._tires_prev)

    def check_health(self) -> None:
        """The runtime guard: raise HealthError naming the step, the rock and the value when a rock is
        non-finite, outside the bed (with recycling) or below the ground (with ground contact)."""
        if not self.n_rocks:
            return
        w = self.world
        lc = self._local_centre()
        # 1 mm, or a few float spacings at the bed's distance from the kernel origin ("world" origin, f32)
        eps = float(np.finfo(w.np_real()).eps)
        slack = 1e-3 + 8.0 * eps * (float(np.max(np.abs(lc))) + self.scene.bed.radius)
        health(w, self._switches["health"], lc, slack)
        if self.plan.active:
            active.store_health(w, lc, slack, self._tile_shift())
        out = w.health_out.to_numpy()
        if not out[:3].any():
            return
        kind = int(np.flatnonzero(out[:3])[0])
        i = int(out[3 + kind])
        if i < 0:  # a rock in the tiles (engine/active.py: store_health)
            j = -1 - i
            rid, p, v = int(w.ts_id[j]), w.ts_pos[j].to_numpy(), np.zeros(3)
        else:
            rid, p, v = int(w.rock_id[i]), w.pos[i].to_numpy(), w.vel[i].to_numpy()
        p = p.astype(np.float64) + self.origin
        what = ("non-finite state", "outside the bed", "below the ground")[kind]
        raise HealthError(
            f"step {self.step_count} (t = {self.time:.4f} s): {int(out[kind])} rock(s) {what}; "
            f"first: rock {rid} at position {np.array2string(p, precision=4)} m, velocity "
            f"{np.array2string(v, precision=4)} m/s")

    def tire_rays(self) -> np.ndarray:
        """The rear tires' rays (centre, bottom) now, world coordinates, (T, 2, 3)."""
        t = self._tires_prev
        return np.stack([t.center, t.bottom], axis=1) + self.anchor if len(t.spin) else np.zeros((0, 2, 3))

    def queried_cells(self) -> np.ndarray:
        w = self.world
        if not self.plan.splash or self.plan.swept:
            return np.zeros((0, 3), np.int64)
        counts = w.ray_cell_count.to_numpy()
        cells = w.ray_cells.to_numpy()
        return np.concatenate([cells[r, :counts[r]] for r in range(len(counts))]).astype(np.int64)
