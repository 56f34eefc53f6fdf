"""The benchmark's seven plots (matplotlib, Agg): accuracy against cost per integrator, detection recall and
miss rate against cost, precision against distance and cost, hash settings (step time and per-pass shares),
the full step against its peers and in N, where a step's time goes with the effects switched off, and the
cost against activity (time against N with the floor, against the rocks in the air, memory)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..config.keys import choices
from ..output.atomic import write_atomically
from .config import CASE_OF_DRAG, DRAGS, INTEGRATORS


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"figure.dpi": 110, "font.size": 9, "axes.grid": True, "grid.alpha": 0.3})
    return plt


# the file each plot writes (run.py refuses an out folder already holding one, unless overwrite)
PNG = {"integrators": "accuracy_integrators.png", "detection": "accuracy_detection.png",
       "precision": "accuracy_precision.png", "hash": "hash_settings.png", "peers": "speed_peers.png",
       "passes": "speed_passes_effects.png", "activity": "activity.png"}
TAB10 = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:gray",
         "tab:olive", "tab:cyan")
COLORS = {name: TAB10[i % len(TAB10)] for i, name in enumerate(INTEGRATORS)}
LINES = ("-", "--", ":", "-.")  # one per precision, stepping mode, ...
PRESET_MARK = {"draft": ("*", "tab:red"), "balanced": ("P", "tab:purple"), "reference": ("X", "black"),
               "game": ("D", "tab:green")}


def _save(plt, fig, out: Path, name: str) -> str:
    """Lay out, write (atomically) and close a figure; return its file name."""
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    write_atomically(out / name, lambda f: f.write(buf.getvalue()))
    return name


def plot_integrators(res, out: Path) -> str:
    plt = _plt()
    acc = res["accuracy"]["integrator_dt"]
    cost = res["accuracy"]["flight_cost"]["ms_per_step"]
    presets = res["accuracy"]["presets"]
    fig, axes = plt.subplots(1, len(DRAGS), figsize=(5 * len(DRAGS), 4.8))
    for ax, (case, drag) in zip(axes, ((CASE_OF_DRAG[d], d) for d in DRAGS)):
        for prec, ls in zip(choices("sim.precision"), LINES):
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
        titles = {"gravity": "gravity only (parabola)",
                  "linear": "linear drag, tau = " + ", ".join(f"{t:.2g}" for t in info.get("tau_s", [])) + " s",
                  "quadratic": "quadratic drag, vertical, v0 = 20 m/s, v_t = "
                               + ", ".join(f"{v:.0f}" for v in info.get("terminal_speed_m_s", [])) + " m/s"}
        ax.set_title(titles.get(case, case))
        ax.set_xlabel("flight cost (ms per simulated second)")
        ax.set_ylabel("max position error over a 2 s flight (m)")
        ax.legend(fontsize=6.5, loc="best")
    n = res["accuracy"]["flight_cost"]["n_rocks"]
    fig.suptitle("Integrator x dt: accuracy against cost, lower left is better (cost: flight pass with all "
                 f"{n:,} rocks flying / dt; solid f32, dashed f64; errors below 1e-12 m drawn at 1e-12)")
    return _save(plt, fig, out, PNG["integrators"])


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
    return _save(plt, fig, out, PNG["detection"])


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
    return _save(plt, fig, out, PNG["precision"])


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
    return _save(plt, fig, out, PNG["hash"])


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
    return _save(plt, fig, out, PNG["peers"])


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
    a1.set_title("Where a step's time goes (passes timed with syncs inside real steps)")
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
    return _save(plt, fig, out, PNG["passes"])


def _ok_ms(p, key="step_ms"):
    return p.get(key) if p and "error" not in p else None


def _activity_vs_n(ax, act) -> None:
    """Step time against N, log-log: each series with active and full stepping, and the floor."""
    style = {"a": ("tab:blue", "o"), "b": ("tab:orange", "s")}
    for series, rows in act["series"].items():
        col, mk = style[series]
        for stepping, ls in zip(choices("sim.stepping"), LINES):
            pts = [(r["n"], _ok_ms(r.get(stepping))) for r in rows if _ok_ms(r.get(stepping))]
            if pts:
                name = {"a": f"(a) R = {act['radius']:g} m", "b": "(b) fixed density"}[series]
                ax.loglog(*zip(*pts), ls, marker=mk, color=col, ms=5, label=f"{name}, {stepping} stepping")
        if series == "a":
            fl = [(r["n"], r["floor_ms"]) for r in rows if r.get("floor_ms")]
            if fl:
                ax.loglog(*zip(*fl), ":", marker="x", color="gray", label="streaming floor (same N)")
                ax.loglog(*zip(*[(n, 0.5 * m) for n, m in fl]), ":", color="tab:red", lw=1,
                          label="target: 0.5x the floor")
    for r in act["series"]["a"]:
        a = r.get("active")
        if _ok_ms(a):
            ax.annotate(f"{a['in_air']:,} in air", (r["n"], a["step_ms"]), fontsize=7, xytext=(4, -10),
                        textcoords="offset points", color="tab:blue")
    ax.set_xlabel("rocks N")
    ax.set_ylabel("ms per step (median of rounds)")
    ax.set_title(f"Step time against N ({act['t_rear']} rear tires, {act['speed']:g} m/s)")
    ax.legend(fontsize=7.5, loc="best", framealpha=0.6)


def _activity_vs_air(ax, act) -> None:
    """Step time against the rocks in the air: the activity sweep at the reference N, and series (a)."""
    marks = {"tires": ("o", "tab:blue"), "speed": ("s", "tab:green"), "parked": ("X", "black"),
             "balanced": ("P", "tab:purple")}
    seen = set()
    for p in act["sweep"]:
        if not _ok_ms(p):
            continue
        mk, col = marks[p["group"]]
        label = {"tires": "rear tires (vehicles)", "speed": "speed", "parked": "parked fleet",
                 "balanced": "balanced preset (heun, swept)"}[p["group"]]
        ax.plot(p["in_air"], p["step_ms"], mk, color=col, ms=8, label=None if label in seen else label)
        seen.add(label)
        ax.annotate(p["label"].replace(" rear tires", " tires"), (p["in_air"], p["step_ms"]), fontsize=7.5,
                    xytext=(5, 4), textcoords="offset points")
    ax.set_xlabel(f"rocks in the air (N = {act['reference_n']:,})")
    ax.set_ylabel("ms per step (active stepping)")
    ax.set_ylim(bottom=0)
    ax.set_xlim(left=-0.05 * max([p.get("in_air", 0) or 0 for p in act["sweep"]] + [1]))
    ax.set_title("Step time against activity at fixed N")
    ax.legend(fontsize=7.5, loc="best", framealpha=0.6)


def _activity_memory(ax, act) -> None:
    for stepping, col in zip(choices("sim.stepping"), ("tab:blue", "tab:gray", "tab:olive")):
        rows = [r for r in act["series"]["a"] if (r.get(stepping) or {}).get("memory")]
        if not rows:
            continue
        n = [r["n"] for r in rows]
        ax.loglog(n, [r[stepping]["memory"]["hwm_mb"] for r in rows], "o-", color=col,
                  label=f"{stepping}: peak RSS")
        ax.loglog(n, [r[stepping]["memory"]["field_mb"] for r in rows], "^--", color=col,
                  label=f"{stepping}: fields")
        m = act["memory"]["a"].get(stepping)
        if m and m["largest_n"] < 10_000_000:
            ax.loglog([m["largest_n"], 1e7], [m["hwm_mb_at_largest"], m["peak_10m_gb"] * 1e9 / 1024 ** 2], ":",
                      marker="o", mfc="none", color=col, label=f"{stepping}: peak projected to 10M")
    ax.axhline(24 * 1024, color="tab:red", lw=1, ls=":", label="24 GB (the machine)")
    ax.set_xlabel("rocks N (series a)")
    ax.set_ylabel("MB (log)")
    ax.set_title("Memory (each point in a process of its own)")
    ax.legend(fontsize=7.5, loc="lower right", framealpha=0.6)


def plot_activity(res, out: Path) -> str:
    """Cost against activity: step time against N (log-log, with the floor), against the rocks in the air at
    fixed N, and the memory against N."""
    plt = _plt()
    act = res["activity"]
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(17, 5.2), gridspec_kw={"width_ratios": [5, 4, 3]})
    _activity_vs_n(a1, act)
    _activity_vs_air(a2, act)
    _activity_memory(a3, act)
    return _save(plt, fig, out, PNG["activity"])
