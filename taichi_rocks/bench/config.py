"""What a benchmark run measures and how much of it: the run's sizes (Config: tiny, quick, full), the hash
settings compared, the integrators and drag laws swept, and the presets' targets. No Taichi here."""

from __future__ import annotations

import dataclasses
from typing import Optional

from ..config.keys import choices

G = 9.81  # m/s^2: the closed forms' gravity (the benchmark's scenes keep the default gravity; checked)
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
    # 4. cost against activity (activity.py): N of the series, the largest N also timed with full stepping,
    # bed radius of series (a), the N whose density series (b) keeps, the rear tires and speed of both series,
    # the N of the activity sweep and its tires and speeds, seconds stepped before timing, rounds x steps timed
    activity: bool = True
    act_n: tuple = (100_000, 300_000, 1_000_000, 3_000_000, 10_000_000)
    act_full_max: int = 10_000_000
    act_full_min: int = 0  # N below this are timed with active stepping only
    act_radius: float = 30.0
    act_ref_n: int = 1_000_000
    act_t: int = 20
    act_speed: float = 25.0
    act_fixed_n: int = 1_000_000
    act_tires: tuple = (2, 6, 20, 40)
    act_speeds: tuple = (10.0, 40.0)  # and act_speed (the 20-tire point of act_tires)
    act_warm_s: float = 1.0
    act_rounds: int = 7
    act_steps: int = 25
    act_balanced: bool = True
    act_profile_n: tuple = (100_000, 1_000_000)  # N profiled (kernel profiler, host side, launches), series (a)
    act_isolated: bool = True  # each job in a process of its own (else, but the profiled one, in this process)
    # 5. impacts (impacts.py): the study's mode ("full", "quick"), None: not run
    impacts: Optional[str] = "full"


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

INTEGRATORS = choices("sim.integrator")
DRAGS = choices("effects.drag")
CASE_OF_DRAG = {d: "gravity" if d == "none" else d for d in DRAGS}  # the accuracy study's case of each drag law


def make_config(quick: bool = False, tiny: bool = False) -> Config:
    if tiny:
        return Config(mode="tiny", grid_n=(20_000,), grid_t=(2,), bed_radius=8.0, main=(20_000, 2), k_hits=30,
                      warm=2, reps=4, pass_reps=2, numpy_reps=2, kdtree_reps=1, warp_reps=2,
                      probe_n=20_000, probe_radius=16.0, speeds=(10.0, 60.0), run_time=0.2,
                      acc_dts=(1e-2, 1 / 60, 2e-2), acc_f64=False, distances=(0.0, 1e5),
                      hash_settings=(DEFAULT_HASH, DESIGN_HASH), hash_n=20_000,
                      integ_cost=tuple((i, "quadratic") for i in INTEGRATORS), validate_presets=False,
                      use_warp=True, substeps_mode=False, effects=("drag none",), effects_all_flying=False,
                      act_n=(10_000, 30_000), act_full_max=30_000, act_full_min=30_000, act_radius=8.0, act_ref_n=30_000, act_t=2,
                      act_fixed_n=30_000, act_tires=(2, 6), act_speeds=(10.0,), act_warm_s=0.2, act_rounds=3,
                      act_steps=10, act_profile_n=(10_000,), act_isolated=False, impacts=None)
    if quick:
        return Config(mode="quick", grid_n=(10_000, 100_000), grid_t=(2, 20), bed_radius=30.0,
                      main=(100_000, 20), k_hits=20, warm=3, reps=10, pass_reps=4, numpy_reps=2, kdtree_reps=2,
                      warp_reps=5, probe_n=100_000, probe_radius=16.0,
                      speeds=(5.0, 10.0, 20.0, 30.0, 45.0, 60.0), run_time=0.4,
                      acc_dts=(2e-3, 5e-3, 1e-2, 1 / 60, 2e-2), acc_f64=False,
                      distances=(0.0, 1e3, 1e4, 1e5),
                      hash_settings=(DEFAULT_HASH, DESIGN_HASH, "scope all"),
                      hash_n=100_000, integ_cost=tuple((i, "quadratic") for i in INTEGRATORS),
                      validate_presets=False, passes_all=False, act_n=(100_000, 1_000_000),
                      act_full_max=1_000_000, act_tires=(2, 20), act_rounds=5, act_steps=20, impacts=None)
    return Config(mode="full", grid_n=(10_000, 100_000, 1_000_000), grid_t=(2, 20, 64), bed_radius=30.0,
                  main=(1_000_000, 20), k_hits=30, warm=5, reps=20, pass_reps=8, numpy_reps=3, kdtree_reps=3,
                  warp_reps=10, probe_n=200_000, probe_radius=16.0,
                  speeds=(5.0, 10.0, 20.0, 30.0, 45.0, 60.0), run_time=0.4,
                  acc_dts=(1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 1 / 60, 2e-2), acc_f64=True,
                  distances=(0.0, 1e2, 1e3, 1e4, 3e4, 1e5), hash_settings=tuple(HASH_SETTINGS),
                  hash_n=100_000, integ_cost=tuple((i, d) for i in INTEGRATORS for d in DRAGS),
                  validate_presets=True)
