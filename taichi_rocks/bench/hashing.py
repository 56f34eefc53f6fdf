"""1d. Hash settings: insert mode, cell size, table size and scope must not change what the tires hit.

Each setting runs the same fleet scene k steps from t = 0; the launched rock ids must be identical to the
default's (recorded by the speed grid). The default setting is run again from a fresh build too: a run that
does not reproduce its own record cannot vouch for the others. A setting whose scene or simulation fails to
build is a failure of the study, not a row left out. Then the step is timed round-robin across all settings
(so a busy machine slows all alike), and each pass is timed inside real steps and on its own.
"""

from __future__ import annotations

import numpy as np

from .config import DEFAULT_HASH, HASH_SETTINGS, Config
from .measure import Built, in_step_profile, launched_ids, separate_passes_ms, stats
from .scenes import fleet_scene, with_overrides


def _default_row(default: dict, scene, cfg: Config, arch: str, ref: list) -> dict:
    """The default setting's row: the grid's simulation (timed below), its identity checked by a fresh build
    of the same scene run k steps from t = 0 against the grid's record."""
    b = default["_built"]
    again, _ = _setting_row(DEFAULT_HASH, scene, cfg, arch, ref)
    return {"name": DEFAULT_HASH, "launched": len(default["launched_after_k"]), "identical": again["identical"],
            "table_size": default["table_size"], "cell_size_m": default["cell_size_m"], "build_s": default["build_s"],
            "entries_capacity": int(getattr(b.sim.world, "entry_capacity", 0))}


def _setting_row(name: str, scene, cfg: Config, arch: str, ref: list) -> tuple:
    """(row, Built) of one setting after k steps from t = 0."""
    b = Built(scene, arch, name)
    first = b.step_timed(cfg.k_hits)
    got = launched_ids(b.sim).tolist()
    row = {"name": name, "launched": len(got), "identical": got == ref, "table_size": int(b.sim.table_size),
           "cell_size_m": float(b.sim.cell_size), "build_s": b.ctor_s + first[0],
           "entries_capacity": int(getattr(b.sim.world, "entry_capacity", 0)),
           "_first_ms": 1e3 * float(np.median(first[1:] or first))}
    return row, b


def _round_robin(live: list, built: dict, cfg: Config, default_ms: float) -> dict:
    """Step times per setting, round-robin: each round ~0.1-0.2 s of steps per setting (at least one)."""
    est = {r["name"]: r.get("_first_ms", default_ms) for r in live}
    m = {k: max(1, min(cfg.reps // 2, int(150.0 / max(v, 1e-3)))) for k, v in est.items()}
    times = {r["name"]: [] for r in live}
    for b in built.values():
        b.step_timed(1)
    for _ in range(4):
        for name, b in built.items():
            times[name] += b.step_timed(m[name])
    return times


def hash_settings_study(cfg: Config, arch: str, grid_by_nt: dict, prog) -> dict:
    """Launched ids after k steps compared with the default's, then step and pass timings per setting."""
    n, t = cfg.hash_n, 20 if 20 in cfg.grid_t else max(cfg.grid_t)
    if (n, t) not in grid_by_nt:
        n, t = cfg.main
    default = grid_by_nt[(n, t)]
    ref = default["launched_after_k"]
    scene0 = fleet_scene(n, t, cfg.bed_radius)
    rows, built = [], {}
    for name in cfg.hash_settings:
        try:
            if name == DEFAULT_HASH:
                rows.append(_default_row(default, scene0, cfg, arch, ref))
                built[name] = default["_built"]
                continue
            row, built[name] = _setting_row(name, with_overrides(scene0, HASH_SETTINGS[name]), cfg, arch, ref)
            rows.append(row)
        except Exception as exc:  # a setting the scene format does not have (any more), or that fails to build
            rows.append({"name": name, "error": f"{type(exc).__name__}: {exc}".splitlines()[0]})
        finally:
            prog(f"hash {name}")
    live = [r for r in rows if "error" not in r]
    times = _round_robin(live, built, cfg, default["step_ms"])
    for r in live:
        sim = built[r["name"]].sim
        st = stats(times[r["name"]])
        r["step_ms"], r["step_stats"] = st["median_ms"], st
        r["in_step"] = in_step_profile(sim, 2)
        r["separate_passes_ms"] = separate_passes_ms(sim, max(2, cfg.pass_reps // 2))
        r.pop("_first_ms", None)
    prog("hash timing")
    ok = hash_verdict(rows)
    return {"n": n, "t": t, "k_steps": cfg.k_hits, "settings": rows, "identical": ok,
            "verdict": "PASS" if ok else "FAIL"}


def hash_verdict(rows: list) -> bool:
    """True when every setting was built and run and launched the default's rocks, and there was something to
    compare (the default and at least one other setting): an error row is a failure, not a row left out."""
    return (len(rows) >= 2 and all("error" not in r for r in rows)
            and all(r["identical"] is True for r in rows))
