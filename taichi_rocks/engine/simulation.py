"""The simulation: which passes run (from the scene's [effects]), the step and the clock.

One step of length dt:
  1. vehicles: poses at t + dt on the host; the bed centre follows ``bed.follow``; tire rays computed;
  2. rock pass (one fused kernel over the rocks; it takes the rays as an argument): flight -> recycle ->
     count for the hash;
  3. hash build: prefix sum over the table, scatter (and every ``reorder_every`` steps the rocks are
     re-sorted in memory by slot, which keeps the next steps' scattered writes local);
  4. tire pass: ray cells, candidate rocks, segment-sphere test, launch.
Passes nobody asked for are neither compiled nor called, and their fields are not allocated: no splashing
tire -> no hash table, no tire pass and no flight (only launched rocks ever leave the ground).
Coasting: once every vehicle that matters has stopped for good, no tire can launch and the bed stands
still; the rocks are then independent and any number of steps runs as one ``coast_pass`` launch,
bit-identical to stepping (``Simulation.coast = False`` turns it off).
Coordinates: kernels work in a local frame, world = origin + local; with ``origin = "floating"`` the
origin jumps (by multiples of 64 m) to stay near the bed, so f32 keeps sub-millimetre precision anywhere.
"""


import math
from pathlib import Path

import numpy as np
import taichi as ti

from . import hashgrid, patch, throw, tires
from .bed import outside_bed, recycle_to_leading_edge
from .flight import fly
from ..config.plan import Plan
from .runtime import init_taichi
from .setup import drag_coefficients
from .timing import NO_TIMER
from ..config.scene import load_scene, scene_with
from ..motion.vehicles import Fleet
from .world import ACTIVE, HALF_W, HULL, RAY_FIELDS, RESTING, IPar, Par, acquire, dilation_cells, next_prime

ORIGIN_SNAP = 64.0  # m: origin moves in whole multiples of this, so the shift is exact in f32
ORIGIN_RANGE = 128.0  # m: the origin moves when the bed centre is farther than this from it


@ti.kernel
def rock_pass(w: ti.template(), rays: ti.types.ndarray(dtype=ti.f64, ndim=2), dt: ti.f64, cx: ti.f64, cy: ti.f64,
              mx: ti.f64, my: ti.f64, lx: ti.f64, ly: ti.f64, gx: ti.f64, gy: ti.f64, step: ti.i32,
              flight: ti.template(), recycle: ti.template(), count: ti.template(), center: ti.template(),
              integrator: ti.template(), gravity: ti.template(), drag: ti.template(), ground: ti.template()):
    """Pass 1 fused: flight, recycling, counting for the hash — one read of each rock per step. With
    ``count`` it first takes the step's tire rays (``rays``, layout of World.ray, float64) into ``w.ray``:
    passed as an argument, they cost no launch of their own."""
    if ti.static(count):
        for t, k in ti.ndrange(w.n_tires, RAY_FIELDS):
            w.ray[t, k] = ti.cast(rays[t, k], w.real)
    h = ti.cast(dt, w.real)
    centre = ti.Vector([ti.cast(cx, w.real), ti.cast(cy, w.real)])
    move = ti.Vector([ti.cast(mx, w.real), ti.cast(my, w.real)])
    lead = ti.Vector([ti.cast(lx, w.real), ti.cast(ly, w.real)])
    grid = ti.Vector([ti.cast(gx, w.real), ti.cast(gy, w.real)])
    if ti.static(count and w.masked):
        hashgrid.mark_tire_tiles(w, grid)
    for i in range(w.ipar[IPar.N_ROCKS]):
        if ti.static(flight):
            fly(w, i, h, integrator, gravity, drag, ground)
        if ti.static(recycle):
            recycle_to_leading_edge(w, i, centre, move, lead, step)
        if ti.static(count):
            hashgrid.count_rock(w, i, center, grid)


@ti.kernel
def coast_pass(w: ti.template(), n: ti.i32, dt: ti.f64, cx: ti.f64, cy: ti.f64, lx: ti.f64, ly: ti.f64,
          step0: ti.i32, flight: ti.template(), recycle: ti.template(), integrator: ti.template(),
          gravity: ti.template(), drag: ti.template(), ground: ti.template()):
    """``n`` steps of pass 1 in one launch, for when nothing outside a rock can change it: every vehicle that
    matters stands still for good, so the bed does not move and no tire can launch (a still tread throws
    nothing). Rocks are then independent: each thread takes its rock through the n steps doing exactly what
    ``rock_pass`` does (same functions, same step numbers for the random streams), and stops early once the
    rock rests inside the bed, where nothing can move it again. Bit-identical to n calls of ``step()``."""
    h = ti.cast(dt, w.real)
    centre = ti.Vector([ti.cast(cx, w.real), ti.cast(cy, w.real)])
    move = ti.Vector([ti.cast(0.0, w.real), ti.cast(0.0, w.real)])
    lead = ti.Vector([ti.cast(lx, w.real), ti.cast(ly, w.real)])
    for i in range(w.ipar[IPar.N_ROCKS]):
        for s in range(n):
            if ti.static(flight):
                fly(w, i, h, integrator, gravity, drag, ground)
            if ti.static(recycle):
                recycle_to_leading_edge(w, i, centre, move, lead, step0 + s + 1)
            if w.phase[i] == RESTING:
                settled = True
                if ti.static(recycle):
                    settled = not outside_bed(w.pos[i], centre, w.par[Par.BED_RADIUS], w.par[Par.GROUND_Z])
                if settled:
                    break


@ti.kernel
def hash_and_tires(w: ti.template(), step: ti.i32, swept: ti.template(), center: ti.template(),
                   ground: ti.template()) -> ti.i32:
    """Passes after the rock pass, in one launch: scan, scatter, ray cells, tire pass, and clearing the
    counts for the next step's rock pass. Returns the rocks launched."""
    hashgrid.scan_counts(w)
    hashgrid.scatter_all(w, center)
    if ti.static(not swept):
        tires.trace_all(w)
    launched = tires.launch_all(w, step, swept, center, ground)
    hashgrid.clear_all(w)
    return launched


@ti.kernel
def shift_origin(w: ti.template(), dx: ti.f64, dy: ti.f64):
    d = ti.Vector([ti.cast(dx, w.real), ti.cast(dy, w.real), 0.0])
    for i in range(w.ipar[IPar.N_ROCKS]):
        w.pos[i] -= d


@ti.kernel
def gather_vec(w: ti.template(), src: ti.template(), dst: ti.template()):
    for k in range(w.ipar[IPar.N_ROCKS]):
        dst[k] = src[w.entries[k]]


@ti.kernel
def copy_field(w: ti.template(), src: ti.template(), dst: ti.template()):
    for k in range(w.ipar[IPar.N_ROCKS]):
        dst[k] = src[k]


@ti.kernel
def identity_entries(w: ti.template()):
    for k in range(w.ipar[IPar.N_ROCKS]):
        w.entries[k] = k


@ti.kernel
def health(w: ti.template(), cx: ti.f64, cy: ti.f64, slack: ti.f64, check_bed: ti.template(),
           check_ground: ti.template(), out: ti.template()):
    """Count bad rocks: non-finite state [0], outside the bed [1], below the ground [2]; the smallest
    index of a bad rock of each kind goes to out[3..5] (as an index into the fields)."""
    for k in ti.static(range(6)):
        out[k] = 0 if k < 3 else 2147483647
    radius = w.par[Par.BED_RADIUS] + ti.cast(slack, w.real)
    ground = w.par[Par.GROUND_Z] - ti.cast(slack, w.real)
    for i in range(w.ipar[IPar.N_ROCKS]):
        p, v = w.pos[i], w.vel[i]
        finite = True
        for a in ti.static(range(3)):
            if not (ti.abs(p[a]) < 1e30 and ti.abs(v[a]) < 1e30):  # false for NaN too
                finite = False
        if not finite:
            out[0] += 1
            ti.atomic_min(out[3], i)
        elif ti.static(check_bed):
            d2 = (p[0] - cx) ** 2 + (p[1] - cy) ** 2
            if d2 > radius * radius:
                out[1] += 1
                ti.atomic_min(out[4], i)
        if ti.static(check_ground):
            if finite and p[2] - w.radius[i] < ground:
                out[2] += 1
                ti.atomic_min(out[5], i)


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
        fx, sim, bed = scene.effects, scene.sim, scene.bed
        self.real = ti.f64 if sim.precision == "f64" else ti.f32
        self.n_rocks = n = int(bed.rocks)
        self.dt = float(sim.dt)
        self.fleet = Fleet(scene)
        self.follow = scene.vehicle_index(bed.follow)
        self.plan = plan = Plan.from_scene(scene)
        splash, center = plan.splash, plan.center
        r_min, r_max = (float(x) for x in bed.rock_radius)
        self.cell_size = plan.cell_size
        rng = np.random.default_rng(scene.seed)
        radius = rng.uniform(r_min, r_max, n) if r_max > r_min else np.full(n, r_min)
        friction = rng.uniform(*bed.static_friction, n)
        rho = np.sqrt(rng.uniform(0.0, 1.0, n))  # uniform over the disk's area
        theta = rng.uniform(0.0, 2.0 * np.pi, n)

        # hash table sizes
        table = entries = 0
        if splash:
            if center:
                entries = n
                expected = n
            else:
                per_axis = np.floor(2.0 * radius / self.cell_size * (1.0 + 1e-5) + 1e-3).astype(np.int64) + 2
                entries = int(np.sum(per_axis ** 3))
                expected = int(np.sum((2.0 * radius / self.cell_size + 1.0) ** 3))
        n_tires = 2 * len(self.fleet.splashing) if splash else 0
        ray_len = max((v.tire_radius for v in scene.vehicles), default=1.0)
        # scope "tires": rocks are hashed only on tiles of a coarse XY mask around the tires' queries
        self.tile = max(0.5, 4.0 * self.cell_size)
        self._margin = r_max + (dilation_cells(r_max, self.cell_size) + 1) * self.cell_size
        if plan.patch:  # the footprint reaches its half-diagonal beyond the ray
            self._margin += max((math.hypot(0.5 * v.tire_width, 0.5 * v.contact_length) for v in scene.vehicles
                                 if v.splash), default=0.0)
        half = bed.radius + 2.0 * self.tile
        self._grid_half = half
        tiles = None
        if splash and not plan.scope_all:
            side = int(math.ceil(2.0 * half / self.tile))
            tiles = (side, side)
            # expected hashed share of the bed: a tire's region is about (2 margin + tile + v dt)^2
            reach = 2.0 * self._margin + 2.0 * self.tile + 60.0 * self.dt
            share = min(1.0, n_tires * reach * reach / (math.pi * bed.radius ** 2))
            expected = max(1, int(expected * share))
        if splash:
            ts = sim.hash.table_size
            table = next_prime(max(expected, 1024 if tiles else 1)) if ts == "auto" else int(ts)
        self.table_size = table
        self.w = w = acquire(self, n, self.real, hash_table=table, hash_entries=entries, n_tires=n_tires,
                           substeps=plan.substeps, ray_capacity=hashgrid.ray_capacity(ray_len, self.cell_size),
                           reorder=self.plan.reorder_every > 0, tiles=tiles, tile_size=self.tile,
                           patch=plan.patch, throw=plan.throw, fenders=plan.fenders)
        self.world = w

        # parameters
        par = np.zeros(Par.COUNT)
        wd = scene.world
        par[Par.GRAVITY] = wd.gravity
        par[Par.GROUND_Z] = 0.0  # set below, relative to the origin
        par[Par.BED_RADIUS] = bed.radius
        par[Par.RESTITUTION] = wd.restitution
        par[Par.GROUND_FRICTION] = wd.ground_friction
        par[Par.REST_SPEED] = wd.rest_speed
        par[Par.CELL] = self.cell_size
        par[Par.ANGLE_MIN], par[Par.ANGLE_MAX] = np.radians(scene.launch.release_angle)
        par[Par.SPREAD] = np.radians(scene.launch.spread)
        par[Par.LINEAR_DRAG], par[Par.QUAD_DRAG] = drag_coefficients(scene)
        par[Par.R_MAX] = r_max
        par[Par.TIE_EPS] = 1e-5
        par[Par.MARGIN] = self._margin
        for k, value in throw.tread_params(scene).items():
            par[k] = value
        # a rock resting on the ground: its bottom is the ground's height up to a few float spacings
        par[Par.PATCH_TOL] = 1e-4 + 64.0 * float(np.finfo(np.float32).eps) * abs(wd.ground_z)
        ipar = np.zeros(IPar.COUNT, dtype=np.int64)
        ipar[IPar.SEED] = scene.seed & 0x7FFFFFFF
        ipar[IPar.DILATE] = dilation_cells(r_max, self.cell_size) if center else 0
        ipar[IPar.N_ROCKS] = n

        # clock, bed and origin
        self.step_count = 0
        self.time = 0.0
        poses = self.fleet.poses(0.0)
        self._poses = poses
        c = poses[self.follow].position
        self.bed_center = np.array([c[0], c[1], wd.ground_z])
        self.origin = np.zeros(3)
        if sim.origin == "floating":
            self.origin[:2] = np.round(self.bed_center[:2] / ORIGIN_SNAP) * ORIGIN_SNAP
        par[Par.GROUND_Z] = wd.ground_z - self.origin[2]
        w.set_params(par, ipar)
        self._par = par

        # rocks: uniform over the disk, resting on the ground
        local = np.zeros((max(n, 1), 3))
        local[:n, 0] = self.bed_center[0] - self.origin[0] + bed.radius * rho * np.cos(theta)
        local[:n, 1] = self.bed_center[1] - self.origin[1] + bed.radius * rho * np.sin(theta)
        local[:n, 2] = par[Par.GROUND_Z] + radius
        pad = lambda a, fill=0: np.concatenate([a, np.full(max(n, 1) - n, fill, dtype=a.dtype)])
        npr = w.np_real()
        w.pos.from_numpy(local.astype(npr))
        w.vel.from_numpy(np.zeros((max(n, 1), 3), npr))
        w.radius.from_numpy(pad(radius.astype(npr), 1))
        w.friction.from_numpy(pad(friction.astype(npr)))
        w.rock_id.from_numpy(pad(np.arange(n, dtype=np.int32)))
        w.phase.from_numpy(np.zeros(max(n, 1), np.int32))
        if splash:
            w.hit_step.from_numpy(np.full(max(n, 1), -1, np.int32))
        self._tires_prev = self.fleet.rear_tires(poses)
        self._upload_rays(self._tires_prev, self._tires_prev)
        self._lead = np.array([math.cos(poses[self.follow].heading), math.sin(poses[self.follow].heading)])
        self.last_launches = 0
        if splash:
            self._initial_sort()
        # coasting: once these vehicles stop for good, steps run as one launch per call (False: always step)
        self.coast = True
        self._no_rays = np.zeros((1, RAY_FIELDS))
        self.steps_coasted = 0
        self._matter = sorted({self.follow, *(self.fleet.splashing if splash else ())})

    # ------------------------------------------------------------------------------------------------
    @property
    def launches_total(self) -> int:
        return int(self.w.launches[None])

    def vehicle_poses(self):
        return self._poses

    def _upload_rays(self, prev, cur, dt: float = 0.0) -> None:
        if self.w.n_tires:
            self.w.ray.from_numpy(self._ray_data(prev, cur, dt).astype(self.w.np_real()))

    def _ray_data(self, prev, cur, dt: float = 0.0) -> np.ndarray:
        """The rays of every splashing rear tire, float64 (T, RAY_FIELDS) in the World.ray layout."""
        w = self.w
        data = np.zeros((max(w.n_tires, 1), RAY_FIELDS))
        if w.n_tires == 0:
            return data
        o = self.origin
        # a tire that moved much farther than its speed allows (a path that jumps, e.g. a looping arc) did
        # not sweep the ground in between: its previous ray is taken to be the current one
        moved = np.linalg.norm(cur.center - prev.center, axis=1)
        speed = np.maximum(np.linalg.norm(cur.velocity, axis=1), np.linalg.norm(prev.velocity, axis=1))
        jumped = moved > 2.0 * speed * dt + 0.05
        data[:, 0:3] = np.where(jumped[:, None], cur.center, prev.center) - o
        data[:, 3:6] = np.where(jumped[:, None], cur.bottom, prev.bottom) - o
        data[:, 6:9] = cur.center - o
        data[:, 9:12] = cur.bottom - o
        data[:, 12:15] = cur.velocity
        data[:, 15:17] = cur.forward
        data[:, 17] = cur.spin
        data[:, HALF_W:] = patch.tread_columns(prev, cur, ~jumped, o)
        # tires far from the bed cannot touch a rock: park their rays, degenerate, high above the bed
        reach = self.scene.bed.radius + 2.0 * float(self.scene.bed.rock_radius[1]) + 2.0
        far = np.hypot(cur.center[:, 0] - self.bed_center[0], cur.center[:, 1] - self.bed_center[1]) > reach
        if far.any():
            park = self.bed_center - o + np.array([0.0, 0.0, 1000.0])
            data[far, 0:12] = np.tile(park, 4)
            data[far, HULL:] = np.tile(park[:2], (RAY_FIELDS - HULL) // 2)
            data[far, 17] = 0.0
        data[:, ACTIVE] = ~far
        return data

    def _grid_origin(self) -> np.ndarray:
        return self.bed_center[:2] - self.origin[:2] - self._grid_half

    def _initial_sort(self) -> None:
        """Sort the rocks in memory by slot once at the start (scope "all"), and clear the counts."""
        w, p = self.w, self.plan
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
        by construction (World), so the scatter cannot lose a rock."""
        w, p = self.w, self.plan
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
                launched = tires.tire_pass(w, self.step_count, p.swept, p.center, p.ground)
            with timer("hash clear"):
                hashgrid.clear_counts(w)
            return launched
        with timer("hash + tires"):
            return hash_and_tires(w, self.step_count, p.swept, p.center, p.ground)

    def _reorder(self) -> None:
        """Re-sort the rocks in memory by slot (entries is then the identity)."""
        w = self.w
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
        w, p = self.w, self.plan
        step0 = self.step_count
        for _ in range(n):  # the clock advances exactly as n calls of _step() advance it
            self.time += self.dt
        self.step_count += n
        self.steps_coasted += n
        lc = self.bed_center[:2] - self.origin[:2]
        with self.timer("coast"):
            for s in range(0, n, 1 << 30):
                coast_pass(w, min(n - s, 1 << 30), self.dt, float(lc[0]), float(lc[1]), float(self._lead[0]),
                           float(self._lead[1]), step0 + s, p.flight, p.recycle, p.integrator, p.gravity,
                           p.drag, p.ground)
        self._poses = self.fleet.poses(self.time)
        self._tires_prev = self.fleet.rear_tires(self._poses)
        self.last_launches = 0

    def _step(self, dt=None) -> None:
        w, p = self.w, self.plan
        dt = self.dt if dt is None else float(dt)
        self.step_count += 1
        self.time += dt
        poses = self.fleet.poses(self.time)
        c = poses[self.follow].position
        move = c[:2] - self.bed_center[:2]
        self.bed_center = np.array([c[0], c[1], self.bed_center[2]])
        lead = poses[self.follow].velocity[:2]
        if np.hypot(*lead) > 1e-9:
            self._lead = lead / np.hypot(*lead)
        if self.scene.sim.origin == "floating" and np.max(np.abs(c[:2] - self.origin[:2])) > ORIGIN_RANGE:
            new = np.round(c[:2] / ORIGIN_SNAP) * ORIGIN_SNAP
            shift = new - self.origin[:2]
            if self.n_rocks:
                with self.timer("origin shift"):
                    shift_origin(w, float(shift[0]), float(shift[1]))
            self.origin[:2] = new
        tires_now = self.fleet.rear_tires(poses)
        rays = self._ray_data(self._tires_prev, tires_now, dt) if p.splash else self._no_rays
        self._tires_prev = tires_now
        self._poses = poses
        if self.n_rocks and (p.flight or p.recycle or p.splash):
            lc = self.bed_center[:2] - self.origin[:2]
            g = self._grid_origin()
            with self.timer("rock pass"):
                rock_pass(w, rays, dt, float(lc[0]), float(lc[1]), float(move[0]), float(move[1]),
                          float(self._lead[0]), float(self._lead[1]), float(g[0]), float(g[1]), self.step_count,
                          p.flight, p.recycle, p.splash, p.center, p.integrator, p.gravity, p.drag, p.ground)
        if p.splash:
            self.last_launches = self._hash_and_tires()

    # ------------------------------------------------------------------------------------------------
    def state(self) -> dict:
        """The current state as NumPy arrays, rocks in their original order (by rock id)."""
        w, n = self.w, self.n_rocks
        ids = w.rock_id.to_numpy()[:n]
        pos = np.empty((n, 3))
        vel = np.empty((n, 3), self.w.np_real())
        radius = np.empty(n)
        phase = np.empty(n, np.int8)
        pos[ids] = w.pos.to_numpy()[:n].astype(np.float64) + self.origin
        vel[ids] = w.vel.to_numpy()[:n]
        radius[ids] = w.radius.to_numpy()[:n]
        phase[ids] = w.phase.to_numpy()[:n]
        poses = self._poses
        return {
            "time": self.time,
            "step": self.step_count,
            "positions": pos,
            "velocities": vel,
            "radii": radius,
            "phase": phase,
            "bed_center": self.bed_center.copy(),
            "vehicle_positions": np.array([p.position for p in poses]).reshape(-1, 3),
            "vehicle_headings": np.array([p.heading for p in poses]),
            "vehicle_names": np.array(self.fleet.names),
            "launches_total": self.launches_total,
        }

    # ------------------------------------------------------------------------------------------------
    _ROCK_FIELDS = ("pos", "vel", "radius", "friction", "rock_id", "phase")

    def checkpoint(self) -> dict:
        """Everything needed to continue bit-identically: rock fields in memory order, clock, origin."""
        w = self.w
        data = {f"rock_{k}": getattr(w, k).to_numpy() for k in self._ROCK_FIELDS}
        if self.plan.splash:
            data["rock_hit_step"] = w.hit_step.to_numpy()
        data.update(step_count=np.int64(self.step_count), time=np.float64(self.time), origin=self.origin.copy(),
                    bed_center=self.bed_center.copy(), lead=self._lead.copy(),
                    launches=np.int64(self.launches_total), scene=np.array(self.scene.name),
                    seed=np.int64(self.scene.seed), rocks=np.int64(self.n_rocks))
        return data

    def restore(self, data: dict) -> None:
        """Continue from a checkpoint() of a simulation of the same scene."""
        if int(data["rocks"]) != self.n_rocks or int(data["seed"]) != self.scene.seed:
            raise ValueError("checkpoint does not belong to this scene (rock count or seed differ)")
        w = self.w
        for k in self._ROCK_FIELDS:
            getattr(w, k).from_numpy(np.asarray(data[f"rock_{k}"]))
        if self.plan.splash:
            w.hit_step.from_numpy(np.asarray(data["rock_hit_step"]))
        self.step_count = int(data["step_count"])
        self.time = float(data["time"])
        self.origin = np.array(data["origin"], dtype=np.float64)
        self.bed_center = np.array(data["bed_center"], dtype=np.float64)
        self._lead = np.array(data["lead"], dtype=np.float64)
        w.launches[None] = int(data["launches"])
        par = self._par.copy()
        par[Par.GROUND_Z] = self.scene.world.ground_z - self.origin[2]
        w.par.from_numpy(par.astype(w.np_real()))
        self._poses = self.fleet.poses(self.time)
        self._tires_prev = self.fleet.rear_tires(self._poses)
        if self.plan.splash:
            self._upload_rays(self._tires_prev, self._tires_prev)

    def check_health(self) -> None:
        """The runtime guard: raise HealthError naming the step, the rock and the value when a rock is
        non-finite, outside the bed (with recycling) or below the ground (with ground contact)."""
        if not self.n_rocks:
            return
        lc = self.bed_center[:2] - self.origin[:2]
        # 1 mm, or a few float spacings at the bed's distance from the kernel origin ("world" origin, f32)
        eps = float(np.finfo(self.w.np_real()).eps)
        slack = 1e-3 + 8.0 * eps * (float(np.max(np.abs(lc))) + self.scene.bed.radius)
        health(self.w, float(lc[0]), float(lc[1]), slack, self.plan.recycle, self.plan.ground != "none",
               self.w.health_out)
        out = self.w.health_out.to_numpy()
        if not out[:3].any():
            return
        kind = int(np.flatnonzero(out[:3])[0])
        i = int(out[3 + kind])
        rid = int(self.w.rock_id[i])
        p = self.w.pos[i].to_numpy().astype(np.float64) + self.origin
        v = self.w.vel[i].to_numpy()
        what = ("non-finite state", "outside the bed", "below the ground")[kind]
        raise HealthError(
            f"step {self.step_count} (t = {self.time:.4f} s): {int(out[kind])} rock(s) {what}; "
            f"first: rock {rid} at position {np.array2string(p, precision=4)} m, velocity "
            f"{np.array2string(v, precision=4)} m/s")

    def tire_rays(self) -> np.ndarray:
        t = self._tires_prev
        return np.stack([t.center, t.bottom], axis=1) if len(t.spin) else np.zeros((0, 2, 3))

    def queried_cells(self) -> np.ndarray:
        w = self.w
        if not self.plan.splash or self.plan.swept:
            return np.zeros((0, 3), np.int64)
        counts = w.ray_cell_count.to_numpy()
        cells = w.ray_cells.to_numpy()
        return np.concatenate([cells[r, :counts[r]] for r in range(len(counts))]).astype(np.int64)
