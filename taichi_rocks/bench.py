"""``taichi-rocks bench``: accuracy against cost, speed against peers, and the performance targets.

``run_bench(out_dir, quick, arch, progress)`` writes ``report.md``, ``results.json`` and PNG plots to
``out_dir`` and returns the results as a dict (with ``report`` = the report's path).

What is measured (every timing: warm-up/compile first, then the median of repeated calls with ``ti.sync()``
around the timed region):

1. Accuracy against cost
   * integrator x dt: one rock per case flown for 2 s (no ground) by calling the engine's ``rock_pass``
     kernel with flight only, against closed forms: gravity only (parabola), linear drag
     (x = x0 + v_inf t + (v0 - v_inf) tau (1 - exp(-t/tau)), v_inf = -g tau z) and quadratic drag (vertical
     rise v = v_t tan(.), fall v = -v_t tanh(.)); cost = the flight pass with every rock of the largest bed
     flying.
   * detection x vehicle speed: six lanes, one vehicle per speed, drive straight over a bed at rest (no
     recycling, no ground contact: a launched rock never lands and is never hit twice). Reference: the
     analytic sweep of each rear tire's ray over its straight path between t = 0 and the end of the run
     (a rectangle; a rock is a true contact iff its centre lies within its radius of it). Recall =
     launched true contacts / true contacts.
   * precision x distance from the origin: launched rocks flown 2 s with the rock positions stored as the
     engine stores them (local = world - origin; origin 0 for ``origin = "world"``, the 64 m snapped bed
     centre for ``"floating"``) in f32 and f64; error = world position against an f64 flight at the origin.
   * hash settings: the same scene run k steps with each setting; the launched rock ids must be identical.
2. Speed against peers: full step for N rocks x T rear tires; time per pass (kernels timed inside a real
   step, and called one at a time); NumPy brute force, SciPy cKDTree, NVIDIA Warp HashGrid (CPU) and a
   streaming floor (one fused Taichi read-modify-write pass over position and velocity).
3. Targets, reported as met / not met with the numbers.

No engine file is changed. At run time the benchmark (a) wraps the Taichi kernels of ``simulation``,
``hashgrid`` and ``tires`` inside ``with KernelTap()`` blocks only (timing and recording their arguments;
restored on exit), and calls kernels again with arguments bound by parameter name (``rock_pass`` flags
``flight``/``recycle``/``count``); (b) gives a simulation the plan ``Plan.from_scene`` makes for a scene that
differs only in kernel template arguments (checked: the fields must not depend on the change); (c) while
flying test rocks, limits ``ipar[N_ROCKS]`` to them and restores the rock fields afterwards.
"""

import contextlib
import dataclasses
import inspect
import io
import json
import math
import os
import platform
import sys
import time
import traceback
from pathlib import Path
from typing import Optional

import numpy as np
import taichi as ti

from . import hashgrid, simulation, tires
from .runtime import init_taichi
from .scene import parse_scene, scene_with
from .world import FLYING, IPar

G = 9.81
ACC_T = 2.0  # s of flight for the accuracy and precision tests
SAMPLE_EVERY = 0.1  # s between error samples (every dt of the sweep divides it)
TAU_LINEAR = 1.0  # s: Stokes time constant of the 3 cm rock in the linear-drag test
PRESET_SPEED = 60.0  # m/s: the speed the presets' recall is judged at

# Presets: the cheapest settings meeting all of (name, flight error, recall at 60 m/s, launch-time bound):
#  * flight error: max position error over a 2 s flight of the default-physics cases (gravity only,
#    quadratic drag), and the f32/f64 error of a flight 100 km from the origin (floating origin) - measured;
#  * recall of true tire contacts at 60 m/s - measured (swept; single ray from a recall-vs-displacement fit);
#  * launch-time bound: a rock is launched at the end of the step in which the tire reaches it, up to dt
#    late, so its path is off by up to v_launch dt (v_launch <= 30 m/s) - modelled, not measured.
V_LAUNCH_MAX = 30.0
PRESET_TARGETS = (
    ("draft", 0.05, 0.90, 0.6),  # a rock diameter; 0.6 m / 30 m/s -> dt <= 0.02 s
    ("balanced", 1e-3, 0.99, 0.06),  # a millimetre; dt <= 0.002 s
    ("reference", 1e-6, 0.999, 0.006),  # a micrometre (beyond f32); dt <= 0.0002 s
)


# ================================================================================================ config
@dataclasses.dataclass
class Config:
    mode: str
    grid_n: tuple
    grid_t: tuple
    bed_radius: float
    main: tuple  # (N, T) of the targets
    k_hits: int  # steps from t = 0 whose launched ids are compared across hash settings
    warm: int
    reps: int
    pass_reps: int
    numpy_reps: int
    kdtree_reps: int
    warp_reps: int
    probe_n: int
    probe_radius: float
    speeds: tuple
    run_time: float
    acc_dts: tuple
    acc_f64: bool
    distances: tuple
    hash_settings: tuple  # names from HASH_SETTINGS
    hash_n: int
    integ_cost: tuple  # (integrator, drag) pairs timed with every rock flying
    validate_presets: bool
    use_warp: bool = True
    substeps_mode: bool = True  # detection with ray x4 substeps (its own simulation)
    effects: tuple = ("gravity off", "drag none", "ground none", "recycle off")
    effects_all_flying: bool = True
    passes_all: bool = True  # per-pass breakdown for every grid configuration (else the main one only)


HASH_SETTINGS = {  # name -> scene overrides (the default scene: centre insert, cell 2 r_max, auto table)
    "default (center, auto=2 r_max, auto, scope tires)": {},
    "center, cell r_min": {"sim.hash.cell_size": "min_radius"},
    "center, cell 0.03 m": {"sim.hash.cell_size": 0.03},
    "center, cell 0.05 m": {"sim.hash.cell_size": 0.05},
    "design: aabb, cell r_min": {"sim.hash.insert": "aabb", "sim.hash.cell_size": "min_radius"},
    "aabb, cell 0.03 m": {"sim.hash.insert": "aabb", "sim.hash.cell_size": 0.03},
    "aabb, cell 2 r_max": {"sim.hash.insert": "aabb", "sim.hash.cell_size": "max_diameter"},
    "table 0.5 N": {"sim.hash.table_size": "0.5N"},
    "table 4 N": {"sim.hash.table_size": "4N"},
    "scope all": {"sim.hash.scope": "all"},
    "design, scope all": {"sim.hash.insert": "aabb", "sim.hash.cell_size": "min_radius", "sim.hash.scope": "all"},
}
DEFAULT_HASH = "default (center, auto=2 r_max, auto, scope tires)"
DESIGN_HASH = "design: aabb, cell r_min"

INTEGRATORS = ("symplectic_euler", "heun", "rk4")
DRAGS = ("none", "linear", "quadratic")
CASE_OF_DRAG = {"none": "gravity", "linear": "linear", "quadratic": "quadratic"}


def make_config(quick: bool = False, tiny: bool = False) -> Config:
    if tiny:
        return Config(mode="tiny", grid_n=(20_000,), grid_t=(2,), bed_radius=8.0, main=(20_000, 2), k_hits=30,
                      warm=2, reps=4, pass_reps=2, numpy_reps=2, kdtree_reps=1, warp_reps=2,
                      probe_n=20_000, probe_radius=16.0, speeds=(10.0, 60.0), run_time=0.2,
                      acc_dts=(1e-2, 2e-2), acc_f64=False, distances=(0.0, 1e5),
                      hash_settings=(DEFAULT_HASH, DESIGN_HASH), hash_n=20_000,
                      integ_cost=tuple((i, "quadratic") for i in INTEGRATORS), validate_presets=False,
                      use_warp=False, substeps_mode=False, effects=("drag none",), effects_all_flying=False)
    if quick:
        return Config(mode="quick", grid_n=(10_000, 100_000), grid_t=(2, 20), bed_radius=30.0,
                      main=(100_000, 20), k_hits=20, warm=3, reps=10, pass_reps=4, numpy_reps=2, kdtree_reps=2,
                      warp_reps=5, probe_n=100_000, probe_radius=16.0,
                      speeds=(5.0, 10.0, 20.0, 30.0, 45.0, 60.0), run_time=0.4,
                      acc_dts=(2e-3, 5e-3, 1e-2, 2e-2), acc_f64=False,
                      distances=(0.0, 1e3, 1e4, 1e5),
                      hash_settings=(DEFAULT_HASH, DESIGN_HASH, "scope all"),
                      hash_n=100_000, integ_cost=tuple((i, "quadratic") for i in INTEGRATORS),
                      validate_presets=False, passes_all=False)
    return Config(mode="full", grid_n=(10_000, 100_000, 1_000_000), grid_t=(2, 20, 64), bed_radius=30.0,
                  main=(1_000_000, 20), k_hits=30, warm=5, reps=20, pass_reps=8, numpy_reps=3, kdtree_reps=3,
                  warp_reps=10, probe_n=200_000, probe_radius=16.0,
                  speeds=(5.0, 10.0, 20.0, 30.0, 45.0, 60.0), run_time=0.4,
                  acc_dts=(1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2e-2), acc_f64=True,
                  distances=(0.0, 1e2, 1e3, 1e4, 3e4, 1e5), hash_settings=tuple(HASH_SETTINGS),
                  hash_n=100_000, integ_cost=tuple((i, d) for i in INTEGRATORS for d in DRAGS),
                  validate_presets=True)


# ================================================================================================ helpers
def _sync():
    ti.sync()


def _stats(seconds) -> dict:
    a = np.asarray(seconds, float) * 1e3
    return {"median_ms": float(np.median(a)), "mean_ms": float(np.mean(a)), "min_ms": float(np.min(a)),
            "max_ms": float(np.max(a)), "reps": int(len(a))}


def _time(fn, reps: int, warmup: int = 1) -> dict:
    """Warm-up calls (compile), then `reps` timed calls with ti.sync() around each."""
    for _ in range(warmup):
        fn()
    _sync()
    out = []
    for _ in range(reps):
        _sync()
        t = time.perf_counter()
        fn()
        _sync()
        out.append(time.perf_counter() - t)
    return _stats(out)


def _is_kernel(obj) -> bool:
    return bool(getattr(obj, "_is_wrapped_kernel", False))


_GROUPS = {"rock_pass": "rock pass (fused)", "clear_counts": "hash clear", "count_all": "hash count (initial)",
           "inclusive_scan": "hash scan", "scatter": "hash scatter", "gather_vec": "reorder",
           "copy_field": "reorder", "identity_entries": "reorder", "trace_rays": "trace rays",
           "tire_pass": "tire pass", "shift_origin": "origin shift",
           "hash_and_tires": "hash scan+scatter+tires (fused)"}


class KernelTap:
    """Wraps every Taichi kernel of the simulation, hashgrid and tires modules for the duration of a
    ``with`` block: each call inside a real ``Simulation.step`` is timed (ti.sync before and after) and its
    arguments are kept, so a kernel can be called again on its own with some arguments changed by name."""

    MODULES = (simulation, hashgrid, tires)

    def __init__(self, timed: bool = True):
        self.timed = timed
        self.times: dict[str, list] = {}
        self.calls: dict[str, tuple] = {}
        self.originals: dict[str, object] = {}
        self._saved = []

    def __enter__(self):
        for mod in self.MODULES:
            for name, obj in list(vars(mod).items()):
                if _is_kernel(obj):
                    self.originals.setdefault(name, obj)
                    self._saved.append((mod, name, obj))
                    setattr(mod, name, self._wrap(name, obj))
        return self

    def __exit__(self, *exc):
        for mod, name, obj in reversed(self._saved):
            setattr(mod, name, obj)
        self._saved.clear()
        return False

    def _wrap(self, name, fn):
        def wrapper(*args, **kwargs):
            self.calls[name] = (args, kwargs)
            if not self.timed:
                return fn(*args, **kwargs)
            _sync()
            t = time.perf_counter()
            out = fn(*args, **kwargs)
            _sync()
            self.times.setdefault(name, []).append(time.perf_counter() - t)
            return out

        return wrapper

    def grouped_ms(self, steps: int) -> dict:
        out: dict[str, float] = {}
        for name, ts in self.times.items():
            key = _GROUPS.get(name, name)
            out[key] = out.get(key, 0.0) + 1e3 * float(np.sum(ts)) / max(steps, 1)
        return out


def call_with(original, recorded, **changes):
    """Call a kernel with the arguments of a recorded call, some replaced by parameter name."""
    args, kwargs = recorded
    bound = inspect.signature(original).bind(*args, **kwargs)
    for key, value in changes.items():
        if key not in bound.arguments:
            raise KeyError(f"{getattr(original, '__name__', original)} has no parameter {key!r}")
        bound.arguments[key] = value
    return original(*bound.args, **bound.kwargs)


def record_step(sim) -> dict:
    """Run one step with every kernel call recorded (untimed); returns name -> (args, kwargs)."""
    with KernelTap(timed=False) as tap:
        sim.step()
    _sync()
    return dict(tap.calls)


def swap_plan(sim, scene) -> None:
    """Give a simulation the plan a fresh Simulation(scene) would have, when only kernel template arguments
    differ (integrator, drag, gravity, ground, recycle, detection swept vs single ray); the fields must not
    depend on the change, which is checked."""
    new = type(sim.plan).from_scene(scene)
    old = sim.plan
    for f in ("splash", "flight", "center", "scope_all", "substeps", "reorder_every", "cell_size"):
        if hasattr(old, f) and getattr(old, f) != getattr(new, f):
            raise ValueError(f"plan change needs other fields ({f}: {getattr(old, f)} -> {getattr(new, f)})")
    sim.plan = new
    sim.scene = scene
    sim.dt = float(scene.sim.dt)


def _launched(sim) -> np.ndarray:
    """Rock ids launched so far (hit_step >= 0), sorted."""
    w, n = sim.world, sim.n_rocks
    if not hasattr(w, "hit_step"):
        return np.zeros(0, np.int64)
    hs = w.hit_step.to_numpy()[:n]
    ids = w.rock_id.to_numpy()[:n]
    return np.sort(ids[hs >= 0]).astype(np.int64)


def _n_flying(sim) -> int:
    return int(np.sum(sim.world.phase.to_numpy()[:sim.n_rocks] == FLYING))


def pin_sources() -> None:
    """Keep the source Taichi compiles kernels from fixed for this run. Taichi reads a kernel's source (through
    linecache) when it first compiles it, so a file edited during a long run would mix two versions of the
    engine; pinned entries (no mtime) are never re-read. Each kernel's def line is checked against it."""
    import linecache

    for name, mod in list(sys.modules.items()):
        if not (name == "taichi_rocks" or name.startswith("taichi_rocks.")):
            continue
        f = getattr(mod, "__file__", None)
        if not f or not f.endswith(".py"):
            continue
        try:
            text = Path(f).read_text()
        except OSError:
            continue
        lines = text.splitlines(keepends=True)
        for obj in vars(mod).values():
            fn = getattr(obj, "__wrapped__", None)
            if _is_kernel(obj) and fn is not None and getattr(fn, "__module__", None) == name:
                first = fn.__code__.co_firstlineno
                window = "".join(lines[max(0, first - 1):first + 2])
                if f"def {fn.__name__}" not in window:
                    raise RuntimeError(f"{f} changed since it was imported ({fn.__name__} moved); run the "
                                       "benchmark again")
        linecache.cache[f] = (len(text), None, lines, f)


def _loadavg():
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (OSError, AttributeError):
        return None


def _machine(arch: str) -> dict:
    model = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    mem = None
    try:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 1e9
    except (ValueError, OSError, AttributeError):
        pass
    import scipy

    info = {"cpu_model": model, "logical_cores": os.cpu_count(), "usable_cores": usable,
            "memory_gb": round(mem, 1) if mem else None, "python": platform.python_version(),
            "platform": platform.platform(), "taichi": ".".join(str(x) for x in ti.__version__),
            "numpy": np.__version__, "scipy": scipy.__version__, "taichi_arch": arch,
            "taichi_threads": os.environ.get("TAICHI_ROCKS_THREADS", "default (all cores)")}
    try:
        import matplotlib

        info["matplotlib"] = matplotlib.__version__
    except ImportError:
        info["matplotlib"] = None
    return info


class Progress:
    def __init__(self, total: int, enabled):
        self.bar = None
        if enabled is not False:
            try:
                from tqdm import tqdm

                self.bar = tqdm(total=total, file=sys.stderr, disable=None if enabled is None else False,
                                unit="task", dynamic_ncols=True)
            except ImportError:
                self.bar = None

    def __call__(self, desc: str, n: int = 1):
        if self.bar is not None:
            self.bar.set_description(desc[:48])
            self.bar.update(n)

    def note(self, desc: str):
        if self.bar is not None:
            self.bar.set_description(desc[:48])
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.n = self.bar.total
            self.bar.refresh()
            self.bar.close()


# ================================================================================================ scenes
BASE = {"name": "bench", "seed": 3, "vehicle": [{"name": "player"}]}


def base_scene():
    return parse_scene(dict(BASE), source="<bench>", default_name="bench")


def _fleet_slots(k: int, radius: float) -> list:
    """Body centres of k vehicles spread over a bed of this radius (the first at the centre)."""
    reach = 0.7 * radius
    cands = [(x, y) for x in np.arange(-28.0, 28.1, 7.0) for y in np.arange(-27.0, 27.1, 3.0)
             if math.hypot(x, y) <= reach]
    cands.sort(key=lambda p: (math.hypot(*p), p[0], p[1]))
    if len(cands) < k:
        raise ValueError(f"{k} vehicles do not fit a bed of radius {radius} m")
    return cands[:k]


def fleet_scene(n: int, t_rear: int, radius: float, overrides=None):
    """N rocks, T/2 splashing vehicles spread over the bed, all at 25 m/s along +x (the bed follows the first)."""
    k = max(1, t_rear // 2)
    vehicles = [{"name": "player" if i == 0 else f"v{i}",
                 "path": {"points": [[float(x), float(y)], [float(x) + 5000.0, float(y)]], "speed": 25.0}}
                for i, (x, y) in enumerate(_fleet_slots(k, radius))]
    s = scene_with(base_scene(), {"name": f"bench-n{n}-t{2 * k}", "bed.rocks": int(n), "bed.radius": float(radius),
                                  "vehicle": vehicles})
    return _with(s, overrides or {})


def _with(scene, overrides: dict):
    fixed = {}
    for k, v in overrides.items():
        if isinstance(v, str) and v.endswith("N") and k.endswith("table_size"):
            v = max(1, int(round(float(v[:-1]) * scene.bed.rocks)))
        fixed[k] = v
    return scene_with(scene, fixed) if fixed else scene


def lane_y(i: int, count: int) -> float:
    return 3.0 * (i - 0.5 * (count - 1))


def probe_scene(cfg: Config, overrides=None):
    """Lanes: a parked, non-splashing anchor that the bed follows, and one vehicle per speed in its own lane,
    straight along +x; no recycling, no ground contact. The linear-drag viscosity makes tau = 1 s for r = 3 cm."""
    rho = 2600.0
    mu = (0.03 ** 2) * rho / (4.5 * TAU_LINEAR)
    x0 = -0.5 * max(cfg.speeds) * cfg.run_time
    vehicles = [{"name": "anchor", "splash": False, "path": {"points": [[0.0, 0.0], [1.0, 0.0]], "speed": 0.0}}]
    for i, v in enumerate(cfg.speeds):
        y = lane_y(i, len(cfg.speeds))
        vehicles.append({"name": f"lane{i}", "path": {"points": [[x0, y], [x0 + 5000.0, y]], "speed": float(v)}})
    s = scene_with(base_scene(), {"name": "bench-probe", "seed": 7, "world.air_viscosity": mu,
                                  "bed.rocks": cfg.probe_n, "bed.radius": cfg.probe_radius, "bed.density": rho,
                                  "bed.follow": "anchor", "camera.follow": "anchor",
                                  "effects.recycle": False, "effects.ground": "none", "vehicle": vehicles})
    return _with(s, overrides or {})


# ================================================================================================ building
class Built:
    """A Simulation plus its build time (construction + first step = compile)."""

    def __init__(self, scene, arch, label):
        from .simulation import Simulation

        t = time.perf_counter()
        self.sim = Simulation(scene, arch=arch)
        _sync()
        self.ctor_s = time.perf_counter() - t
        self.label = label
        self.first_step_s = None

    def step_timed(self, n: int) -> list:
        out = []
        for _ in range(n):
            _sync()
            t = time.perf_counter()
            self.sim.step()
            _sync()
            out.append(time.perf_counter() - t)
        if self.first_step_s is None and out:
            self.first_step_s = out[0]
        return out


# ================================================================================================ closed forms
def exact_gravity(x0, v0, t):
    t = np.asarray(t)[:, None]
    return x0 + v0 * t + 0.5 * np.array([0.0, 0.0, -G]) * t ** 2


def exact_linear(x0, v0, tau, t):
    t = np.asarray(t)[:, None]
    vinf = np.array([0.0, 0.0, -G * tau])
    return x0 + vinf * t - (v0 - vinf) * tau * np.expm1(-t / tau)


def exact_quadratic_vertical(z0, w0, vt, t):
    """Height of a rock thrown straight up at w0 > 0 with a = -g - (g / vt^2) |v| v."""
    t = np.asarray(t, float)
    th0 = math.atan(w0 / vt)
    ta = vt * th0 / G
    za = z0 - vt * vt / G * math.log(math.cos(th0))
    rise = z0 + vt * vt / G * np.log(np.cos(th0 - G * np.minimum(t, ta) / vt) / math.cos(th0))
    fall = za - vt * vt / G * np.log(np.cosh(G * np.maximum(t - ta, 0.0) / vt))
    return np.where(t <= ta, rise, fall)


# ================================================================================================ 1a integrator x dt
def _test_cases(sim):
    """Test rocks per drag case: (x0, v0, r), and a function giving the exact positions."""
    par = sim.world.par.to_numpy().astype(np.float64)
    from .world import Par

    lin, quad = float(par[Par.LINEAR_DRAG]), float(par[Par.QUAD_DRAG])
    g = float(par[Par.GRAVITY])
    assert abs(g - G) < 1e-4
    cases = {}
    x0 = np.array([0.0, 0.0, 1.0])
    grav = [(x0, np.array([12.0, 2.0, 15.0]), 0.03), (x0 + [1.0, 1.0, 0.0], np.array([-6.0, 4.0, 9.0]), 0.02),
            (x0 - [1.0, 0.0, 0.0], np.array([3.0, 0.0, 22.0]), 0.05)]
    cases["gravity"] = (grav, lambda x, v, r, t: exact_gravity(x, v, t), {})
    lin_rocks = [(x0, np.array([10.0, 0.0, 15.0]), r) for r in (0.015, 0.03, 0.05)]
    taus = [r * r / lin for r in (0.015, 0.03, 0.05)]
    cases["linear"] = (lin_rocks, lambda x, v, r, t: exact_linear(x, v, r * r / lin, t), {"tau_s": taus})
    quad_rocks = [(x0, np.array([0.0, 0.0, 20.0]), r) for r in (0.015, 0.03, 0.05)]
    vts = [math.sqrt(G * r / quad) for r in (0.015, 0.03, 0.05)]

    def q_exact(x, v, r, t):
        z = exact_quadratic_vertical(x[2], v[2], math.sqrt(G * r / quad), t)
        return np.stack([np.full_like(z, x[0]), np.full_like(z, x[1]), z], axis=1)

    cases["quadratic"] = (quad_rocks, q_exact, {"terminal_speed_m_s": vts, "launch_speed_m_s": 20.0})
    return cases


class DirectFlight:
    """Fly chosen rocks (memory slots 0..K-1) by calling rock_pass with flight only and every other pass
    off; the rock loop is limited to those K slots (ipar N_ROCKS) while it runs and restored after."""

    def __init__(self, sim, recorded):
        self.sim = sim
        self.rec = recorded["rock_pass"]
        self.kernel = simulation.rock_pass

    def run(self, x0_local, v0, radius, dt, integrator, drag, duration=ACC_T, gravity=True):
        sim, w = self.sim, self.sim.world
        k = len(x0_local)
        npr = w.np_real()
        pos, vel, rad, ph = (getattr(w, f).to_numpy() for f in ("pos", "vel", "radius", "phase"))
        saved = (pos.copy(), vel.copy(), rad.copy(), ph.copy())
        pos[:k] = np.asarray(x0_local, np.float64).astype(npr)
        vel[:k] = np.asarray(v0, np.float64).astype(npr)
        rad[:k] = np.asarray(radius, np.float64).astype(npr)
        ph[:k] = FLYING
        w.pos.from_numpy(pos)
        w.vel.from_numpy(vel)
        w.radius.from_numpy(rad)
        w.phase.from_numpy(ph)
        n_saved = int(w.ipar[IPar.N_ROCKS])
        w.ipar[IPar.N_ROCKS] = k
        steps = int(round(duration / dt))
        every = int(round(SAMPLE_EVERY / dt))
        assert abs(every * dt - SAMPLE_EVERY) < 1e-9 and abs(steps * dt - duration) < 1e-9, dt
        samples_t, samples_x = [], []
        args, kwargs = self.rec
        bound = inspect.signature(self.kernel).bind(*args, **kwargs)
        bound.arguments.update(dt=float(dt), step=0, flight=True, recycle=False, count=False, integrator=integrator,
                               gravity=gravity, drag=drag, ground="none")
        call = list(bound.args)
        i_step = list(inspect.signature(self.kernel).parameters).index("step")
        kernel = self.kernel
        try:
            for s in range(1, steps + 1):
                call[i_step] = s
                kernel(*call)
                if s % every == 0:
                    samples_t.append(s * dt)
                    samples_x.append(w.pos.to_numpy()[:k].astype(np.float64))
        finally:
            w.ipar[IPar.N_ROCKS] = n_saved
            for f, a in zip(("pos", "vel", "radius", "phase"), saved):
                getattr(w, f).from_numpy(a)
        return np.array(samples_t), np.stack(samples_x, axis=1)  # (k, samples, 3)


def integrator_sweep(sims: dict, recs: dict, cfg: Config, prog) -> dict:
    rows = []
    meta = {}
    for prec, sim in sims.items():
        fl = DirectFlight(sim, recs[prec])
        cases = _test_cases(sim)
        for drag in DRAGS:
            case = CASE_OF_DRAG[drag]
            rocks, exact, info = cases[case]
            meta[case] = info
            x0 = np.array([r[0] for r in rocks])
            v0 = np.array([r[1] for r in rocks])
            rad = np.array([r[2] for r in rocks])
            for integ in INTEGRATORS:
                if prec == "f64" and integ == "symplectic_euler":
                    continue  # first order: its error never comes near the f64 level
                for dt in cfg.acc_dts:
                    t, xs = fl.run(x0, v0, rad, dt, integ, drag)
                    err = 0.0
                    for j in range(len(rocks)):
                        r_stored = float(np.asarray(rad[j]).astype(sim.world.np_real()))
                        ref = exact(x0[j], v0[j], r_stored, t)
                        err = max(err, float(np.max(np.linalg.norm(xs[j] - ref, axis=1))))
                    rows.append({"precision": prec, "integrator": integ, "case": case, "drag": drag, "dt": dt,
                                 "max_error_m": err})
                prog(f"flight {prec} {case} {integ}")
    return {"rows": rows, "cases": meta, "flight_s": ACC_T, "sampled_every_s": SAMPLE_EVERY,
            "closed_forms": {
                "gravity": "x0 + v0 t - g t^2/2 z",
                "linear": "x0 + v_inf t + (v0 - v_inf) tau (1 - exp(-t/tau)), v_inf = -g tau z, tau = r^2 / L",
                "quadratic": "vertical: rise v = v_t tan(atan(v0/v_t) - g t/v_t), fall v = -v_t tanh(g (t-t_a)/v_t)"}}


def flight_cost(built: Built, recorded, pairs, reps: int, prog, effects: bool = True) -> dict:
    """ms per flight pass with every rock flying, per (integrator, drag) (gravity on, ground contact off),
    plus, with ``effects``, gravity off and ground bounce variants; all variants timed interleaved."""
    sim = built.sim
    w = sim.world
    n = sim.n_rocks
    rng = np.random.default_rng(11)
    ph = w.phase.to_numpy()
    ph[:n] = FLYING
    vel = w.vel.to_numpy()
    vel[:n, 0] = rng.uniform(-5, 5, n)
    vel[:n, 1] = rng.uniform(-2, 2, n)
    vel[:n, 2] = rng.uniform(2, 15, n)
    w.vel.from_numpy(vel)
    w.phase.from_numpy(ph)
    variants = [(i, d, True, "none") for i, d in pairs]
    if effects:
        for v in (("symplectic_euler", "none", False, "none"), ("symplectic_euler", "none", True, "none"),
                  ("symplectic_euler", "quadratic", True, "none"), ("symplectic_euler", "quadratic", True, "bounce")):
            if v not in variants:
                variants.append(v)
    fns = {}
    for v in variants:
        integ, drag, grav, ground = v
        fns[v] = (lambda integ=integ, drag=drag, grav=grav, ground=ground: call_with(
            simulation.rock_pass, recorded["rock_pass"], dt=sim.dt, flight=True, recycle=False, count=False,
            integrator=integ, gravity=grav, drag=drag, ground=ground))
        fns[v]()
        fns[v]()  # compile, warm
        prog(f"flight cost {integ} {drag}")
    times = {v: [] for v in variants}
    for _ in range(max(3, reps)):
        for v, fn in fns.items():
            _sync()
            t = time.perf_counter()
            fn()
            _sync()
            times[v].append(time.perf_counter() - t)
    med = {v: 1e3 * float(np.median(ts)) for v, ts in times.items()}
    out = {}
    for (integ, drag, grav, ground), ms in med.items():
        if grav and ground == "none":
            out.setdefault(integ, {})[drag] = ms
    res = {"n_rocks": n, "ms_per_step": out, "note": "every rock flying, flight pass alone, variants interleaved"}
    if effects:
        se = lambda d, g, gr: med[("symplectic_euler", d, g, gr)]
        res["effects_all_flying_ms"] = {
            "gravity (symplectic Euler, no drag)": se("none", True, "none") - se("none", False, "none"),
            "quadratic drag (symplectic Euler)": se("quadratic", True, "none") - se("none", True, "none"),
            "ground contact bounce (symplectic Euler, quadratic)": se("quadratic", True, "bounce")
                                                                 - se("quadratic", True, "none")}
    return res


# ================================================================================================ 1b detection
def _rect_dist2(c, a0, a1, b0):
    """Squared distance of points c (n,3) to the parallelogram {a0 + u (a1 - a0) + v (b0 - a0)}, for
    orthogonal edges (a straight horizontal path and a vertical ray: a rectangle)."""
    e1, e2 = a1 - a0, b0 - a0
    l1, l2 = float(e1 @ e1), float(e2 @ e2)
    assert abs(float(e1 @ e2)) <= 1e-9 * max(l1 * l2, 1e-30) ** 0.5 + 1e-12
    d = c - a0
    u = np.clip(d @ e1 / l1, 0.0, 1.0) if l1 > 0 else np.zeros(len(c))
    v = np.clip(d @ e2 / l2, 0.0, 1.0) if l2 > 0 else np.zeros(len(c))
    q = a0 + u[:, None] * e1 + v[:, None] * e2
    return np.sum((c - q) ** 2, axis=1)


def _t0_state(sim) -> dict:
    w, n = sim.world, sim.n_rocks
    return {"ids": w.rock_id.to_numpy()[:n], "world": w.pos.to_numpy()[:n].astype(np.float64) + sim.origin,
            "radius": w.radius.to_numpy()[:n].astype(np.float64),
            "tires0": sim.fleet.rear_tires(sim.fleet.poses(0.0))}


def detection_result(built: Built, t0: dict, times: list, cfg: Config, label: str) -> dict:
    """Recall per lane (speed) against the analytic sweep of each rear tire's ray over [0, t_end]."""
    sim = built.sim
    t_end = sim.time
    t1 = sim.fleet.rear_tires(sim.fleet.poses(t_end))
    hit = set(_launched(sim).tolist())
    names = [sim.fleet.names[i] for i in sim.fleet.splashing]
    per_speed, all_ref = [], set()
    rad, ids = t0["radius"], t0["ids"]
    for li, v in enumerate(cfg.speeds):
        vi = names.index(f"lane{li}")
        ref = set()
        for side in (0, 1):
            tt = 2 * vi + side
            d2 = _rect_dist2(t0["world"], t0["tires0"].center[tt], t1.center[tt], t0["tires0"].bottom[tt])
            ref |= set(ids[d2 <= rad * rad].tolist())
        all_ref |= ref
        found = len(ref & hit)
        per_speed.append({"speed_m_s": v, "contacts": len(ref), "found": found,
                          "recall": found / len(ref) if ref else float("nan"),
                          "step_displacement_m": v * sim.dt / max(1, sim.plan.substeps)})
    skip = min(3, max(0, len(times) - 1))
    st = _stats(times[skip:])
    return {"mode": label, "dt": sim.dt, "substeps": sim.plan.substeps, "swept": sim.plan.swept,
            "per_speed": per_speed, "false_positives": len(hit - all_ref), "launched": len(hit),
            "steps": len(times), "step_ms": st["median_ms"], "step_stats": st, "n_rocks": sim.n_rocks,
            "tires": len(names) * 2}


def detection_runs(builds: dict, cfg: Config, prog) -> dict:
    """Run the lanes scenes in lockstep (one step of each in turn, so a busy machine slows all alike)."""
    t0 = {k: _t0_state(b.sim) for k, b in builds.items()}
    steps = {k: int(round(cfg.run_time / b.sim.dt)) for k, b in builds.items()}
    times = {k: [] for k in builds}
    for s in range(max(steps.values())):
        for k, b in builds.items():
            if s < steps[k]:
                times[k] += b.step_timed(1)
    out = {k: detection_result(b, t0[k], times[k], cfg, k) for k, b in builds.items()}
    prog("detection runs")
    return out


# ================================================================================================ 1c precision
def precision_runs(sims: dict, recs: dict, cfg: Config, prog) -> dict:
    """Flight of launched rocks stored as the engine stores them, at several distances from the origin."""
    from .simulation import ORIGIN_SNAP

    launches = []  # (offset from the launch point reference, v0, r): vehicle at 25 m/s, three release angles
    spin = 25.0 * 1.15
    for k, (alpha, r) in enumerate(((10.0, 0.015), (22.0, 0.03), (35.0, 0.05))):
        a = math.radians(alpha)
        launches.append((np.array([-1.45, 0.8 if k % 2 else -0.8, r]),
                         np.array([25.0 - spin * math.cos(a), 0.3 * (k - 1), 0.65 * spin * math.sin(a)]), r))
    configs = []
    for prec in sims:
        for origin in ("world", "floating"):
            configs.append((prec, origin))
    results = {}
    trajectories = {}
    for prec, sim in sims.items():
        fl = DirectFlight(sim, recs[prec])
        x0, v0, rr, keys = [], [], [], []
        for origin in ("world", "floating"):
            for d in cfg.distances:
                o = 0.0 if origin == "world" else round(d / ORIGIN_SNAP) * ORIGIN_SNAP
                for j, (off, v, r) in enumerate(launches):
                    x0.append(np.array([d + off[0] - o, off[1], off[2]]))
                    v0.append(v)
                    rr.append(r)
                    keys.append((origin, d, j, o))
        t, xs = fl.run(np.array(x0), np.array(v0), np.array(rr), sim.dt, sim.plan.integrator, sim.plan.drag)
        for (origin, d, j, o), x in zip(keys, xs):
            rel = x + np.array([o, 0.0, 0.0]) - np.array([d, 0.0, 0.0])  # world - (d, 0, 0), in f64
            trajectories[(prec, origin, d, j)] = rel
        prog(f"precision {prec}")
    ref = {j: trajectories[("f64", "floating", 0.0, j)] for j in range(len(launches))}
    for prec, origin in configs:
        errs = []
        for d in cfg.distances:
            e = max(float(np.max(np.linalg.norm(trajectories[(prec, origin, d, j)] - ref[j], axis=1)))
                    for j in range(len(launches)))
            errs.append(e)
        results[f"{prec} {origin}"] = {"precision": prec, "origin": origin, "max_error_m": errs}
    return {"distances_m": list(cfg.distances), "configs": results,
            "reference": "f64 flight launched at the origin (same integrator, dt, drag)",
            "note": "rock positions stored as the engine stores them (local = world - origin), flown by rock_pass; "
                    "origin shifts of the floating origin (exact multiples of 64 m) are not exercised"}


# ================================================================================================ 2 peers
def _ray_samples(rays: np.ndarray, r_max: float):
    """Points along each ray (spacing <= r_max) and a query radius that finds every sphere of radius
    <= r_max touching the segment."""
    pts, q = [], 0.0
    for a, b in rays:
        L = float(np.linalg.norm(b - a))
        m = max(1, int(math.ceil(L / r_max)))
        s = L / m
        q = max(q, r_max + 0.5 * s)
        f = (np.arange(m) + 0.5) / m
        pts.append(a[None, :] + f[:, None] * (b - a)[None, :])
    return np.concatenate(pts).astype(np.float32), m, q


def numpy_brute(pos, rad, rays) -> np.ndarray:
    """Segment-sphere test of every rock against every tire ray (vectorised, float32)."""
    hit = np.zeros(len(pos), bool)
    r2 = rad * rad
    for a, b in rays:
        d = b - a
        dd = float(d @ d)
        w = pos - a
        t = np.clip((w @ d) / dd, 0.0, 1.0) if dd > 0 else np.zeros(len(pos), np.float32)
        e = w - t[:, None] * d
        hit |= np.einsum("ij,ij->i", e, e) <= r2
    return hit


def _exact_on(cand, pos, rad, rays):
    hit = np.zeros(len(cand), bool)
    c = pos[cand]
    r2 = rad[cand] ** 2
    for a, b in rays:
        d = b - a
        dd = float(d @ d)
        w = c - a
        t = np.clip((w @ d) / dd, 0.0, 1.0) if dd > 0 else np.zeros(len(c), np.float32)
        e = w - t[:, None] * d
        hit |= np.einsum("ij,ij->i", e, e) <= r2
    return cand[hit]


def kdtree_query(pos, rad, rays, r_max):
    from scipy.spatial import cKDTree

    tree = cKDTree(pos, leafsize=16, compact_nodes=False, balanced_tree=False)
    samples, _, q = _ray_samples(rays, r_max)
    lists = tree.query_ball_point(samples, q, workers=-1)
    cand = np.unique(np.concatenate([np.asarray(x, np.int64) for x in lists])) if len(lists) else np.zeros(0, int)
    return _exact_on(cand, pos, rad, rays)


class WarpPeer:
    """NVIDIA Warp HashGrid build + a kernel that queries it around ray samples (CPU device)."""

    def __init__(self):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            import warp as wp  # prints a CUDA-driver warning on machines without one

            wp.config.quiet = True
            wp.init()
        self.wp = wp
        self.version = wp.__version__

        @wp.kernel
        def query(grid: wp.uint64, pts: wp.array(dtype=wp.vec3), rad: wp.array(dtype=float),
                  a: wp.array(dtype=wp.vec3), b: wp.array(dtype=wp.vec3), nsamp: int, qr: float,
                  hits: wp.array(dtype=wp.int32), stamp: int):
            tid = wp.tid()
            ray = tid // nsamp
            s = tid - ray * nsamp
            pa = a[ray]
            pb = b[ray]
            d = pb - pa
            p = pa + d * ((float(s) + 0.5) / float(nsamp))
            dd = wp.dot(d, d)
            qq = wp.hash_grid_query(grid, p, qr)
            idx = int(0)
            while wp.hash_grid_query_next(qq, idx):
                c = pts[idx]
                t = float(0.0)
                if dd > 0.0:
                    t = wp.clamp(wp.dot(c - pa, d) / dd, 0.0, 1.0)
                e = c - (pa + d * t)
                r = rad[idx]
                if wp.dot(e, e) <= r * r:
                    hits[idx] = stamp

        self.kernel = query
        self.grid = wp.HashGrid(128, 128, 128, device="cpu")
        self.stamp = 0

    def prepare(self, pos, rad, rays, r_max):
        wp = self.wp
        self.pts = wp.array(np.ascontiguousarray(pos, np.float32), dtype=wp.vec3, device="cpu")
        self.rad = wp.array(np.ascontiguousarray(rad, np.float32), dtype=float, device="cpu")
        self.hits = wp.zeros(len(pos), dtype=wp.int32, device="cpu")
        a = np.ascontiguousarray(rays[:, 0], np.float32)
        b = np.ascontiguousarray(rays[:, 1], np.float32)
        self.a = wp.array(a, dtype=wp.vec3, device="cpu")
        self.b = wp.array(b, dtype=wp.vec3, device="cpu")
        _, self.nsamp, self.qr = _ray_samples(rays, r_max)
        self.n_rays = len(rays)

    def run(self):
        if self.stamp == 0:  # the first launch compiles the module and says so on stdout
            with contextlib.redirect_stdout(io.StringIO()):
                self._run()
        else:
            self._run()

    def _run(self):
        wp = self.wp
        self.stamp += 1
        self.grid.build(self.pts, self.qr)
        wp.launch(self.kernel, dim=self.n_rays * self.nsamp,
                  inputs=[self.grid.id, self.pts, self.rad, self.a, self.b, self.nsamp, float(self.qr),
                          self.hits, self.stamp], device="cpu")
        wp.synchronize()

    def hit_ids(self):
        return np.flatnonzero(self.hits.numpy() == self.stamp)


@ti.kernel
def _floor_pass(pos: ti.template(), vel: ti.template(), n: ti.i32, dt: ti.f32, g: ti.f32, zmin: ti.f32):
    """The streaming floor: one fused read-modify-write of position and velocity (gravity + ground clamp)."""
    for i in range(n):
        v = vel[i]
        v[2] -= g * dt
        p = pos[i] + v * dt
        if p[2] < zmin:
            p[2] = zmin
            v = ti.Vector([0.0, 0.0, 0.0])
        pos[i] = p
        vel[i] = v


class Floor:
    """The streaming floor on fields of its own (same layout as the rock fields), loaded from a state."""

    def __init__(self, capacity: int):
        self.cap = capacity
        self.n = 0
        self.pos = ti.Vector.field(3, ti.f32, shape=capacity)
        self.vel = ti.Vector.field(3, ti.f32, shape=capacity)

    def load(self, pos, vel):
        n = len(pos)
        p = np.zeros((self.cap, 3), np.float32)
        v = np.zeros((self.cap, 3), np.float32)
        p[:n], v[:n] = pos, vel
        self.pos.from_numpy(p)
        self.vel.from_numpy(v)
        self.n = n

    def run(self):
        _floor_pass(self.pos, self.vel, self.n, 0.002, 9.81, 0.0)


def call_named(kernel, **values):
    """Call a kernel with its arguments picked by parameter name (e.g. w, center, step, swept, ground)."""
    names = list(inspect.signature(kernel).parameters)
    missing = [n for n in names if n not in values]
    if missing:
        raise KeyError(f"{getattr(kernel, '__name__', kernel)}: no value for parameter(s) {missing}")
    return kernel(*[values[n] for n in names])


def separate_passes(sim, reps: int) -> dict:
    """Each pass on its own, after a normal step each round: rock_pass with one flag at a time (the other
    arguments as the step passed them), then clear, count, scan, scatter, trace_rays, tire_pass. The counts
    are cleared again at the end (whichever end of the step the engine clears them at)."""
    p = sim.plan
    out: dict[str, list] = {}

    def timed(name, fn):
        _sync()
        t = time.perf_counter()
        r = fn()
        _sync()
        out.setdefault(name, []).append(time.perf_counter() - t)
        return r

    rp = simulation.rock_pass
    for _ in range(reps + 1):
        rec = record_step(sim)  # a normal step; its arguments (bed centre, mask origin, step) are current
        rec_rp = rec["rock_pass"]
        w = sim.world
        named = dict(w=w, center=p.center, step=sim.step_count, swept=p.swept, ground=p.ground)
        if p.flight:
            timed("flight", lambda: call_with(rp, rec_rp, flight=True, recycle=False, count=False))
        if p.recycle:
            timed("recycle", lambda: call_with(rp, rec_rp, flight=False, recycle=True, count=False))
        if p.splash:
            timed("hash clear", lambda: call_named(hashgrid.clear_counts, **named))
            timed("hash count", lambda: call_with(rp, rec_rp, flight=False, recycle=False, count=True))
            timed("hash scan", lambda: call_named(hashgrid.inclusive_scan, **named))
            timed("hash scatter", lambda: call_named(hashgrid.scatter, **named))
            if not p.swept:
                timed("trace rays", lambda: call_named(tires.trace_rays, **named))
            timed("tire pass", lambda: call_named(tires.tire_pass, **named))
            call_named(hashgrid.clear_counts, **named)
    res = {k: 1e3 * float(np.median(v[1:])) for k, v in out.items()}  # the first round compiles
    if p.splash:
        res["hash build (clear+count+scan+scatter)"] = sum(res[k] for k in ("hash clear", "hash count", "hash scan",
                                                                            "hash scatter"))
    return res


@ti.kernel
def _empty_kernel():
    pass


def launch_overheads(built: Built, rec, cfg: Config) -> dict:
    """Fixed cost of a kernel call on this machine: an empty kernel, and rock_pass (its 20 arguments) over
    zero rocks; plus the host part of a step (vehicle poses, rays, mask)."""
    sim = built.sim
    w = sim.world
    out = {"empty_kernel_ms": _time(_empty_kernel, 50, warmup=2)["median_ms"]}
    n_saved = int(w.ipar[IPar.N_ROCKS])
    try:
        w.ipar[IPar.N_ROCKS] = 0
        out["rock_pass_zero_rocks_ms"] = _time(lambda: call_with(simulation.rock_pass, rec["rock_pass"], flight=False,
                                                                 recycle=False, count=False), 50, warmup=2)["median_ms"]
    finally:
        w.ipar[IPar.N_ROCKS] = n_saved
    t = sim.time
    fleet = sim.fleet
    out["vehicle_poses_and_rays_ms"] = _time(lambda: fleet.rear_tires(fleet.poses(t + 0.01)), 20,
                                             warmup=1)["median_ms"]
    return out


def in_step_profile(sim, steps: int) -> dict:
    with KernelTap(timed=True) as tap:
        times = []
        for _ in range(steps):
            t = time.perf_counter()
            sim.step()
            _sync()
            times.append(time.perf_counter() - t)
    prof = tap.grouped_ms(steps)
    total = 1e3 * float(np.mean(times))
    prof["host and launch overhead"] = max(0.0, total - sum(prof.values()))
    return {"mean_step_ms_with_syncs": total, "per_pass_ms": prof}


def reorder_cost(sim, reps: int = 3):
    if not sim.plan.reorder_every or not hasattr(sim, "_reorder"):
        return None
    return _time(lambda: sim._reorder(), reps, warmup=1)["median_ms"]


def _grid_entry(built: Built, cfg: Config, floor, warp, prog, record_hits: bool) -> dict:
    sim = built.sim
    w, n = sim.world, sim.n_rocks
    t_rear = len(sim.fleet.splashing) * 2
    e = {"n": n, "t": t_rear, "table_size": int(sim.table_size), "cell_size_m": float(sim.cell_size),
         "reorder_every": int(sim.plan.reorder_every)}
    first = built.step_timed(cfg.k_hits)
    e["launched_after_k"] = _launched(sim).tolist() if record_hits else None
    e["build_s"] = built.ctor_s + first[0]
    built.step_timed(cfg.warm)
    e["in_step"] = in_step_profile(sim, max(3, cfg.pass_reps))
    if cfg.passes_all or (n, t_rear) == tuple(cfg.main):
        e["separate_passes_ms"] = separate_passes(sim, cfg.pass_reps)
    else:
        e["separate_passes_ms"] = {}
    e["reorder_ms"] = reorder_cost(sim)
    prog(f"passes N={n} T={t_rear}")
    # one more step, then the peers on exactly this state (same rocks, same rays)
    sim.step()
    _sync()
    r_max = float(sim.scene.bed.rock_radius[1])
    pos = np.ascontiguousarray(w.pos.to_numpy()[:n], np.float32)
    vel = np.ascontiguousarray(w.vel.to_numpy()[:n], np.float32)
    rad = np.ascontiguousarray(w.radius.to_numpy()[:n], np.float32)
    hs = w.hit_step.to_numpy()[:n]
    phase = w.phase.to_numpy()[:n]
    rays = (sim.tire_rays() - sim.origin).astype(np.float32)
    ref = numpy_brute(pos, rad, rays)
    ref_ids = np.flatnonzero(ref)
    now = np.flatnonzero(hs == sim.step_count)
    p = {"check": {
        "numpy_hits": int(len(ref_ids)), "taichi_launched_this_step": int(len(now)),
        "taichi_launched_subset_of_geometric_hits": bool(np.all(ref[now])),
        "geometric_hits_not_launched_are_flying": bool(np.all(phase[np.setdiff1d(ref_ids, now)] == FLYING))}}
    kd = kdtree_query(pos, rad, rays, r_max)
    p["check"]["kdtree_equals_numpy"] = bool(np.array_equal(np.sort(kd), ref_ids))
    floor.load(pos, vel)
    if warp is not None:
        warp.prepare(pos, rad, rays, r_max)
        warp.run()
        p["check"]["warp_sym_diff_vs_numpy"] = int(len(np.setxor1d(warp.hit_ids(), ref_ids)))
    # the step, the floor and Warp interleaved: rounds of (m steps, 2 floor passes, 1-2 Warp runs)
    rounds = 5
    m = max(2, cfg.reps // rounds)
    st, fl, wa = [], [], []
    floor.run()
    for _ in range(rounds):
        st += built.step_timed(m)
        for _ in range(2):
            fl.append(_timed_call(floor.run))
        if warp is not None:
            for _ in range(2 if n <= 100_000 else 1):
                wa.append(_timed_call(warp.run))
    e["step_stats"] = _stats(st)
    e["step_ms"] = e["step_stats"]["median_ms"]
    p["floor_ms"] = _stats(fl)["median_ms"]
    p["warp_ms"] = _stats(wa)["median_ms"] if wa else None
    prog(f"step N={n} T={t_rear}")
    p["numpy_ms"] = _time(lambda: numpy_brute(pos, rad, rays), cfg.numpy_reps, warmup=0)["median_ms"]
    p["kdtree_ms"] = _time(lambda: kdtree_query(pos, rad, rays, r_max), cfg.kdtree_reps, warmup=0)["median_ms"]
    prog(f"numpy, cKDTree N={n} T={t_rear}")
    e["n_flying"] = _n_flying(sim)
    e["peers"] = p
    e["ratios"] = {"numpy_over_step": p["numpy_ms"] / e["step_ms"], "kdtree_over_step": p["kdtree_ms"] / e["step_ms"],
                   "step_over_floor": e["step_ms"] / p["floor_ms"],
                   "step_over_warp": e["step_ms"] / p["warp_ms"] if p["warp_ms"] else None}
    e["_rec"] = record_step(sim)
    e["_built"] = built
    return e


def _timed_call(fn) -> float:
    _sync()
    t = time.perf_counter()
    fn()
    _sync()
    return time.perf_counter() - t


def _ab_steps(built: Built, scene_a, scene_b, rounds: int, m: int) -> tuple:
    """Step times of ``built``'s simulation with the plans of two scenes, interleaved (``rounds`` x ``m``
    steps each, after compiling b), so that drifting machine load hits both alike. Ends on plan b."""
    swap_plan(built.sim, scene_b)
    built.step_timed(2)  # compile
    a, b = [], []
    for _ in range(rounds):
        swap_plan(built.sim, scene_a)
        a += built.step_timed(m)
        swap_plan(built.sim, scene_b)
        b += built.step_timed(m)
    return a, b


def effects_costs(main: Built, bed_only: Built, cfg: Config, prog) -> dict:
    """Cost of each effect = step with it on - step with it off, measured interleaved (A, B, A, B, ...) on
    the same simulation so that drift cancels; the splash cost comes from a bed-only scene."""
    sim = main.sim
    scene0, plan0 = sim.scene, sim.plan
    variants = {"gravity off": {"effects.gravity": False}, "drag none": {"effects.drag": "none"},
                "ground none": {"effects.ground": "none"}, "recycle off": {"effects.recycle": False}}
    rounds, m = 3, max(2, cfg.reps // 3)
    base_all = []
    out = {}
    try:
        for name, ov in variants.items():
            if name not in cfg.effects:
                continue
            a, b = _ab_steps(main, scene0, scene_with(scene0, ov), rounds, m)
            base_all += a
            ma, mb = 1e3 * float(np.median(a)), 1e3 * float(np.median(b))
            out[name] = {"step_ms": mb, "effect_cost_ms": ma - mb, "baseline_ms": ma}
            prog(f"effect {name}")
    finally:
        sim.plan, sim.scene, sim.dt = plan0, scene0, float(scene0.sim.dt)
    if not base_all:
        base_all = main.step_timed(cfg.reps)
    base = 1e3 * float(np.median(base_all))
    res = {"all on (default)": {"step_ms": base}}
    res.update(out)
    bo = bed_only.sim
    bed_only.step_timed(cfg.warm)
    scene_b = bo.scene
    a, b = _ab_steps(bed_only, scene_b, scene_with(scene_b, {"effects.recycle": False}), rounds, m)
    swap_plan(bo, scene_b)
    bed_ms, off = 1e3 * float(np.median(a)), 1e3 * float(np.median(b))
    res["splash off (bed only: recycle)"] = {"step_ms": bed_ms, "effect_cost_ms": base - bed_ms}
    res["everything off (host work only)"] = {"step_ms": off, "effect_cost_ms": None}
    res["recycle alone (bed only - everything off)"] = {"step_ms": None, "effect_cost_ms": bed_ms - off}
    res["n_flying_during_measurement"] = _n_flying(sim)
    prog("effects")
    return res


def detection_and_precision(cfg: Config, arch: str, prog) -> tuple:
    specs = [("ray", {}), ("ray (f64)", {"sim.precision": "f64"}), ("swept", {"sim.detection": "swept"})]
    if cfg.substeps_mode:
        specs.append(("ray x4 substeps", {"sim.substeps": 4}))
    builds = {}
    for key, ov in specs:
        builds[key] = Built(probe_scene(cfg, ov), arch, f"probe {key}")
        prog(f"build probe {key}")
    det = detection_runs(builds, cfg, prog)
    sims = {"f32": builds["ray"], "f64": builds["ray (f64)"]}
    recs = {k: record_step(b.sim) for k, b in sims.items()}
    build_s = {b.label: b.ctor_s + (b.first_step_s or 0.0) for b in builds.values()}
    return det, sims, recs, build_s


def _hash_section(cfg: Config, arch: str, grid_by_nt: dict, prog) -> dict:
    """Each setting: the same scene run k steps from t = 0 (launched ids compared with the default's), then
    the step timed round-robin across all settings (so a busy machine slows all alike), then each pass on
    its own."""
    n, t = cfg.hash_n, 20 if 20 in cfg.grid_t else max(cfg.grid_t)
    if (n, t) not in grid_by_nt:
        n, t = cfg.main
    default = grid_by_nt[(n, t)]
    ref = default["launched_after_k"]
    scene0 = fleet_scene(n, t, cfg.bed_radius)
    rows, built = [], {}
    for name in cfg.hash_settings:
        if name == DEFAULT_HASH:
            b = default["_built"]
            rows.append({"name": name, "launched": len(ref), "identical": True, "table_size": default["table_size"],
                         "cell_size_m": default["cell_size_m"], "build_s": default["build_s"],
                         "entries_capacity": int(getattr(b.sim.world, "entry_capacity", 0))})
            built[name] = b
            continue
        try:
            scene = _with(scene0, HASH_SETTINGS[name])
        except Exception as exc:  # a setting the scene format does not have (any more)
            rows.append({"name": name, "error": f"{type(exc).__name__}: {exc}".splitlines()[0]})
            prog(f"hash {name}")
            continue
        b = Built(scene, arch, name)
        first = b.step_timed(cfg.k_hits)
        got = _launched(b.sim).tolist()
        rows.append({"name": name, "launched": len(got), "identical": got == ref, "table_size": int(b.sim.table_size),
                     "cell_size_m": float(b.sim.cell_size), "build_s": b.ctor_s + first[0],
                     "entries_capacity": int(getattr(b.sim.world, "entry_capacity", 0)),
                     "_first_ms": 1e3 * float(np.median(first[1:] or first))})
        built[name] = b
        prog(f"hash {name}")
    # round-robin step timing: each round ~0.1-0.2 s of steps per setting (at least one step)
    live = [r for r in rows if "error" not in r]
    est = {r["name"]: r.get("_first_ms", default["step_ms"]) for r in live}
    m = {k: max(1, min(cfg.reps // 2, int(150.0 / max(v, 1e-3)))) for k, v in est.items()}
    times = {r["name"]: [] for r in live}
    for k in built.values():
        k.step_timed(1)
    for _ in range(4):
        for name, b in built.items():
            times[name] += b.step_timed(m[name])
    for r in live:
        b = built[r["name"]]
        st = _stats(times[r["name"]])
        r["step_ms"], r["step_stats"] = st["median_ms"], st
        r["in_step"] = in_step_profile(b.sim, 2)
        r["separate_passes_ms"] = separate_passes(b.sim, max(2, cfg.pass_reps // 2))
        r.pop("_first_ms", None)
    prog("hash timing")
    ok = all(r.get("identical", True) for r in live)
    return {"n": n, "t": t, "k_steps": cfg.k_hits, "settings": rows, "identical": ok,
            "verdict": "PASS" if ok else "FAIL"}


# ================================================================================================ presets
def _recall_model(det: dict):
    """Recall of single-ray detection as a function of the ray's displacement per evaluation s (m),
    from the ray and ray-with-substeps runs; monotone non-increasing; 1/s tail beyond the data."""
    pts = []
    for key in ("ray", "ray x4 substeps"):
        if key in det:
            for row in det[key]["per_speed"]:
                if row["contacts"]:
                    pts.append((row["step_displacement_m"], row["recall"]))
    pts.sort()
    s = np.array([p[0] for p in pts])
    r = np.minimum.accumulate(np.array([p[1] for p in pts]))

    def model(x):
        if not len(s):
            return float("nan")
        if x <= s[0]:
            return float(r[0])
        if x >= s[-1]:
            return float(r[-1] * s[-1] / x)
        return float(np.interp(math.log(x), np.log(s), r))

    return model


def choose_presets(res: dict) -> list:
    acc = res["accuracy"]["integrator_dt"]["rows"]
    det = res["accuracy"]["detection"]["modes"]
    prec = res["accuracy"]["precision"]["configs"]
    cost = res["accuracy"]["preset_costs"]
    model = _recall_model(det)
    fc = res["accuracy"]["flight_cost"]["ms_per_step"]
    se = fc.get("symplectic_euler", {}).get("quadratic")
    integ_extra = {i: max(0.0, fc[i]["quadratic"] - se) for i in fc if se is not None and "quadratic" in fc[i]}
    swept_recall = min((r["recall"] for r in det["swept"]["per_speed"] if r["contacts"]), default=float("nan"))
    far = max(res["accuracy"]["precision"]["distances_m"])
    prec_err = {p: prec[f"{p} floating"]["max_error_m"][-1] for p in ("f32", "f64") if f"{p} floating" in prec}
    err = {}
    for row in acc:
        if row["case"] in ("gravity", "quadratic"):
            key = (row["precision"], row["integrator"], row["dt"])
            err[key] = max(err.get(key, 0.0), row["max_error_m"])
    out = []
    for name, e_target, r_target, q_target in PRESET_TARGETS:
        best = None
        for (p, integ, dt), e in err.items():
            total_e = max(e, prec_err.get(p, 0.0))
            if total_e > e_target or V_LAUNCH_MAX * dt > q_target * (1 + 1e-9):
                continue
            for detection, substeps in (("ray", 1), ("ray", 2), ("ray", 4), ("ray", 8), ("swept", 1)):
                recall = swept_recall if detection == "swept" else model(PRESET_SPEED * dt / substeps)
                if not recall >= r_target:
                    continue
                c = cost["step_ms"].get(detection)
                if c is None:
                    continue
                c += integ_extra.get(integ, 0.0)
                if substeps > 1:
                    if cost["substep_ms_per_extra"] is None:
                        continue
                    c += cost["substep_ms_per_extra"] * (substeps - 1)
                if p == "f64":
                    c *= cost["f64_factor"]
                per_s = c / dt
                cand = {"name": name, "target_flight_error_m": e_target, "target_recall": r_target,
                        "target_launch_time_bound_m": q_target, "launch_time_bound_m": V_LAUNCH_MAX * dt,
                        "integrator": integ, "dt": dt, "detection": detection, "substeps": substeps,
                        "precision": p, "origin": "floating", "flight_error_m": e,
                        "precision_error_far_m": prec_err.get(p), "far_m": far, "error_m": total_e,
                        "recall_at_60": recall, "recall_source": "measured" if detection == "swept" else "modelled",
                        "step_ms": c, "ms_per_simulated_s": per_s}
                rank = per_s * (1.05 if p == "f64" else 1.0)  # prefer f32 unless f64 is clearly cheaper
                if best is None or rank < best["_rank"]:
                    best = dict(cand, _rank=rank)
        if best:
            best.pop("_rank")
        out.append(best or {"name": name, "target_flight_error_m": e_target, "target_recall": r_target,
                            "target_launch_time_bound_m": q_target,
                            "none": "no measured setting meets this target"
                                    + ("" if any(k[0] == "f64" for k in err) else " (f64 flights are measured "
                                                                                  "in the full run only)")})
    return out


def preset_costs(main: Built, cfg: Config, det: dict, prog) -> dict:
    """Step cost of the main scene with ray and with swept detection, interleaved (plan swaps: the fields do not
    change); the integrators' extra cost is taken from the flight pass with every rock flying (worst case)."""
    sim = main.sim
    scene0, plan0 = sim.scene, sim.plan
    scenes = {d: scene_with(scene0, {"sim.detection": d}) for d in ("ray", "swept")}
    times = {d: [] for d in scenes}
    m = max(2, cfg.reps // 4)
    try:
        for d, sc in scenes.items():
            swap_plan(sim, sc)
            main.step_timed(2)  # compile
        for _ in range(4):
            for d, sc in scenes.items():
                swap_plan(sim, sc)
                times[d] += main.step_timed(m)
        prog("preset costs")
    finally:
        sim.plan, sim.scene, sim.dt = plan0, scene0, float(scene0.sim.dt)
    out = {d: 1e3 * float(np.median(ts)) for d, ts in times.items()}
    t_probe = det["ray"]["tires"]
    t_main = len(sim.fleet.splashing) * 2
    extra = None
    if "ray x4 substeps" in det:
        extra = max(0.0, (det["ray x4 substeps"]["step_ms"] - det["ray"]["step_ms"]) / 3.0 * t_main / max(1, t_probe))
    f64 = det["ray (f64)"]["step_ms"] / det["ray"]["step_ms"]
    return {"step_ms": out, "substep_ms_per_extra": extra, "f64_factor": f64, "n": sim.n_rocks,
            "t": t_main, "note": "main scene step (symplectic Euler) + the integrator's extra flight cost with "
                                 "every rock flying; substeps and f64 scaled from the lanes scene"}


def validate_presets(presets: list, cfg: Config, arch: str, prog) -> None:
    """Run the lanes scene with each preset's settings and measure its recall at every speed."""
    for p in presets:
        if "integrator" not in p:
            continue
        ov = {"sim.dt": p["dt"], "sim.integrator": p["integrator"], "sim.detection": p["detection"],
              "sim.substeps": p["substeps"], "sim.precision": p["precision"]}
        b = Built(probe_scene(cfg, ov), arch, f"preset {p['name']}")
        r = detection_runs({p["name"]: b}, cfg, lambda *a: None)[p["name"]]
        top = [x for x in r["per_speed"] if x["speed_m_s"] == max(cfg.speeds)]
        p["validated_recall_at_60"] = top[0]["recall"] if top else None
        p["validated_recall_all_speeds"] = [x["recall"] for x in r["per_speed"]]
        prog(f"validate {p['name']}")


# ================================================================================================ targets
def evaluate_targets(res: dict, cfg: Config) -> list:
    grid = {(e["n"], e["t"]): e for e in res["speed"]["grid"]}
    n, t = cfg.main
    m = grid.get((n, t))
    out = []
    scale = f"N={n:,}, T={t}" + ("" if n == 1_000_000 else " (quick/tiny run: the targets are stated at 1M, 20)")
    if m is None:
        return out
    p = m["peers"]

    def add(name, value, limit, met, detail):
        out.append({"target": name, "value": value, "limit": limit, "met": bool(met), "detail": detail,
                    "at": scale})

    if p["warp_ms"]:
        r = m["step_ms"] / p["warp_ms"]
        add("full step <= 1.0x Warp HashGrid build+query", r, 1.0, r <= 1.0,
            f"{m['step_ms']:.2f} ms vs {p['warp_ms']:.2f} ms")
    else:
        out.append({"target": "full step <= 1.0x Warp HashGrid build+query", "value": None, "limit": 1.0,
                    "met": None, "detail": f"Warp not measured: {res['warp'].get('error')}", "at": scale})
    r = m["step_ms"] / p["floor_ms"]
    add("full step <= 3x streaming floor", r, 3.0, r <= 3.0, f"{m['step_ms']:.2f} ms vs floor {p['floor_ms']:.2f} ms")
    r = p["numpy_ms"] / m["step_ms"]
    add(">= 100x faster than NumPy brute force", r, 100.0, r >= 100.0,
        f"NumPy {p['numpy_ms']:.1f} ms vs {m['step_ms']:.2f} ms")
    eff = res["speed"]["effects"]
    bed = eff["splash off (bed only: recycle)"]["step_ms"]
    r = bed / p["floor_ms"]
    add("bed-only scene (no splash) <= 1.3x streaming floor", r, 1.3, r <= 1.3,
        f"{bed:.2f} ms vs floor {p['floor_ms']:.2f} ms")
    ns = sorted({e["n"] for e in res["speed"]["grid"] if e["t"] == t})
    if len(ns) >= 2:
        hi, lo = ns[-1], ns[-2]
        r = grid[(hi, t)]["step_ms"] / grid[(lo, t)]["step_ms"]
        lim = 1.1 * hi / lo
        add(f"linear in N: step({hi:,})/step({lo:,}) <= {lim:g}", r, lim, r <= lim,
            f"{grid[(hi, t)]['step_ms']:.2f} / {grid[(lo, t)]['step_ms']:.2f} ms")
    hs = res["accuracy"]["hash_settings"]["settings"]
    d = {r["name"]: r for r in hs if "error" not in r}
    if DESIGN_HASH in d and DEFAULT_HASH in d:
        r = d[DESIGN_HASH]["step_ms"] / d[DEFAULT_HASH]["step_ms"]
        far = r > 2.0
        out.append({"target": "design hash (aabb, cell r_min) vs default (center, 2 r_max): far slower?",
                    "value": r, "limit": 2.0, "met": None,
                    "detail": f"{'yes' if far else 'no'}: {d[DESIGN_HASH]['step_ms']:.2f} ms vs "
                              f"{d[DEFAULT_HASH]['step_ms']:.2f} ms per step (x{r:.2f})",
                    "at": f"N={res['accuracy']['hash_settings']['n']:,}, T={res['accuracy']['hash_settings']['t']}"})
    if "design, scope all" in d and "scope all" in d:
        r = d["design, scope all"]["step_ms"] / d["scope all"]["step_ms"]
        out.append({"target": "design hash vs centre insert, both hashing every rock (scope all)", "value": r,
                    "limit": 2.0, "met": None, "detail": f"x{r:.2f}", "at": out[-1]["at"]})
    return out


# ================================================================================================ plots
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"figure.dpi": 110, "font.size": 9, "axes.grid": True, "grid.alpha": 0.3})
    return plt


COLORS = {"symplectic_euler": "tab:blue", "heun": "tab:orange", "rk4": "tab:green"}
PRESET_MARK = {"draft": ("*", "tab:red"), "balanced": ("P", "tab:purple"), "reference": ("X", "black")}


def _save(plt, fig, out: Path, name: str) -> str:
    """Lay out, write and close a figure; return its file name."""
    fig.tight_layout()
    fig.savefig(out / name)
    plt.close(fig)
    return name


def plot_integrators(res, out: Path) -> str:
    plt = _plt()
    acc = res["accuracy"]["integrator_dt"]
    cost = res["accuracy"]["flight_cost"]["ms_per_step"]
    presets = res["accuracy"]["presets"]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    for ax, (case, drag) in zip(axes, (("gravity", "none"), ("linear", "linear"), ("quadratic", "quadratic"))):
        for prec, ls in (("f32", "-"), ("f64", "--")):
            for integ in INTEGRATORS:
                rows = [r for r in acc["rows"] if r["case"] == case and r["integrator"] == integ
                        and r["precision"] == prec]
                if not rows:
                    continue
                ms = cost.get(integ, {}).get(drag) or cost.get(integ, {}).get("quadratic")
                if ms is None:
                    ms = next(iter(next(iter(cost.values())).values()))
                x = [ms / r["dt"] for r in rows]
                y = [max(r["max_error_m"], 1e-12) for r in rows]
                ax.loglog(x, y, ls, marker="o", ms=3.5, color=COLORS[integ], label=f"{integ} {prec}")
                if prec == "f32" and integ in ("symplectic_euler", "rk4"):
                    for xi, yi, r in zip(x, y, rows):
                        if any(abs(r["dt"] - d) < 1e-12 for d in (1e-4, 1e-3, 2e-3, 1e-2, 2e-2)):
                            ax.annotate(f"dt {r['dt']:g}", (xi, yi), fontsize=6, alpha=0.75, xytext=(3, 3),
                                        textcoords="offset points")
        if case != "linear":
            for p in presets:
                if "integrator" not in p:
                    continue
                rows = [r for r in acc["rows"] if r["case"] == case and r["integrator"] == p["integrator"]
                        and r["precision"] == p["precision"] and r["dt"] == p["dt"]]
                if rows:
                    ms = cost.get(p["integrator"], {}).get(drag) or cost.get(p["integrator"], {}).get("quadratic")
                    if ms is None:
                        continue
                    mk, col = PRESET_MARK[p["name"]]
                    ax.loglog([ms / p["dt"]], [max(rows[0]["max_error_m"], 1e-12)], mk, color=col, ms=13,
                              mec="white", zorder=5, label=f"preset {p['name']}")
        info = acc["cases"].get(case, {})
        title = {"gravity": "gravity only (parabola)",
                 "linear": "linear drag, tau = " + ", ".join(f"{t:.2g}" for t in info.get("tau_s", [])) + " s",
                 "quadratic": "quadratic drag, vertical, v0 = 20 m/s, v_t = "
                              + ", ".join(f"{v:.0f}" for v in info.get("terminal_speed_m_s", [])) + " m/s"}[case]
        ax.set_title(title)
        ax.set_xlabel("flight cost (ms per simulated second)")
        ax.set_ylabel("max position error over a 2 s flight (m)")
        ax.legend(fontsize=6.5, loc="best")
    n = res["accuracy"]["flight_cost"]["n_rocks"]
    fig.suptitle("Integrator x dt: accuracy against cost, lower left is better (cost: flight pass with all "
                 f"{n:,} rocks flying / dt; solid f32, dashed f64; errors below 1e-12 m drawn at 1e-12)")
    return _save(plt, fig, out, "accuracy_integrators.png")


def plot_detection(res, out: Path) -> str:
    plt = _plt()
    det = res["accuracy"]["detection"]["modes"]
    presets = res["accuracy"]["presets"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.6))
    style = {"ray": ("tab:blue", "o", "-"), "ray (f64)": ("tab:cyan", "x", "--"), "swept": ("tab:green", "s", "-"),
             "ray x4 substeps": ("tab:orange", "^", "-")}
    for key, d in det.items():
        col, mk, ls = style.get(key, ("tab:gray", "o", "-"))
        sp = [r["speed_m_s"] for r in d["per_speed"]]
        rc = [r["recall"] for r in d["per_speed"]]
        a1.plot(sp, rc, ls, marker=mk, color=col, label=f"{key} ({d['step_ms']:.2f} ms/step)")
        miss = max(1e-4, 1.0 - min(rc))
        a2.semilogy([d["step_ms"]], [miss], mk, ms=9, color=col, label=key)
        a2.annotate(key, (d["step_ms"], miss), fontsize=7, xytext=(5, -10 if "f64" in key else 5),
                    textcoords="offset points")
    a1.set_xlabel("vehicle speed (m/s)")
    a1.set_ylabel("recall of true tire-rock contacts")
    a1.set_ylim(0, 1.05)
    dt = det["ray"]["dt"]
    a1.set_title(f"Recall vs speed (dt = {dt:g} s; reference: analytic sweep)")
    a1.legend(fontsize=7, loc="lower left")
    for p in presets:
        if "integrator" in p:
            key = "swept" if p["detection"] == "swept" else ("ray x4 substeps" if p["substeps"] == 4 else "ray")
            if key not in det:
                continue
            mk, col = PRESET_MARK[p["name"]]
            span = max(d["step_ms"] for d in det.values()) - min(d["step_ms"] for d in det.values())
            dx = (list(PRESET_MARK).index(p["name"]) - 1) * 0.03 * max(span, 1e-3)
            a2.semilogy([det[key]["step_ms"] + dx], [max(1e-4, 1.0 - p["recall_at_60"])], mk, color=col, ms=12,
                        mec="white", label=f"preset {p['name']}: {p['detection']}"
                                           + (f" x{p['substeps']}" if p["substeps"] > 1 else "")
                                           + f" at dt {p['dt']:g} s")
    a2.set_xlabel(f"cost per step, lanes scene (ms; {det['ray']['n_rocks']:,} rocks, {det['ray']['tires']} tires)")
    a2.set_ylabel("worst miss rate, 1 - recall (1e-4 = none missed)")
    a2.set_title("Miss rate against cost (lower left is better)")
    a2.legend(fontsize=6.5, loc="center right")
    return _save(plt, fig, out, "accuracy_detection.png")


def plot_precision(res, out: Path) -> str:
    plt = _plt()
    pr = res["accuracy"]["precision"]
    cost = res["accuracy"]["detection"]["modes"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.6))
    d = np.array(pr["distances_m"], float)
    x = np.maximum(d, 1.0)
    styles = {"f32 world": ("tab:red", "-"), "f32 floating": ("tab:blue", "-"), "f64 world": ("tab:gray", "--"),
              "f64 floating": ("black", "--")}
    for name, c in pr["configs"].items():
        col, ls = styles.get(name, ("tab:olive", "-"))
        a1.loglog(x, np.maximum(c["max_error_m"], 1e-13), ls, marker="o", color=col, label=name)
        ms = cost["ray (f64)" if c["precision"] == "f64" else "ray"]["step_ms"]
        a2.semilogy([ms], [max(c["max_error_m"][-1], 1e-13)], "o", color=col, ms=8, label=name)
        a2.annotate(name, (ms, max(c["max_error_m"][-1], 1e-13)), fontsize=7, xytext=(4, 4),
                    textcoords="offset points")
    for p in res["accuracy"]["presets"]:
        if "integrator" in p:
            key = f"{p['precision']} floating"
            if key in pr["configs"]:
                mk, col = PRESET_MARK[p["name"]]
                ms = cost["ray (f64)" if p["precision"] == "f64" else "ray"]["step_ms"]
                span = abs(cost["ray (f64)"]["step_ms"] - cost["ray"]["step_ms"])
                ms += (list(PRESET_MARK).index(p["name"]) - 1) * 0.06 * max(span, 1e-3)
                a2.semilogy([ms], [max(pr["configs"][key]["max_error_m"][-1], 1e-13)], mk, color=col, ms=12,
                            mec="white", label=f"preset {p['name']}")
    a1.set_xlabel("distance of the launch point from the world origin (m; 0 drawn at 1 m)")
    a1.set_ylabel("max position error over a 2 s flight vs f64 (m)")
    a1.set_title("Precision x distance")
    a1.legend(fontsize=7)
    a2.set_xlabel("cost per step, lanes scene (ms)")
    lo, hi = a2.get_xlim()
    a2.set_xlim(lo - 0.15 * (hi - lo), hi + 0.35 * (hi - lo))
    a2.set_ylabel(f"error at {max(d) / 1e3:g} km (m)")
    a2.set_title("Precision: error against cost")
    a2.legend(fontsize=7)
    return _save(plt, fig, out, "accuracy_precision.png")


def plot_hash(res, out: Path) -> str:
    plt = _plt()
    hs = res["accuracy"]["hash_settings"]
    rows = [r for r in hs["settings"] if "error" not in r]
    keys = ["hash clear", "hash count", "hash scan", "hash scatter", "trace rays", "tire pass", "recycle", "flight"]
    colors = plt.get_cmap("tab10").colors
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(15.5, 0.45 * len(rows) + 1.8), sharey=True)
    y = np.arange(len(rows))
    steps = [r["step_ms"] for r in rows]
    a1.barh(y, steps, color=["tab:green" if r["identical"] else "tab:red" for r in rows])
    for i, r in enumerate(rows):
        a1.text(steps[i], i, f"  {steps[i]:.2f} ms" + ("" if r["identical"] else "  DIFFERENT HITS"), va="center",
                fontsize=7)
    if max(steps) > 20 * min(steps):
        a1.set_xscale("log")
        a1.set_xlim(min(steps) * 0.5, max(steps) * 6)
        scale = "log"
    else:
        a1.set_xlim(0, max(steps) * 1.45)
        scale = "linear"
    a1.set_yticks(y)
    a1.set_yticklabels([r["name"] for r in rows], fontsize=7.5)
    a1.invert_yaxis()
    a1.set_xlabel(f"full step (ms, {scale}; medians timed round-robin across settings)")
    a1.set_title(f"Step time; {hs['verdict']}: launched ids after {hs['k_steps']} steps "
                 + ("identical" if hs["identical"] else "DIFFER"))
    for i, r in enumerate(rows):
        sp = r["separate_passes_ms"]
        total = sum(sp.get(k, 0.0) for k in keys)
        left = 0.0
        for j, k in enumerate(keys):
            v = 100.0 * sp.get(k, 0.0) / total
            a2.barh(i, v, left=left, color=colors[j % 10], label=k if i == 0 else None)
            left += v
        a2.text(101, i, f"{total:.2f} ms", va="center", fontsize=7)
    a2.set_xlim(0, 118)
    a2.set_xlabel("share of the passes' time, each kernel called on its own (%; sum in ms at the right)")
    a2.set_title(f"Per pass (N={hs['n']:,} rocks, T={hs['t']} tires)")
    a2.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.09, 0.5))
    return _save(plt, fig, out, "hash_settings.png")


def plot_peers(res, out: Path) -> str:
    plt = _plt()
    grid = res["speed"]["grid"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(14, 4.8), gridspec_kw={"width_ratios": [3, 2]})
    labels = [f"N={e['n'] // 1000}k\nT={e['t']}" for e in grid]
    series = [("taichi-rocks step", lambda e: e["step_ms"], "tab:blue"),
              ("streaming floor", lambda e: e["peers"]["floor_ms"], "tab:gray"),
              ("Warp HashGrid build+query", lambda e: e["peers"]["warp_ms"], "tab:green"),
              ("SciPy cKDTree build+query", lambda e: e["peers"]["kdtree_ms"], "tab:orange"),
              ("NumPy brute force", lambda e: e["peers"]["numpy_ms"], "tab:red")]
    w = 0.16
    for k, (name, f, col) in enumerate(series):
        vals = [f(e) if f(e) is not None else np.nan for e in grid]
        a1.bar(np.arange(len(grid)) + (k - 2) * w, vals, w, label=name, color=col)
    a1.set_yscale("log")
    a1.set_xticks(range(len(grid)))
    a1.set_xticklabels(labels, fontsize=7)
    a1.set_ylabel("ms per step (log)")
    a1.set_title("Full step vs peers (same rays, same rocks)")
    a1.legend(fontsize=7)
    for t in sorted({e["t"] for e in grid}):
        es = sorted([e for e in grid if e["t"] == t], key=lambda e: e["n"])
        a2.loglog([e["n"] for e in es], [e["step_ms"] for e in es], "o-", label=f"taichi-rocks, T={t}")
    es = sorted([e for e in grid if e["t"] == min(e2["t"] for e2 in grid)], key=lambda e: e["n"])
    a2.loglog([e["n"] for e in es], [e["peers"]["floor_ms"] for e in es], "s--", color="gray", label="streaming floor")
    if len(es) >= 2:
        n0, m0 = es[0]["n"], es[0]["step_ms"]
        a2.loglog([n0, es[-1]["n"]], [m0, m0 * es[-1]["n"] / n0], ":", color="k", label="linear from smallest N")
    a2.set_xlabel("rocks N")
    a2.set_ylabel("ms per step")
    a2.set_title("Scaling in N")
    a2.legend(fontsize=7)
    return _save(plt, fig, out, "speed_peers.png")


def plot_passes(res, out: Path) -> str:
    plt = _plt()
    grid = res["speed"]["grid"]
    keys = []
    for e in grid:
        for k in e["in_step"]["per_pass_ms"]:
            if k not in keys:
                keys.append(k)
    colors = plt.get_cmap("tab10").colors
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(14, 4.8))
    x = np.arange(len(grid))
    totals = np.array([sum(e["in_step"]["per_pass_ms"].values()) for e in grid])
    bottom = np.zeros(len(grid))
    for j, k in enumerate(keys):
        v = np.array([e["in_step"]["per_pass_ms"].get(k, 0.0) for e in grid]) / totals * 100.0
        a1.bar(x, v, bottom=bottom, label=k, color=colors[j % 10])
        bottom += v
    for i, e in enumerate(grid):
        a1.text(i, 101, f"{totals[i]:.2f} ms", ha="center", fontsize=7)
    a1.set_xticks(x)
    a1.set_xticklabels([f"N={e['n'] // 1000}k\nT={e['t']}" for e in grid], fontsize=7)
    a1.set_ylim(0, 112)
    a1.set_ylabel("share of the step (%); total ms above each bar")
    a1.set_title("Where a step's time goes (kernels timed with syncs inside real steps)")
    a1.legend(fontsize=6.5, loc="lower left")
    eff = res["speed"]["effects"]
    names = [k for k, v in eff.items() if isinstance(v, dict) and v.get("step_ms") is not None]
    vals = [eff[k]["step_ms"] for k in names]
    a2.barh(range(len(names)), vals, color="tab:blue")
    for i, k in enumerate(names):
        c = eff[k].get("effect_cost_ms")
        a2.text(vals[i], i, f"  {vals[i]:.2f} ms" + (f" (effect costs {c:+.2f} ms)" if c is not None else ""),
                va="center", fontsize=7)
    a2.set_yticks(range(len(names)))
    a2.set_yticklabels(names, fontsize=7.5)
    a2.invert_yaxis()
    a2.set_xlim(0, max(vals) * 1.6)
    a2.set_xlabel("ms per step (interleaved A/B medians)")
    n, t = res["config"]["main"]
    a2.set_title(f"Effects switched off one at a time (N={n:,}, T={t})")
    return _save(plt, fig, out, "speed_passes_effects.png")


# ================================================================================================ report
def _fmt(x, unit="", digits=3):
    if x is None:
        return "n/a"
    if isinstance(x, float) and not math.isfinite(x):
        return "nan"
    if isinstance(x, (int, np.integer)):
        return f"{x:,}{unit}"
    if x != 0 and (abs(x) < 1e-3 or abs(x) >= 1e5):
        return f"{x:.{digits - 1}e}{unit}"
    return f"{x:.{digits}g}{unit}"


def _default_error(res):
    rows = [r for r in res["accuracy"]["integrator_dt"]["rows"] if r["precision"] == "f32"
            and r["integrator"] == "symplectic_euler" and abs(r["dt"] - 0.002) < 1e-12
            and r["case"] in ("gravity", "quadratic")]
    return max((r["max_error_m"] for r in rows), default=None)


def _default_recall(res):
    rows = res["accuracy"]["detection"]["modes"]["ray"]["per_speed"]
    top = [r["recall"] for r in rows if r["speed_m_s"] == max(x["speed_m_s"] for x in rows)]
    return top[0] if top else None


def write_report(res: dict, out: Path, plots: list) -> Path:
    m = res["machine"]
    L = []
    L.append("# taichi-rocks benchmark\n")
    L.append(f"Mode **{res['config']['mode']}**, {res['elapsed_s']:.0f} s wall time, {res['started']}.\n")
    L.append(f"Machine: {m['cpu_model']}, {m['usable_cores']} usable cores ({m['logical_cores']} logical), "
             f"{m['memory_gb']} GB; Python {m['python']}; Taichi {m['taichi']} ({m['taichi_arch']}, threads "
             f"{m['taichi_threads']}); NumPy {m['numpy']}; SciPy {m['scipy']}; "
             f"Warp {res['warp'].get('version') or 'not available'}.\n")
    la0, la1 = res.get("load_average_start"), res.get("load_average_end")
    if la0 and la1:
        busy = max(la0[0], la1[0]) > 0.75 * (m["usable_cores"] or 1)
        L.append(f"Load average (1, 5, 15 min) at the start {la0}, at the end {la1}"
                 + (": **the machine was busy with other work; timings are noisy**." if busy else ".") + "\n")
    if not res["warp"]["available"]:
        L.append(f"> **warp-lang is not installed** ({res['warp']['error']}): the Warp peer was skipped. "
                 "Install it with `pip install warp-lang` (the `bench` extra).\n")
    L.append("Timings: warm-up (compile) first, then the median of repeated calls with `ti.sync()` around the "
             "timed region. Warp runs on the CPU (its CPU kernels are single-threaded); NumPy/SciPy on the CPU "
             "(cKDTree queries with all cores).\n")
    # targets
    L.append("## Targets\n")
    L.append("| target | measured | limit | met | detail | at |")
    L.append("|---|---|---|---|---|---|")
    for t in res["targets"]:
        met = {True: "**met**", False: "**NOT met**", None: "-"}[t["met"]]
        L.append(f"| {t['target']} | {_fmt(t['value'])} | {_fmt(t['limit'])} | {met} | {t['detail']} | {t['at']} |")
    L.append("")
    # presets
    L.append("## Proposed presets (`[sim] accuracy = ...`)\n")
    L.append("The cheapest measured setting meeting all of: (1) error = max of the flight error over a 2 s flight "
             "of the default-physics cases (gravity only, quadratic drag) and the f32/f64 error of a flight 100 km "
             f"from the origin with the floating origin (measured); (2) recall of true tire contacts at "
             f"{PRESET_SPEED:g} m/s (swept: measured; single ray: from the recall-vs-displacement-per-ray fit of "
             "section 1b); (3) launch-time bound: a rock is launched at the end of the step in which the tire "
             f"reaches it, so its path can be off by up to v_launch dt with v_launch <= {V_LAUNCH_MAX:g} m/s "
             "(modelled, not measured). Candidates: the integrator x dt grid of 1a (dt <= 0.02 s), detection ray "
             "x1/2/4/8 or swept, f32 or f64 with the floating origin. Cost = main-scene step (measured with ray and "
             "swept by plan swaps) + the integrator's extra flight cost with every rock flying (worst case), x the "
             "f64/f32 step ratio of the lanes scene, / dt. Not covered: ground contact and sliding at large dt.\n")
    L.append("| preset | targets: error / recall / launch bound | integrator | dt (s) | detection | precision, origin | "
             "flight error (m) | f32/f64 error far (m) | recall @60 | validated recall @60 | launch bound (m) | "
             "ms/step | ms per simulated s |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for p in res["accuracy"]["presets"]:
        tg = (f"{_fmt(p['target_flight_error_m'])} m / {p['target_recall']} / "
              f"{_fmt(p.get('target_launch_time_bound_m'))} m")
        if "integrator" not in p:
            L.append(f"| {p['name']} | {tg} | {p['none']} |||||||||||")
            continue
        det = p["detection"] + (f" x{p['substeps']}" if p["substeps"] > 1 else "")
        L.append(f"| **{p['name']}** | {tg} | {p['integrator']} | {p['dt']:g} | {det} | {p['precision']}, "
                 f"{p['origin']} | {_fmt(p['flight_error_m'])} | {_fmt(p['precision_error_far_m'])} | "
                 f"{_fmt(p['recall_at_60'])} ({p['recall_source']}) | {_fmt(p.get('validated_recall_at_60'))} | "
                 f"{_fmt(p['launch_time_bound_m'])} | {_fmt(p['step_ms'])} | {_fmt(p['ms_per_simulated_s'])} |")
    d0 = res["accuracy"]["preset_costs"]
    L.append(f"\nFor comparison, the engine defaults (symplectic Euler, dt 0.002 s, ray x1, f32 floating): flight error "
             f"{_fmt(_default_error(res))} m, recall at 60 m/s "
             f"{_fmt(_default_recall(res))}, {_fmt(d0['step_ms'].get('ray'))} ms/step, "
             f"{_fmt(d0['step_ms'].get('ray', float('nan')) / 0.002)} ms per simulated s.\n")
    # accuracy: integrators
    acc = res["accuracy"]["integrator_dt"]
    L.append("## 1a. Integrator x dt\n")
    L.append(f"![integrators]({plots[0]})\n")
    L.append("Closed forms: " + "; ".join(f"{k}: {v}" for k, v in acc["closed_forms"].items()) + ". "
             f"Linear drag uses air viscosity raised so that tau = {TAU_LINEAR:g} s for a 3 cm rock (with the "
             "default 1.81e-5 Pa s tau is about 2 h and the drag is invisible); the other cases use the default "
             "physics. Errors are sampled every 0.1 s.\n")
    dts = sorted({r["dt"] for r in acc["rows"]})
    for prec in sorted({r["precision"] for r in acc["rows"]}):
        L.append(f"Max position error (m), {prec}:\n")
        L.append("| case | integrator | " + " | ".join(f"dt {d:g}" for d in dts) + " |")
        L.append("|---|---|" + "---|" * len(dts))
        for case in ("gravity", "linear", "quadratic"):
            for integ in INTEGRATORS:
                vals = {r["dt"]: r["max_error_m"] for r in acc["rows"]
                        if r["precision"] == prec and r["case"] == case and r["integrator"] == integ}
                L.append(f"| {case} | {integ} | " + " | ".join(_fmt(vals.get(d)) for d in dts) + " |")
        L.append("")
    fc = res["accuracy"]["flight_cost"]
    L.append(f"Flight pass alone with all {fc['n_rocks']:,} rocks flying (ms per step): " + "; ".join(
        f"{i}: " + ", ".join(f"drag {d} {v:.2f}" for d, v in dd.items()) for i, dd in fc["ms_per_step"].items()) + "\n")
    # detection
    dd = res["accuracy"]["detection"]
    L.append("## 1b. Detection x vehicle speed\n")
    L.append(f"![detection]({plots[1]})\n")
    L.append(dd["reference"] + "\n")
    modes = list(dd["modes"])
    speeds = [r["speed_m_s"] for r in dd["modes"]["ray"]["per_speed"]]
    L.append("| mode | ms/step | false positives | " + " | ".join(f"{s:g} m/s" for s in speeds) + " |")
    L.append("|---|---|---|" + "---|" * len(speeds))
    for k in modes:
        d = dd["modes"][k]
        L.append(f"| {k} | {d['step_ms']:.3f} | {d['false_positives']} | " + " | ".join(
            f"{r['recall']:.4f} ({r['found']}/{r['contacts']})" for r in d["per_speed"]) + " |")
    L.append(f"\nLanes scene: {dd['modes']['ray']['n_rocks']:,} rocks, {dd['modes']['ray']['tires']} rear tires, "
             f"dt {dd['modes']['ray']['dt']:g} s, {dd['modes']['ray']['steps']} steps.\n")
    # precision
    pr = res["accuracy"]["precision"]
    L.append("## 1c. Precision x distance from the origin\n")
    L.append(f"![precision]({plots[2]})\n")
    L.append(f"Reference: {pr['reference']}. {pr['note']}.\n")
    L.append("| config | " + " | ".join(f"{d / 1e3:g} km" for d in pr["distances_m"]) + " | step ms (lanes) |")
    L.append("|---|" + "---|" * len(pr["distances_m"]) + "---|")
    for name, c in pr["configs"].items():
        ms = dd["modes"]["ray (f64)" if c["precision"] == "f64" else "ray"]["step_ms"]
        L.append(f"| {name} | " + " | ".join(_fmt(e) for e in c["max_error_m"]) + f" | {ms:.3f} |")
    L.append("")
    # hash
    hs = res["accuracy"]["hash_settings"]
    L.append("## 1d. Hash settings\n")
    L.append(f"![hash]({plots[3]})\n")
    L.append(f"**{hs['verdict']}**: launched rock ids after {hs['k_steps']} steps "
             f"{'identical for every setting' if hs['identical'] else 'DIFFER between settings'} "
             f"(N={hs['n']:,}, T={hs['t']}).\n")
    L.append("| setting | cell (m) | table | launched | identical | step ms | count | scan | scatter | trace | "
             "tire | build+compile s |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in hs["settings"]:
        if "error" in r:
            L.append(f"| {r['name']} | skipped: {r['error']} |||||||||||")
            continue
        s = r["separate_passes_ms"]
        L.append(f"| {r['name']} | {r['cell_size_m']:g} | {r['table_size']:,} | {r['launched']} | "
                 f"{'yes' if r['identical'] else '**NO**'} | {r['step_ms']:.3f} | {_fmt(s.get('hash count'))} | "
                 f"{_fmt(s.get('hash scan'))} | {_fmt(s.get('hash scatter'))} | {_fmt(s.get('trace rays'))} | "
                 f"{_fmt(s.get('tire pass'))} | {r['build_s']:.1f} |")
    L.append("")
    # speed
    L.append("## 2. Speed against peers\n")
    L.append(f"![peers]({plots[4]})\n")
    L.append(f"![passes]({plots[5]})\n")
    L.append("| N | T | step ms (median) | mean | floor | Warp | cKDTree | NumPy | step/floor | step/Warp | "
             "NumPy/step | cKDTree/step | flying | hits agree |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for e in res["speed"]["grid"]:
        p, r, c = e["peers"], e["ratios"], e["peers"]["check"]
        agree = (c["kdtree_equals_numpy"] and c["taichi_launched_subset_of_geometric_hits"]
                 and c.get("warp_sym_diff_vs_numpy", 0) == 0)
        L.append(f"| {e['n']:,} | {e['t']} | {e['step_ms']:.3f} | {e['step_stats']['mean_ms']:.3f} | "
                 f"{p['floor_ms']:.3f} | {_fmt(p['warp_ms'])} | {p['kdtree_ms']:.1f} | {p['numpy_ms']:.1f} | "
                 f"{r['step_over_floor']:.2f} | {_fmt(r['step_over_warp'])} | {r['numpy_over_step']:.0f} | "
                 f"{r['kdtree_over_step']:.0f} | {e['n_flying']:,} | {'yes' if agree else 'NO'} |")
    L.append("")
    L.append("Per pass (ms per step), each kernel called on its own after a normal step (`rock_pass` with one "
             "flag at a time, `inclusive_scan`, `scatter`, `trace_rays`, `tire_pass`):\n")
    keys = []
    for e in res["speed"]["grid"]:
        for k in e["separate_passes_ms"]:
            if k not in keys:
                keys.append(k)
    L.append("| N | T | " + " | ".join(keys) + " | reorder (every k steps) |")
    L.append("|---|---|" + "---|" * (len(keys) + 1))
    for e in res["speed"]["grid"]:
        s = e["separate_passes_ms"]
        L.append(f"| {e['n']:,} | {e['t']} | " + " | ".join(_fmt(s.get(k)) for k in keys)
                 + f" | {_fmt(e['reorder_ms'])} (every {e['reorder_every']}) |")
    L.append("")
    L.append("Inside a real step (each kernel timed with syncs; the rock pass fuses flight, recycle and count):\n")
    keys = []
    for e in res["speed"]["grid"]:
        for k in e["in_step"]["per_pass_ms"]:
            if k not in keys:
                keys.append(k)
    L.append("| N | T | " + " | ".join(keys) + " |")
    L.append("|---|---|" + "---|" * len(keys))
    for e in res["speed"]["grid"]:
        s = e["in_step"]["per_pass_ms"]
        L.append(f"| {e['n']:,} | {e['t']} | " + " | ".join(_fmt(s.get(k)) for k in keys) + " |")
    L.append("")
    ov = res["speed"].get("overheads", {})
    if ov:
        L.append(f"Fixed costs: an empty Taichi kernel call {_fmt(ov.get('empty_kernel_ms'))} ms; `rock_pass` over "
                 f"zero rocks with every pass off {_fmt(ov.get('rock_pass_zero_rocks_ms'))} ms (the cost of passing its 20 "
                 "arguments); "
                 f"vehicle poses + rear-tire rays on the host {_fmt(ov.get('vehicle_poses_and_rays_ms'))} ms "
                 f"(main scene).\n")
    eff = res["speed"]["effects"]
    L.append(f"Effects (N={res['config']['main'][0]:,}, T={res['config']['main'][1]}; "
             f"{eff['n_flying_during_measurement']:,} rocks flying while measured):\n")
    efa = res["accuracy"]["flight_cost"].get("effects_all_flying_ms")
    if efa:
        L.append(f"With every one of the {res['accuracy']['flight_cost']['n_rocks']:,} rocks flying (flight pass "
                 "alone): " + "; ".join(f"{k} costs {v:+.2f} ms" for k, v in efa.items()) + ".\n")
    L.append("| variant | step ms | effect cost ms (on - off) |")
    L.append("|---|---|---|")
    for k, v in eff.items():
        if isinstance(v, dict):
            L.append(f"| {k} | {_fmt(v.get('step_ms'))} | {_fmt(v.get('effect_cost_ms'))} |")
    L.append("")
    L.append("## Build (compile) time per simulation\n")
    L.append(", ".join(f"{k}: {v:.1f} s" for k, v in res["build_s"].items()) + "\n")
    if res.get("errors"):
        L.append("## Errors\n")
        for e in res["errors"]:
            L.append(f"- {e}")
        L.append("")
    path = out / "report.md"
    path.write_text("\n".join(L))
    return path


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items() if not str(k).startswith("_")}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating,)):
        x = float(x)
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, Path):
        return str(x)
    return x


# ================================================================================================ entry
def _count_tasks(cfg: Config) -> int:
    n_grid = len(cfg.grid_n) * len(cfg.grid_t)
    acc = (2 if cfg.acc_f64 else 1) * 9
    return (4 + acc + 2 + len(cfg.integ_cost) + n_grid * 5 + len(cfg.hash_settings) - 1 + 6 + 6
            + (3 if cfg.validate_presets else 0) + 3)


def run_bench(out_dir="renders/bench", quick: bool = False, arch: str = "cpu", progress=True, tiny: bool = False,
              config: "Optional[Config]" = None) -> dict:
    """Run the benchmark and write report.md, results.json and PNG plots to ``out_dir``.

    ``quick``: the CI smoke run (< 2 min on 2 cores); ``tiny``: the smallest sizes (tests); ``config``
    overrides both. ``progress``: True shows a tqdm bar on stderr, None only on a terminal, False never.
    The missing folders of ``out_dir`` are created, and removed again if the run fails before writing into them.
    """
    from .recording import new_folders

    out = Path(out_dir)
    with new_folders(out):
        return _run_bench(out, config or make_config(quick=quick, tiny=tiny), arch, progress)


def _run_bench(out: Path, cfg: "Config", arch: str, progress) -> dict:
    t_start = time.perf_counter()
    used = init_taichi(arch)
    pin_sources()
    prog = Progress(_count_tasks(cfg), progress)
    res: dict = {"started": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": _machine(used),
                 "load_average_start": _loadavg(),
                 "config": dataclasses.asdict(cfg), "errors": [], "build_s": {}}
    # warp, lazily
    warp = None
    if not cfg.use_warp:
        res["warp"] = {"available": False, "error": "skipped by the configuration (tiny run)"}
    else:
        try:
            warp = WarpPeer()
            res["warp"] = {"available": True, "version": warp.version, "device": "cpu"}
        except Exception as exc:  # not installed, or no compiler: skip the peer, never crash
            res["warp"] = {"available": False, "error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    res["machine"]["warp"] = res["warp"].get("version")
    prog("warp")

    # ---- 1b/1c/1a: lanes scenes (detection, in lockstep), then direct flights on the same worlds
    det, builds, recs, bs = detection_and_precision(cfg, used, prog)
    res["build_s"].update(bs)
    acc_sims = {"f32": builds["f32"].sim}
    if cfg.acc_f64:
        acc_sims["f64"] = builds["f64"].sim
    res["accuracy"] = {}
    res["accuracy"]["detection"] = {
        "modes": det,
        "reference": ("Reference: analytic sweep - each rear tire's ray (centre to ground) swept along its straight "
                      "path from t = 0 to the end of the run is a vertical rectangle; a rock resting at t = 0 is a "
                      "true contact iff its centre is within its radius of that rectangle. Chosen over a small-dt "
                      "swept run because it is exact and independent of the engine. Launched rocks never land "
                      "(ground none) and the bed is not recycled, so each rock can be launched once. The four "
                      "lanes simulations are stepped in lockstep, so their step costs are comparable.")}
    res["accuracy"]["integrator_dt"] = integrator_sweep(acc_sims, recs, cfg, prog)
    res["accuracy"]["precision"] = precision_runs({k: b.sim for k, b in builds.items()}, recs, cfg, prog)

    # ---- 2: speed grid
    floor = Floor(max(cfg.grid_n))
    grid, grid_by_nt, main_built, main_rec = [], {}, None, None
    for n in cfg.grid_n:
        for t in cfg.grid_t:
            b = Built(fleet_scene(n, t, cfg.bed_radius), used, f"grid N={n} T={t}")
            e = _grid_entry(b, cfg, floor, warp, prog, record_hits=(n == cfg.hash_n or (n, t) == cfg.main))
            res["build_s"][b.label] = e["build_s"]
            grid.append(e)
            grid_by_nt[(n, t)] = e
            if (n, t) == cfg.main:
                main_built, main_rec = b, e["_rec"]
    res["speed"] = {"grid": grid}

    # ---- 1d: hash settings (uses the grid's default simulation, so before anything changes its state)
    res["accuracy"]["hash_settings"] = _hash_section(cfg, used, grid_by_nt, prog)

    # ---- effects, preset costs (plan swaps on the main scene), launch overheads, then the flight cost with
    # every rock flying (last: it leaves the main scene's rocks all flying)
    bed_only = Built(fleet_scene(*cfg.main, cfg.bed_radius, {"effects.splash": False}), used, "bed only")
    res["speed"]["effects"] = effects_costs(main_built, bed_only, cfg, prog)
    res["build_s"]["bed only"] = bed_only.ctor_s + (bed_only.first_step_s or 0.0)
    res["accuracy"]["preset_costs"] = preset_costs(main_built, cfg, det, prog)
    res["speed"]["overheads"] = launch_overheads(main_built, main_rec, cfg)
    res["accuracy"]["flight_cost"] = flight_cost(main_built, main_rec, cfg.integ_cost, max(3, cfg.reps // 2), prog,
                                                 effects=cfg.effects_all_flying)
    for e in grid:
        for k in ("launched_after_k", "_built", "_rec"):
            e.pop(k, None)

    # ---- presets and targets
    res["accuracy"]["presets"] = choose_presets(res)
    if cfg.validate_presets:
        try:
            validate_presets(res["accuracy"]["presets"], cfg, used, prog)
        except Exception as exc:
            res["errors"].append(f"preset validation: {type(exc).__name__}: {exc}")
    res["targets"] = evaluate_targets(res, cfg)

    # ---- outputs
    res["elapsed_s"] = time.perf_counter() - t_start
    res["load_average_end"] = _loadavg()
    plots = []
    for fn in (plot_integrators, plot_detection, plot_precision, plot_hash, plot_peers, plot_passes):
        try:
            plots.append(fn(res, out))
        except Exception as exc:
            res["errors"].append(f"plot {fn.__name__}: {type(exc).__name__}: {exc}")
            plots.append("")
            traceback.print_exc()
        prog("plots")
    res["plots"] = [p for p in plots if p]
    res["elapsed_s"] = time.perf_counter() - t_start
    report = write_report(res, out, plots)
    res["report"] = str(report)
    (out / "results.json").write_text(json.dumps(_jsonable(res), indent=1))
    prog.close()
    if res["accuracy"]["hash_settings"]["verdict"] != "PASS":
        print("taichi-rocks bench: FAIL: hash settings launched different rocks (see report)", file=sys.stderr)
    return res
