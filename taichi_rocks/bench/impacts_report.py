"""The impacts study's outputs: four plots (hits per km by gap, windscreen hits per km by gap, the height of the
windscreen hits, normal momentum and normal energy with the damage bands), the report's markdown (its own
impacts.md, or a section of the benchmark's report.md), impacts.json and the events (impacts_events.npz, one
array per run, ``EVENT_DTYPE``). Every file is written atomically (output/atomic.py)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ..config.impacts import DAMAGE_CLASSES
from ..output.atomic import new_folders, write_atomically
from .impacts_analysis import WINDSCREEN, normal_energy, own_events, summary
from .plots import TAB10, _plt, _save
from .report import check_out_dir, jsonable

PNG = {"hits": "impacts_hits_by_gap.png", "windscreen": "impacts_windscreen_by_gap.png",
       "heights": "impacts_heights.png", "damage": "impacts_damage.png"}
EVENTS = "impacts_events.npz"
FILES = tuple(PNG.values()) + (EVENTS,)  # what the section writes beside a report
OUTPUTS = ("impacts.md", "impacts.json") + FILES  # what `bench --only impacts` writes
BAND_COLORS = {"mark": "tab:green", "chip": "tab:orange", "crack": "tab:red"}
ALBERT_Z = 1.25  # m: small stones hit a follower 40 m back up to this high (Albert, Nover & Nover 2006)


def _panels(res: dict):
    """The (gravel, wet, flaps) combinations present, as panels: rows gravel, columns (wet, flaps)."""
    rows = res["rows"]
    gravels = sorted({r["gravel"] for r in rows})
    cols = sorted({(r["wet"], r["flaps"]) for r in rows})
    return gravels, cols


def _cond(wet, flaps) -> str:
    return f"{'wet' if wet else 'dry'}, flaps {'on' if flaps else 'off'}"


def plot_by_gap(res: dict, out: Path, what: str) -> str:
    """Rates per km against the gap, one line per leader x speed; a zero count at its 95 % upper bound (v)."""
    plt = _plt()
    table = res["by_gap" if what == "hits" else "by_gap_windscreen"]
    gravels, cols = _panels(res)
    fig, axes = plt.subplots(len(gravels), len(cols), figsize=(4.2 * len(cols) + 1, 3.4 * len(gravels) + 0.4),
                             squeeze=False, sharex=True, sharey=True)
    speeds = sorted({d["speed"] for d in table})
    color = {v: TAB10[i % len(TAB10)] for i, v in enumerate(speeds)}
    for i, g in enumerate(gravels):
        for j, (wet, flaps) in enumerate(cols):
            ax = axes[i][j]
            for d in table:
                if (d["gravel"], d["wet"], d["flaps"]) != (g, wet, flaps):
                    continue
                x, y = np.array(d["gaps"]), np.array(d["per_km"])
                ls = "-" if d["leader"] == "car" else "--"
                pos = y > 0
                ax.plot(x[pos], y[pos], ls, marker="o", ms=4, color=color[d["speed"]],
                        label=f"{d['leader']} {d['speed']:g} m/s")
                ax.plot(x[~pos], np.array(d["upper_per_km"])[~pos], "v", mfc="none", color=color[d["speed"]])
            ax.set(yscale="log", title=f"{g}, {_cond(wet, flaps)}")
            if i == len(gravels) - 1:
                ax.set_xlabel("gap (leader's rear to follower's front), m")
            if j == 0:
                ax.set_ylabel(f"{'hits' if what == 'hits' else 'windscreen hits'} per km")
    axes[0][-1].legend(fontsize=7, title="solid: car, dashed: truck\nv: none (95 % bound)", title_fontsize=7,
                       loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.suptitle(f"{'Hits' if what == 'hits' else 'Windscreen hits'} on the follower per km driven", fontsize=10)
    return _save(plt, fig, out, PNG[what])


def plot_heights(res: dict, out: Path) -> str:
    """Heights of the windscreen hits (body frame: above the ground) per gap: points and quartiles."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 3.8))
    hs = res["windscreen_heights"]
    gaps = sorted(float(g) for g in hs)
    rng = np.random.default_rng(0)
    for g in gaps:
        z = np.array(hs[str(g)] if str(g) in hs else hs[f"{g:g}"])
        if len(z):
            ax.plot(g + rng.uniform(-0.8, 0.8, len(z)), z, ".", ms=2, alpha=0.4, color="tab:blue")
            q = np.quantile(z, (0.25, 0.5, 0.75))
            ax.errorbar([g], [q[1]], yerr=[[q[1] - q[0]], [q[2] - q[1]]], fmt="s", color="black", capsize=4)
        ax.annotate(f"n={len(z)}", (g, 0.95), xycoords=("data", "axes fraction"), ha="center", fontsize=7)
    ax.axhline(ALBERT_Z, color="tab:red", ls="--", lw=1, label="1.25 m: Albert, Nover & Nover 2006 (40 m, 80 km/h)")
    top = max([ALBERT_Z] + [max(v) for v in hs.values() if v])
    ax.set(xlabel="gap, m", ylabel="height above the ground, m", xticks=gaps, ylim=(0.0, top + 0.35),
           title="Windscreen hits on the follower: height (all runs; squares: median, quartiles)")
    ax.legend(fontsize=7)
    return _save(plt, fig, out, PNG["heights"])


def plot_damage(res: dict, runs: list, out: Path) -> str:
    """Histograms of normal momentum and normal energy (log axes), per gravel class, the bands shaded."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.9))
    gravels = sorted({r["gravel"] for r in res["rows"]})
    for ax, (measure, unit) in zip(axes, (("momentum", "N s"), ("energy", "J"))):
        chip, crack = res["bands"][measure]
        vals = {}
        for g in gravels:
            ev = own_events(runs, gravel=g)
            v = ev["normal_momentum"] if measure == "momentum" else normal_energy(ev)
            vals[g] = (v[v > 0], (ev["part"] == WINDSCREEN)[v > 0])
        allv = np.concatenate([v for v, _ in vals.values()]) if vals else np.zeros(0)
        lo = min(chip / 100, allv.min()) if len(allv) else chip / 100
        hi = max(crack * 10, allv.max()) if len(allv) else crack * 10
        bins = np.geomspace(lo, hi * 1.01, 50)
        for (name, a, b) in (("mark", lo, chip), ("chip", chip, crack), ("crack", crack, hi * 1.01)):
            ax.axvspan(a, b, color=BAND_COLORS[name], alpha=0.12,
                       label=f"{name}: " + (f"< {chip:g}" if name == "mark" else f">= {a:g}") + f" {unit}")
        for k, (g, (v, ws)) in enumerate(vals.items()):
            c = TAB10[k]
            ax.hist(v, bins=bins, histtype="step", lw=1.5, color=c, label=f"{g}: all parts ({len(v)})")
            ax.hist(v[ws], bins=bins, histtype="stepfilled", alpha=0.35, color=c, label=f"{g}: windscreen ({ws.sum()})")
        what = "normal momentum m u_n" if measure == "momentum" else "normal energy 1/2 m u_n^2"
        ax.set(xscale="log", yscale="log", xlabel=f"{what}, {unit}", ylabel="hits",
               title=f"{what[0].upper()}{what[1:]} of the hits, [impacts] bands")
        ax.set_ylim(bottom=0.7)
        ax.legend(fontsize=7)
    return _save(plt, fig, out, PNG["damage"])


def make_plots(res: dict, runs: list, out: Path) -> tuple[list, list]:
    """Every plot of the section; (file names written, errors)."""
    names, errors = [], []
    jobs = (("hits by gap", lambda: plot_by_gap(res, out, "hits")),
            ("windscreen by gap", lambda: plot_by_gap(res, out, "windscreen")),
            ("heights", lambda: plot_heights(res, out)), ("damage", lambda: plot_damage(res, runs, out)))
    for what, fn in jobs:
        try:
            names.append(fn())
        except Exception as exc:  # a plot that fails is reported; the report is still written
            errors.append(f"impacts plot {what}: {type(exc).__name__}: {exc}")
    return names, errors


# --------------------------------------------------------------------------------------------- markdown
def _met(m) -> str:
    return {True: "**met**", False: "**MISSED**", None: "-"}[m]


def _rate(d: dict, k: int) -> str:
    return f"< {d['upper_per_km'][k]:.2g}" if d["count"][k] == 0 else f"{d['per_km'][k]:.3g} ({d['count'][k]})"


def _gap_table(table: list, gaps: list) -> list:
    L = ["| leader | speed | ground | gravel | flaps | " + " | ".join(f"{g:g} m" for g in gaps) + " |",
         "|---|---|---|---|---|" + "---|" * len(gaps)]
    for d in sorted(table, key=lambda d: tuple(d[k] for k in ("gravel", "leader", "wet", "flaps", "speed"))):
        by = {g: k for k, g in enumerate(d["gaps"])}
        cells = [_rate(d, by[g]) if g in by else "" for g in gaps]
        L.append(f"| {d['leader']} | {d['speed']:g} m/s | {'wet' if d['wet'] else 'dry'} | {d['gravel']} | "
                 f"{'on' if d['flaps'] else 'off'} | " + " | ".join(cells) + " |")
    return L + [""]


def section_lines(imp: dict, plots: list, level: str = "##") -> list:
    """The study's markdown: setup, targets, hits per km by gap, heights, damage, runs, plots."""
    cfg = imp["config"]
    runs = imp["runs"]
    ok = [r for r in runs if not r.get("error")]
    gaps = sorted({r["gap"] for r in imp["rows"]})
    L = [f"{level} Impacts: stones that hit the follower\n",
         f"Mode **{cfg['mode']}**: leaders {', '.join(cfg['leaders'])}; speeds {', '.join(f'{v:g}' for v in cfg['speeds'])}"
         f" m/s; wetness {', '.join(f'{w:g}' for w in cfg['wetness'])}; gravel {', '.join(cfg['gravels'])}; mud "
         f"flaps {', '.join('on' if f else 'off' for f in cfg['flaps'])}; gaps {', '.join(f'{g:g}' for g in cfg['gaps'])}"
         f" m, one lane each. {len(ok)} of {len(runs)} runs, {imp['elapsed_s']:.0f} s on "
         f"{imp['placement']['workers'] or 'this'} process(es)"
         + (f", bed {ok[0]['bed_radius']:g} m, {ok[0]['rocks']:,} rocks" if ok else "") + ". Distance per run: "
         f"{cfg['warm_m']:g} m warm-up (not counted), then {cfg['min_m']:g} m and on in {cfg['chunk_m']:g} m chunks "
         f"until every lane has {cfg['enough']} windscreen hits or a 95 % bound under {cfg['bound_per_km']:g} /km, at "
         f"most {cfg['max_m']:g} m. Zero counts are shown as the one-sided 95 % Poisson upper bound (< 3.0 / km "
         "driven).\n",
         "| target | measured | met | detail | why, where missed |", "|---|---|---|---|---|"]
    for t in imp["targets"]:
        L.append(f"| {t['target']} | {t['shown']} | {_met(t['met'])} | {t['detail']} | {t['reason']} |")
    cl = imp["cross_lane"]
    L += ["", f"Hits across lanes (a follower hit by another lane's leader): {cl['cross']} against {cl['own']} own-lane "
              f"hits ({100 * cl['share']:.2f} %).\n"]
    for p in plots:
        L.append(f"![{p}]({p})\n")
    L += [f"{level}# Hits per km by gap (all parts; count in brackets; < bound: none)\n"]
    L += _gap_table(imp["by_gap"], gaps)
    L += [f"{level}# Windscreen hits per km by gap\n"] + _gap_table(imp["by_gap_windscreen"], gaps)
    L += [f"{level}# Height of the windscreen hits (above the ground)\n", "| gap | hits | median | 90 % | max |",
          "|---|---|---|---|---|"]
    for g, z in imp["windscreen_heights"].items():
        if z:
            q = np.quantile(z, (0.5, 0.9))
            L.append(f"| {float(g):g} m | {len(z)} | {q[0]:.2f} m | {q[1]:.2f} m | {max(z):.2f} m |")
        else:
            L.append(f"| {float(g):g} m | 0 | | | |")
    L.append("")
    if "damage" in imp:
        b = imp["bands"]
        L += [f"{level}# Damage classes ([impacts] defaults; proxies, config/impacts.py)\n",
              f"Bands: momentum chip {b['momentum'][0]:g} N s, crack {b['momentum'][1]:g} N s; energy chip "
              f"{b['energy'][0]:g} J, crack {b['energy'][1]:g} J.\n",
              "| hits | measure | " + " | ".join(DAMAGE_CLASSES) + " |", "|---|---|" + "---|" * len(DAMAGE_CLASSES)]
        for what, key in (("all parts", "damage"), ("windscreen", "damage_windscreen")):
            for m in ("momentum", "energy"):
                L.append(f"| {what} | {m} | " + " | ".join(str(imp[key][m][c]) for c in DAMAGE_CLASSES) + " |")
        L.append("")
    L += [f"{level}# Runs\n", "| run | km | steps | ms / step | own hits | windscreen | dropped | error |",
          "|---|---|---|---|---|---|---|---|"]
    per_run = {}
    for r in imp["rows"]:
        s = per_run.setdefault(r["run"], [0, 0])
        s[0] += r["hits"]
        s[1] += r["windscreen"]
    for r in runs:
        if r.get("error"):
            L.append(f"| {r['id']} | | | | | | | {r['error']} |")
            continue
        h = per_run.get(r["id"], [0, 0])
        L.append(f"| {r['id']} | {r['distance_m'] / 1e3:.2f} | {r['steps']:,} | {r['ms_per_step']:.2f} | {h[0]} | "
                 f"{h[1]} | {r['dropped']} | |")
    L.append("")
    L += [f"- error: {e}" for e in imp.get("errors", [])]
    return L


def write_events(runs: list, path: Path) -> None:
    """One structured array per run (its id as the key), atomically."""
    arrays = {r["id"]: r["events"] for r in runs if "events" in r}

    def write(f):
        np.savez_compressed(f, **arrays)

    write_atomically(path, write)


def write_section_files(imp: dict, out: Path) -> tuple[list, list]:
    """The plots and the events of a finished section into ``out``; (plot names, errors)."""
    runs = [r for r in imp["_runs"] if not r.get("error")]
    plots, errors = make_plots(imp, runs, out) if runs else ([], ["no run finished: no plots"])
    write_events(imp["_runs"], out / EVENTS)
    return plots, errors


def write_outputs(res: dict, out: Path) -> dict:
    """`bench --only impacts`: the plots, the events, impacts.md and impacts.json; the names written."""
    imp = res["impacts"]
    plots, errors = write_section_files(imp, out)
    imp["errors"] += errors
    imp["plots"] = plots
    m = res["machine"]
    head = ["# taichi-rocks benchmark: impacts\n",
            f"{res['started']}; {m['cpu_model']}, {m['usable_cores']} usable cores, {m['memory_gb']} GB; Taichi "
            f"{m['taichi']} ({m['taichi_arch']}). Load average (1, 5, 15 min) at the start "
            f"{res['load_average_start']}, at the end {res['load_average_end']}.\n"]
    text = "\n".join(head + section_lines(imp, plots))
    write_atomically(out / "impacts.md", lambda f: f.write(text.encode()))
    blob = json.dumps(jsonable(res), indent=1)
    write_atomically(out / "impacts.json", lambda f: f.write(blob.encode()))
    return {"plots": plots, "report": str(out / "impacts.md")}


def reanalyse(src, out, overwrite: bool = False) -> dict:
    """The report of an earlier run again, from its impacts.json and impacts_events.npz in ``src`` (the runs are
    not run again: the analysis, targets and plots of this code), written to ``out`` like ``bench --only
    impacts`` writes them (refused if ``out`` holds them, unless ``overwrite``)."""
    src, out = Path(src), Path(out)
    res = json.loads((src / "impacts.json").read_text())
    imp = res["impacts"]
    with np.load(src / EVENTS) as z:
        runs = [dict(r, events=z[r["id"]]) if r["id"] in z.files else dict(r) for r in imp["runs"]]
    check_out_dir(out, OUTPUTS, overwrite)
    fresh = summary(runs, imp.get("launch"))
    errors = [e for e in imp.get("errors", []) if not e.startswith("impacts plot")]
    imp.update(fresh, _runs=runs)
    imp["errors"] = list(dict.fromkeys(errors + fresh["errors"]))
    res["errors"] = imp["errors"]
    with new_folders(out):
        return write_outputs(res, out)


if __name__ == "__main__":  # python -m taichi_rocks.bench.impacts_report SRC OUT [--overwrite]
    print(reanalyse(sys.argv[1], sys.argv[2], "--overwrite" in sys.argv[3:])["report"])
