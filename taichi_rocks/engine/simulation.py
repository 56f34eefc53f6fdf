"""The simulation's public face: a Scene in, steps, the rocks out (``state``, ``rock_arrays``, checkpoints).

``Simulation`` builds the World of the scene's layout (engine/layout.py, engine/world.py: its data in a few ndarrays),
the host state and the host side of a step (engine/host.py) and the stepper of its stepping mode
(engine/steppers.py, chosen once), then a step is:
  1. the host side: clock, poses at t + dt, the bed following its vehicle, the floating origin, the tire rays
     (a batch of steps at a time, the same bits as step by step: ``Simulation.lookahead = 0`` computes it per
     step);
  2. if the origin moved, the stepper moves every rock by the (exact) difference;
  3. the stepper's kernels: flight -> recycle -> hash -> tires over every rock ("full") or over the active list
     ("active", resting rocks in ground tiles), the same results.
  4. the optional effects that run (engine/effects/, declared in config/effects/: dust), from the poses at
     t + dt, on fields of their own; ``effect_arrays()`` gives what they hold.
Passes nobody asked for are neither compiled nor called, and their fields are not allocated: no splashing
tire -> no hash table, no tire pass and no flight (only launched rocks ever leave the ground). The kernels
(engine/kernels.py) read which passes run from the Plan; the set-up (initial rocks, hash sizes, parameters)
is engine/setup.py; the rocks as NumPy arrays, from the declaration of the rock fields, engine/rocks.py.
Coasting: once every vehicle that matters has stopped for good, no tire can launch and the bed stands
still; the rocks are then independent and any number of steps runs as one ``coast_pass`` launch,
bit-identical to stepping (``Simulation.coast = False`` turns it off).
"""


import numpy as np
import taichi as ti

from ..config.arches import API, arch_problem
from ..config.plan import Plan
from ..config.scene import SceneError, load_scene, scene_with
from ..motion.live import drive_pose
from ..motion.vehicles import Fleet
from . import arguments, changes, drives, rocks
from .effects import Effects
from .host import LOOKAHEAD, ORIGIN_RANGE, ORIGIN_SNAP, HostSide, HostState
from .impact_pass import ImpactLog, body_table, check_bodies, write_bodies
from .livesteps import LiveHostSide
from .kernels import count_flying
from .launcher import Launcher
from .layout import check_fits, world_layout
from .runtime import init_taichi
from .simreads import Reads
from .simsaves import HealthError, Saves
from .setup import initial_orientations, initial_rocks, scene_params
from .steppers import stepper_for
from .timing import NO_TIMER
from .world import Par, World, acquire

__all__ = ["ORIGIN_RANGE", "ORIGIN_SNAP", "LOOKAHEAD", "HealthError", "Simulation"]


class Simulation(Reads, Saves):
    """A bed of rocks following a vehicle, with the rear tires of the splashing vehicles throwing rocks.

    Build one from a scene, move it forward in time, read what happened::

        sim = Simulation.from_scene("scenes/convoy.toml")
        sim.advance_to(1 / 60)      # or sim.step(n)
        hits = sim.impacts()        # stones that hit a vehicle since the last call
        state = sim.state()         # every rock, world coordinates

    How a step runs: the module docstring. Its kernels compile once per World layout and switches, not per
    Simulation (engine/view.py): a second one of the same switches and another rock count compiles nothing.

    Args:
        scene: a validated ``Scene`` (``load_scene``, ``parse_scene``, ``scene_with``).
        arch: the Taichi backend: "cpu", "gpu" or "cuda" (CUDA, else the CPU with one warning line) or
            "vulkan". Taichi starts once per process, on the first Simulation's arch; later ones run on it.
        seed: overrides the scene's seed (None: the scene's).
        timer: the timing hook (engine/timing.py): ``PassTimer()`` times every pass of a step; the default
            times nothing.
        tumble: also track each rock's spin and orientation (engine/tumble.py; ``state()`` then has
            "angular_velocities" and "orientations"), as the commands that draw or export them ask; without it
            (and without the scene's ``[effects] tumble = "always"``) they are neither allocated nor compiled.
        track_changes: keep a mirror of each rock's drawn state by id, so that ``changes()`` costs the rows it
            returns (engine/changes.py; about 24 bytes a rock); False: neither allocated nor compiled.

    Raises:
        SceneError: (a ValueError; one line per problem, naming the key) the scene does not fit this machine's
            memory, resting rocks would lie inside a body that stones hit, or ``arch`` cannot run it (``sim.precision
            = "f64"`` or ``sim.hash.insert = "aabb"`` on Vulkan: config/arches.py, as the command line refuses them).
        ValueError: ``arch`` is not a backend's name, or an environment variable of config/environment.py is bad.

    Attributes:
        scene: the Scene (with ``seed`` applied).
        n_rocks: the number of rocks N; rock ids are 0 .. N-1.
        dt: the time step, s.
        plan: the compile-time Plan: which passes run (config/plan.py).
        coast: when True (default), steps after every vehicle that matters has stopped for good run as one
            launch, bit-identical to stepping.
    """

    @classmethod
    def from_scene(cls, path, arch: str = "cpu", seed=None, timer=NO_TIMER, tumble: bool = False,
                   track_changes: bool = True) -> "Simulation":
        """A Simulation of the scene file ``path``.

        Args:
            path: a scene file (TOML; docs/scene-format.md).
            arch, seed, timer, tumble, track_changes: as for ``Simulation``.

        Returns:
            The Simulation at time 0.

        Raises:
            SceneError: the file cannot be read or is not a valid scene (one line per problem).
        """
        return cls(load_scene(path), arch=arch, seed=seed, timer=timer, tumble=tumble, track_changes=track_changes)

    def __init__(self, scene, arch: str = "cpu", seed=None, timer=NO_TIMER, tumble: bool = False,
                 track_changes: bool = True):
        if seed is not None:
            scene = scene_with(scene, {"seed": int(seed)})
        check_fits(scene)  # a scene too big for this machine is refused before anything is allocated
        check_bodies(scene)  # and one whose resting rocks would lie inside a body that stones hit
        self._check_arch(scene, arch)  # and one the backend asked for cannot run, before Taichi starts
        self.arch = init_taichi(arch)
        self._check_arch(scene, self.arch)  # and the backend Taichi runs on (it starts once per process)
        self.scene = scene
        self.real = ti.f64 if scene.sim.precision == "f64" else ti.f32
        self.n_rocks = int(scene.bed.rocks)
        self.dt = float(scene.sim.dt)
        self.fleet = Fleet(scene)
        self.follow = scene.vehicle_index(scene.bed.follow)
        self.tumble = bool(tumble)  # the caller draws or exports orientations (config/plan.py spin_on)
        self.track_changes = bool(track_changes)  # keep the mirror changes() reads (engine/changes.py)
        self.plan = plan = Plan.from_scene(scene, self.tumble, self.track_changes)
        self.cell_size = plan.cell_size
        start = initial_rocks(scene)
        self.world = self._allocate(start.radius)
        self._host = HostState()
        host = LiveHostSide if self.fleet.live else HostSide  # live vehicles: engine/livesteps.py
        self._host_side = host(scene, self.fleet, self.follow, self.world.n_tires, LOOKAHEAD, plan.targets)
        self._host_side.start(self._host)
        self._stepper = stepper_for(plan)(self.world, plan, self._sizing, self._host,
                                          scene.sim.hash.table_size == "auto", timer)
        self._timer = timer  # the timing hook (engine/timing.py): PassTimer() times every pass of a step
        self._par, ipar = scene_params(scene, plan, self._sizing, ground_z=scene.world.ground_z - self.origin[2])
        self.world.set_params(self._par, ipar)
        pos = start.resting_positions(self._host.local_centre(), scene.bed.radius, self._par[Par.GROUND_Z])
        given = {"pos": pos, "radius": start.radius, "friction": start.friction}
        if plan.spin:
            given["orient"] = initial_orientations(scene.seed, self.n_rocks)
        rocks.write(self.world, rocks.initial_arrays(self.world, self.n_rocks, given), self.n_rocks)
        self._put_rays()
        self._changes_buf = np.empty((4096, 9 if plan.spin else 5))  # changes()' rows on the CPU, grown as needed
        self._gather = Launcher(changes.gather_packed)  # changes()' read at the cost of its launch (CPU)
        self._impacts = None  # with impacts: the events' host side (engine/impact_pass.py ImpactLog)
        if plan.impacts:
            write_bodies(self.world, body_table(scene, plan, self._par[Par.GROUND_Z]),
                         [i for i in self.fleet.splashing for _ in range(2)])
            self._impacts = ImpactLog(self.world.events)
        self._stepper.start()
        self._stepper.sync_drawn()
        self._effects = Effects(scene, plan, self.real)  # the optional effects that run (engine/effects/)
        # coasting: once these vehicles stop for good, steps run as one launch per call (False: always step)
        self.coast = True
        self._matter = sorted({self.follow, *(self.fleet.splashing if plan.splash else ())})

    @staticmethod
    def _check_arch(scene, arch) -> None:
        problem = arch_problem(scene, arch, API)
        if problem:
            raise SceneError([problem])

    def _allocate(self, radius: np.ndarray) -> World:
        """A new World of this scene's layout, sized for the rocks' radii ``radius``; sets the hash sizes
        (``_sizing``, ``table_size``)."""
        p = self.plan
        layout, self._sizing = world_layout(self.scene, p, radius)
        self.table_size = self._sizing.table
        return acquire(self, self.n_rocks, self.real, **layout)

    # ------------------------------------------------------------------------------------------ the host state
    @property
    def time(self) -> float:
        """The simulated time, s."""
        return self._host.time

    @property
    def step_count(self) -> int:
        """Steps taken since time 0 (a coasted step counts as one)."""
        return self._host.step_count

    @property
    def origin(self) -> np.ndarray:
        """The kernels' local frame in world coordinates (float64, m): world = origin + local."""
        return self._host.origin

    @property
    def anchor(self) -> np.ndarray:
        """The floating origin's anchor in world coordinates (float64, m): the followed vehicle's path start."""
        return self._host.anchor

    @property
    def bed_center(self) -> np.ndarray:
        """The bed's centre in world coordinates (float64, m, (3,))."""
        return self._host.bed_center

    @property
    def steps_coasted(self) -> int:
        """Steps run as coasting (one launch for many steps) since time 0."""
        return self._host.steps_coasted

    @property
    def last_launches(self) -> int:
        """Rocks launched in the last step (read from the device when asked: a step reads nothing back)."""
        n = self._host.last_launches
        return self._stepper.launched() if n is None else n

    @property
    def lookahead(self) -> int:
        """Steps whose host side is computed at once (engine/host.py; 0: step by step)."""
        return self._host_side.lookahead

    @lookahead.setter
    def lookahead(self, steps: int) -> None:
        self._host_side.lookahead = int(steps)

    @property
    def timer(self):
        """The timing hook (engine/timing.py); set it to time the passes of the coming steps."""
        return self._timer

    @timer.setter
    def timer(self, timer) -> None:
        self._timer = self._stepper.timer = timer

    @property
    def loops(self) -> str:
        """How the step's loops run: "serial" or "parallel" now (engine/variant.py; the engine chooses from the
        backend, the CPU threads and the rocks in the step's loops). Set "serial", "parallel" or "auto" (the
        engine's choice, the default; ``TAICHI_ROCKS_LOOPS`` sets it for a process)."""
        return "serial" if self._stepper.variant.serial else "parallel"

    @loops.setter
    def loops(self, mode: str) -> None:
        self._stepper.set_loops(mode)

    @property
    def active_count(self) -> int:
        """Rocks in the active list (active stepping; all rocks with "full" stepping)."""
        return self._stepper.active_count

    @property
    def launches_total(self) -> int:
        """Rocks launched by a tire since time 0."""
        return int(self.world.launches[None])

    @property
    def recycles_total(self) -> int:
        """Rocks moved to the bed's leading edge so far (each time a rock leaves the bed it counts once)."""
        return int(self.world.recycles[None])

    def vehicle_poses(self):
        """The vehicles' poses now.

        Returns:
            A list of motion/vehicles.py ``VehiclePose``, in scene order: name, position (world, m, the body
            centre at ground level), heading (rad), speed (m/s), yaw_rate (rad/s), velocity.
        """
        return self._host.poses

    def drive(self, name: str, position, heading: float, speed=None, yaw_rate=None, wheel_spin=None, *,
              at=None) -> None:
        """Set where live vehicle ``name`` (``path = { kind = "live" }``) will be at the end of the next
        ``advance_to`` / ``step`` (or at time ``at``). Between that and the pose it has now, the pose is
        interpolated (cubic Hermite: the tires sweep continuously over the sub-steps); a move farther than its
        speeds allow is a jump (a teleport: no launches along it). A later call before the advance replaces
        this one. The manual: docs/drives.md; the interpolation: motion/live.py.

        Args:
            name: a live vehicle of the scene.
            position: (x, y), world coordinates, m (as ``state()`` reports them).
            heading: rad, counter-clockwise from +x.
            speed: m/s along the heading (negative: reversing); None: derived from the motion.
            yaw_rate: rad/s; None: derived from the motion.
            wheel_spin: the rear wheels' spin, rad/s (faster than speed / tire radius: a burnout, which throws
                harder); None: rolling, speed / tire_radius (1 + slip).
            at: the time the pose is for, s (after ``time``); None: the end of the next advance.

        Raises:
            ValueError: naming the vehicle and the value: an unknown name, a scripted vehicle, a NaN or infinite
                value, a position that is not (x, y), ``at`` already passed. The simulation is unchanged.
        """
        i = drives.live_index(self.fleet, name)
        self.fleet.paths[i].pending = drive_pose(name, position, heading, speed, yaw_rate, wheel_spin, at, self.time)

    def drive_track(self, name: str) -> np.ndarray:
        """The poses live vehicle ``name`` was given so far (its keyframes: motion/live.py), as a recorded drive's
        rows (config/drivefile.py ``drive_text`` writes them; docs/drives.md).

        Args:
            name: a live vehicle of the scene.

        Returns:
            (K, 7) float64: t (s), x, y (world m), heading (rad), speed (m/s), yaw_rate (rad/s), wheel_spin
            (rad/s; NaN: rolling).

        Raises:
            ValueError: an unknown name or a scripted vehicle.
        """
        return self.fleet.paths[drives.live_index(self.fleet, name)].rows()

    def tile_shift(self) -> np.ndarray:
        """The floating origin's shift in tiles of active stepping's store (whole numbers, float64; zeros with
        full stepping): what drawing the tiles needs (engine/drawing.py).

        Returns:
            (2,) float64.
        """
        return self._stepper.tile_shift()

    def rocks_in_air(self) -> int:
        """How many rocks fly now (phase FLYING), counted in a kernel.

        Returns:
            The count (0 without rocks).
        """
        return int(count_flying(self.world)) if self.n_rocks else 0

    def _put_rays(self) -> None:
        """The rays of the tires standing where they are now (before a step, after a restore)."""
        h = self._host
        self._stepper.put_rays(self._host_side.ray_data(h, h.tires_prev, h.tires_prev))

    # ------------------------------------------------------------------------------------------ stepping
    def step(self, n: int = 1) -> None:
        """Take ``n`` steps of dt.

        Args:
            n: the number of steps, a whole number >= 0 (the kernels count at most 2^31 - 1 steps).

        Raises:
            TypeError: ``n`` is not a whole number.
            ValueError: ``n`` is negative, or too many steps.
        """
        n = arguments.whole_steps(n, self.step_count)
        drives.bind_steps(self.fleet, self.time, n, self.dt)  # live vehicles: drive() is for these steps' end
        while n > 0:
            if self._can_coast():
                self._coast(n)
                return
            self._step()
            n -= 1

    def advance_to(self, t: float) -> None:
        """Step to exactly time ``t``: whole steps of dt, then one shorter step if dt does not divide the
        interval (so frame f is the state at f / fps for any fps). A game calls it once per frame.

        Args:
            t: the time to reach, s, a finite number; a time at or before ``time`` takes no step.

        Raises:
            TypeError: ``t`` is not a number.
            ValueError: ``t`` is infinite, NaN or past the last step the kernels count (2^31 - 1 steps).
        """
        t = arguments.target_time(t, self.time, self.dt, self.step_count)
        tol = 1e-9 * max(1.0, abs(t))
        drives.bind_to(self.fleet, self.time, t)  # live vehicles: drive() is for time t
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
                    and self.time >= self.fleet.still_after(self._matter)
                    and not (p.impacts and self.rocks_in_air()))  # a flying stone may still hit a body

    def _coast(self, n: int) -> None:
        h = self._host
        step0 = h.step_count
        for _ in range(n):  # the clock advances exactly as n calls of _step() advance it
            h.time += self.dt
        h.step_count += n
        h.steps_coasted += n
        self._stepper.coast(n, self.dt, h.local_centre(), h.lead, step0)
        self._host_side.resume(h)
        self._effects.coast(h, n * self.dt)
        h.last_launches = 0

    def _step(self, dt=None) -> None:
        with self._timer("vehicles + rays"):
            s = self._host_side.advance(self._host, self.dt if dt is None else float(dt))
        if s.origin_moved is not None and self.n_rocks:
            self._stepper.shift_origin(s.origin_moved)
        tires_ran = self._stepper.step(s)
        if self.plan.splash:
            self._host.last_launches = None if tires_ran else 0  # None: on the device (Stepper.launched)
        if self._impacts is not None:
            self._impacts.after_step(self._host.step_count, self._host.time)
        self._effects.after_step(self._host, self.dt if dt is None else float(dt))
