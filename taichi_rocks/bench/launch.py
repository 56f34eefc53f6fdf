"""The launch study (`taichi-rocks bench --only launch`): what the tread model throws, measured on the engine.

Setup. A car (tire radius 0.33 m, contact length 0.12 m, slip 0.15, fenders at 50 deg) drives straight at V
through a bed of gravel of radius 6 m ([sim] accuracy = "balanced", detection = "patch"). The bed stands
still: it follows a parked vehicle that throws nothing, so that each thrown rock is followed in the ground
frame from launch to landing (a bed following the car would recycle the rocks it leaves behind while they
are still in the air). The study steps the simulation and reads ``state()`` every step while the car is in
the bed, then every few steps until the thrown rocks have landed, and records for each launch:
  * the release angle, recovered from the launch velocity: v = k (V f - s cos(a) Rot(b) f, s sin a) with
    s = V (1 + slip) gives (V^2 - s^2) k^2 - 2 V v_x k + |v|^2 = 0 for k, then
    a = atan2(v_z, sign(V k - v_x) |(V k - v_x, v_y)|); a stone stopped by the fender, e (v_xy, -|v_z|), is
    first divided by e and turned up again;
  * the launch speed over V; the apex above its resting height on its first arc; where it first lands
    relative to the tire (m behind it at that moment); rocks the bed recycles in the air are counted apart.
Cases: V in {10, 20, 30} m/s, dry and wet (wetness 1), small (1.5-2.5 cm), large (3-5 cm) and the default
gravel (1.5-5 cm). Targets (at V = 20 m/s, dry gravel, defaults) are those of docs/physics.md, "The throw", with
the reference bands of the field reports drawn on the histograms. Also: launches per metre driven with
"patch" and "swept" detection, in a bed that follows the car.
"""

from __future__ import annotations

import io
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from ..config.scene import parse_scene
from ..engine.simulation import Simulation
from ..engine.world import FLYING, RESTING, SLIDING
from ..output.atomic import new_folders, write_atomically
from .report import check_out_dir

SPEEDS = (10.0, 20.0, 30.0)
SIZES = {"gravel": (0.015, 0.05), "small": (0.015, 0.025), "large": (0.03, 0.05)}
WETNESS = (0.0, 1.0)
SLIP, WHEELBASE, TIRE_R, CONTACT, FENDER = 0.15, 2.7, 0.33, 0.12, 50.0
BED_RADIUS = 8.0
START, END = -3.0, 9.0  # m, the car's path through the bed (its rear tires from -4.35 to 7.65 m)
TRACK_EVERY = 4  # steps between reads once the car has left the bed
SIZES_OF_RUN = {"full": (40000, 3, 2.0, 4.0), "quick": (6000, 1, 0.5, 4.0), "tiny": (1500, 1, 0.25, 2.0)}
# per run size: rocks, seeds of the reference case, seconds of the launch-rate runs, seconds followed after the
# car has left the bed
# reference bands (docs/physics.md, "The throw"): proxies from field reports
BANDS = {"Berner 2003: >20 mm stones at 70 km/h bounced ~0.6 m": 0.6,
         "Albert 2006: 2-8 mm pebbles at 80 km/h rose to ~1.4 m": 1.4,
         "target: 95 % below 1.5 m": 1.5, "target: 99.9 % below 3 m": 3.0}


def _progress(enabled):
    """progress(desc): True prints to stderr, None only on a terminal, False never."""
    on = enabled is True or (enabled is None and sys.stderr.isatty())
    return (lambda desc: print(f"launch study: {desc}", file=sys.stderr, flush=True)) if on else (lambda desc: None)


def throw_scene(speed: float, wetness: float, radii, rocks: int, seed: int, start: float = START,
                end: float = END):
    """The still bed and the car driving through it (see the module docstring)."""
    car = {"name": "car", "tire_radius": TIRE_R, "contact_length": CONTACT, "slip": SLIP, "wheelbase": WHEELBASE,
           "fender_angle": FENDER, "path": {"points": [[start, 0.0], [end, 0.0]], "speed": speed}}
    anchor = {"name": "anchor", "splash": False, "path": {"points": [[0.0, 0.0], [1.0, 0.0]], "speed": 0.0}}
    data = {"name": "launch_study", "seed": seed, "duration": 10.0, "world": {"wetness": wetness},
            "bed": {"radius": BED_RADIUS, "rocks": rocks, "rock_radius": list(radii), "follow": "anchor"},
            "sim": {"accuracy": "balanced", "detection": "patch"}, "vehicle": [anchor, car]}
    return parse_scene(data, source="<launch study>")


def release_angles(v: np.ndarray, speed: float, restitution: float, slip: float = SLIP) -> np.ndarray:
    """Release angle (rad) from launch velocities v (N, 3) of a tire rolling along +x (module docstring)."""
    v = np.array(v, np.float64)
    stopped = v[:, 2] < 0.0
    v[stopped] /= restitution
    v[stopped, 2] *= -1.0
    s = speed * (1.0 + slip)
    a, b, c = speed ** 2 - s ** 2, -2.0 * speed * v[:, 0], np.einsum("ij,ij->i", v, v)
    if abs(a) < 1e-12:
        k = c / np.maximum(-b, 1e-12)
    else:
        k = (-b - np.sqrt(np.maximum(b * b - 4.0 * a * c, 0.0))) / (2.0 * a)  # the positive root (a < 0)
    back = speed * k - v[:, 0]
    return np.arctan2(v[:, 2], np.sign(back) * np.hypot(back, v[:, 1]))


class Tracker:
    """Launch records of one run: velocities at launch, apex and first landing."""

    def __init__(self, st):
        self.prev = st
        self.rows: list[dict] = []
        self.open: dict[int, dict] = {}  # rock id -> its record while in the air

    def update(self, st, tire_x: float) -> None:
        p0, p1 = self.prev["phase"], st["phase"]
        v0, v1 = self.prev["velocities"], st["velocities"]
        x0, x1 = self.prev["positions"], st["positions"]
        kicked = np.linalg.norm(v1 - v0, axis=1) > 0.5
        new = ((p0 == RESTING) & (p1 != RESTING)) | ((p0 == SLIDING) & ((p1 == FLYING) | kicked))
        for i in np.flatnonzero(new):
            if i in self.open:
                self._close(i, self.prev, tire_x, landed=True)
            rec = {"v": v1[i].astype(np.float64), "r": float(st["radii"][i]), "z0": float(x0[i, 2]),
                   "apex": float(x1[i, 2] - x0[i, 2]), "landed": None, "behind": None, "lost": False}
            self.rows.append(rec)
            self.open[i] = rec
        ground = float(st["bed_center"][2])
        for i in list(self.open):
            if new[i]:
                continue
            rec = self.open[i]
            jump = np.linalg.norm(x1[i, :2] - x0[i, :2]) > 0.5
            if jump:  # recycled by the bed while in the air
                rec["lost"] = True
                del self.open[i]
                continue
            rec["apex"] = max(rec["apex"], float(x1[i, 2] - rec["z0"]))
            touched = p1[i] != FLYING or (v0[i, 2] < 0.0 <= v1[i, 2] and x1[i, 2] - st["radii"][i] - ground < 0.05)
            if touched:
                self._close(i, st, tire_x, landed=True)

    def _close(self, i, st, tire_x, landed):
        rec = self.open.pop(i)
        rec["landed"] = landed
        rec["behind"] = float(tire_x - st["positions"][i, 0])

    def step_done(self, st):
        self.prev = st


def follow_throws(scene, speed: float, arch: str, follow_s: float = 4.0) -> dict:
    """Run one case and return its launch records as arrays."""
    sim = Simulation(scene, arch=arch)
    car = sim.scene.vehicle_index("car")
    st = sim.state()
    tr = Tracker(st)
    dt = sim.dt
    t_end_drive = (END - START) / speed + 0.01
    t_max = t_end_drive + follow_s
    while sim.time < t_max:
        driving = sim.time < t_end_drive
        n = 1 if driving else TRACK_EVERY
        sim.step(n)
        st = sim.state()
        tire_x = float(st["vehicle_positions"][car, 0]) - 0.5 * WHEELBASE
        tr.update(st, tire_x)
        tr.step_done(st)
        if not driving and not tr.open:
            break
    rows = tr.rows
    v = np.array([r["v"] for r in rows]).reshape(-1, 3)
    out = {"v": v, "radius": np.array([r["r"] for r in rows]), "apex": np.array([r["apex"] for r in rows]),
           "behind": np.array([np.nan if r["behind"] is None else r["behind"] for r in rows]),
           "lost": np.array([r["lost"] for r in rows], bool), "launches_total": sim.launches_total,
           "steps": sim.step_count, "dt": dt}
    out["alpha"] = release_angles(v, speed, sim.scene.world.restitution) if len(v) else np.zeros(0)
    out["speed_ratio"] = np.linalg.norm(v, axis=1) / speed if len(v) else np.zeros(0)
    return out


def _merge(runs: list[dict]) -> dict:
    keys = ("v", "radius", "apex", "behind", "lost", "alpha", "speed_ratio")
    out = {k: np.concatenate([r[k] for r in runs]) for k in keys}
    out["launches_total"] = int(sum(r["launches_total"] for r in runs))
    return out


def launches_per_metre(detection: str, rocks: int, speed: float, seconds: float, arch: str) -> dict:
    """Launches per metre driven by one car with a bed that follows it (the everyday setup)."""
    car = {"name": "car", "path": {"points": [[0.0, 0.0], [speed * seconds + 50.0, 0.0]], "speed": speed}}
    data = {"name": "launch_rate", "seed": 1, "duration": seconds,
            "bed": {"radius": BED_RADIUS, "rocks": rocks, "rock_radius": [0.015, 0.05]},
            "sim": {"accuracy": "balanced", "detection": detection}, "vehicle": [car]}
    sim = Simulation(parse_scene(data, source="<launch study>"), arch=arch)
    sim.step(int(round(0.5 / sim.dt)))  # settle: the bed's density ahead of the car is reached
    n0, t0 = sim.launches_total, sim.time
    sim.step(int(round(seconds / sim.dt)))
    metres = speed * (sim.time - t0)
    return {"detection": detection, "launches": sim.launches_total - n0, "metres": metres,
            "per_metre": (sim.launches_total - n0) / metres}


def launch_stats(d: dict) -> dict:
    """Statistics of one case's launch records (arrays alpha, apex, lost, behind, radius, speed_ratio)."""
    a, apex, ok = d["alpha"], d["apex"], ~d["lost"]
    behind = d["behind"][np.isfinite(d["behind"])]
    big = d["radius"] >= 0.03
    return {
        "launches": int(len(a)), "launches_total": d["launches_total"], "lost_in_air": int(d["lost"].sum()),
        "alpha_median_deg": float(np.degrees(np.median(a))) if len(a) else math.nan,
        "alpha_mean_deg": float(np.degrees(np.mean(a))) if len(a) else math.nan,
        "alpha_above_25": float(np.mean(a > math.radians(25))) if len(a) else math.nan,
        "apex_median": float(np.median(apex[ok])) if ok.any() else math.nan,
        "apex_mean": float(np.mean(apex[ok])) if ok.any() else math.nan,
        "apex_p95": float(np.percentile(apex[ok], 95)) if ok.any() else math.nan,
        "apex_max": float(np.max(apex)) if len(apex) else math.nan,
        "below_1_5": float(np.mean(apex < 1.5)) if len(apex) else math.nan,
        "below_3": float(np.mean(apex < 3.0)) if len(apex) else math.nan,
        "big_above_1": float(np.mean(apex[big] > 1.0)) if big.any() else math.nan,
        "big_launches": int(big.sum()),
        "speed_ratio_max": float(np.max(d["speed_ratio"])) if len(a) else math.nan,
        "behind_median": float(np.median(behind)) if len(behind) else math.nan,
        "behind_p95": float(np.percentile(behind, 95)) if len(behind) else math.nan,
        "behind_max": float(np.max(behind)) if len(behind) else math.nan,
        "beyond_40": float(np.mean(behind > 40.0)) if len(behind) else math.nan,
    }


# ------------------------------------------------------------------------------------------------ targets
# the bands one case is held to (docs/physics.md, "The throw"; stated for V 20, dry gravel): what, statistic, limit,
# whether the statistic must be at most (True) or at least (False) the limit
BAND_TARGETS = (
    (": >= 95 % of launched rocks peak below 1.5 m", "below_1_5", 0.95, False),
    (": >= 99.9 % peak below 3 m", "below_3", 0.999, False),
    (": median release angle <= 10 deg", "alpha_median_deg", 10.0, True),
    (": <= 5 % released above 25 deg", "alpha_above_25", 0.05, True),
    (", rocks r >= 3 cm: <= 1 % peak above 1 m", "big_above_1", 0.01, True),
)


def band_met(stats: dict, key: str) -> bool:
    """Whether a case's statistic ``key`` meets its band of BAND_TARGETS (a statistic not measured: no)."""
    _, _, limit, at_most = next(b for b in BAND_TARGETS if b[1] == key)
    value = stats[key]
    return bool(value <= limit if at_most else value >= limit)


def _row(name, value, met=None, shown=None):
    return {"target": name, "value": value, "shown": shown if shown is not None else f"{value:.4g}",
            "met": met}


def targets(stats: dict, rate: dict) -> list[dict]:
    """The table: every target with its measured value and whether it is met (met None: reported only)."""
    g = lambda v, w="dry", s="gravel": stats[f"V{v:g} {w} {s}"]
    ref = g(20)
    med = [g(v)["apex_median"] for v in SPEEDS]
    wet, small, large = g(20, "wet"), g(20, "dry", "small"), g(20, "dry", "large")
    pct = lambda x: f"{100 * x:.2f} %"
    shown = {"below_1_5": pct(ref["below_1_5"]), "below_3": pct(ref["below_3"]),
             "alpha_median_deg": f"{ref['alpha_median_deg']:.2f} deg", "alpha_above_25": pct(ref["alpha_above_25"]),
             "big_above_1": pct(ref["big_above_1"]) + f" of {ref['big_launches']}"}
    rows = [_row(f"V 20, dry gravel{what}", ref[key], band_met(ref, key), shown[key])
            for what, key, _, _ in BAND_TARGETS]
    rows += [
        _row("median apex rises with speed, 10 -> 20 -> 30 m/s (dry gravel)", med[-1] - med[0],
             bool(med[0] < med[1] < med[2]), " -> ".join(f"{m * 100:.1f} cm" for m in med)),
        _row("wet ground (w = 1) releases later and throws higher (V 20 gravel: mean angle, mean apex)",
             wet["apex_mean"] - ref["apex_mean"],
             bool(wet["alpha_mean_deg"] > ref["alpha_mean_deg"] and wet["apex_mean"] > ref["apex_mean"]),
             f"dry -> wet: {ref['alpha_mean_deg']:.1f} -> {wet['alpha_mean_deg']:.1f} deg, "
             f"{100 * ref['apex_mean']:.1f} -> {100 * wet['apex_mean']:.1f} cm"),
        _row("small stones (1.5-2.5 cm) release later and fly higher than large (3-5 cm) (V 20 dry)",
             small["apex_mean"] - large["apex_mean"],
             bool(small["alpha_mean_deg"] > large["alpha_mean_deg"] and small["apex_mean"] > large["apex_mean"]),
             f"large -> small: {large['alpha_mean_deg']:.1f} -> {small['alpha_mean_deg']:.1f} deg, "
             f"{100 * large['apex_mean']:.1f} -> {100 * small['apex_mean']:.1f} cm"),
        _row("V 20, dry gravel: landing, m behind the tire (median / 95th pct / max)", ref["behind_median"], None,
             f"{ref['behind_median']:.2f} / {ref['behind_p95']:.2f} / {ref['behind_max']:.2f} m"),
        _row("V 20, dry gravel: share landing > 40 m behind the tire", ref["beyond_40"], None, pct(ref["beyond_40"])),
        _row("V 30, wet gravel: share landing > 40 m behind the tire", g(30, "wet")["beyond_40"], None,
             pct(g(30, "wet")["beyond_40"])),
        _row("launches per metre driven, patch / swept detection (V 20, bed following the car)",
             rate["patch"]["per_metre"] / max(rate["swept"]["per_metre"], 1e-12), None,
             f"{rate['patch']['per_metre']:.2f} / {rate['swept']['per_metre']:.2f} = "
             f"{rate['patch']['per_metre'] / max(rate['swept']['per_metre'], 1e-12):.2f} x"),
    ]
    return rows


# ------------------------------------------------------------------------------------------------ plots
PNG = {"apex": "launch_apex.png", "release": "launch_release.png", "speed": "launch_speed_landing.png",
       "trends": "launch_trends.png"}
OUTPUTS = ("launch_study.md", "launch_study.json") + tuple(PNG.values())  # what run_launch_study writes


def _save(fig, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    write_atomically(path, lambda f: f.write(buf.getvalue()))


def plot_all(data: dict, out: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    cases = [k for k in ("V20 dry gravel", "V20 wet gravel", "V20 dry small", "V20 dry large") if k in data]
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    bins = np.linspace(0, 3.2, 65)
    for k in cases:
        ax.hist(np.minimum(data[k]["apex"], 3.19), bins=bins, histtype="step", lw=1.5, label=k)
    for (label, h), c in zip(BANDS.items(), ("tab:gray", "tab:brown", "tab:red", "black")):
        ax.axvline(h, color=c, ls="--", lw=1, label=label)
    ax.set(yscale="log", xlabel="apex above resting height, m", ylabel="launched rocks",
           title="Apex of thrown rocks, V = 20 m/s (last bin: >= 3.2 m)")
    ax.legend(fontsize=7)
    _save(fig, out / PNG["apex"])
    names.append(PNG["apex"])
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    ap = math.degrees(math.asin(CONTACT / (2 * TIRE_R)))
    ax.axvspan(0, ap, color="tab:green", alpha=0.15, label=f"contact patch exit (0-{ap:.1f} deg; Plocher 2014)")
    for k in cases:
        ax.hist(np.degrees(data[k]["alpha"]), bins=np.linspace(0, 180, 91), histtype="step", lw=1.5, label=k)
    ax.axvline(10, color="tab:red", ls="--", lw=1, label="target: median <= 10 deg")
    ax.axvline(25, color="black", ls="--", lw=1, label="target: <= 5 % above 25 deg")
    ax.axvline(FENDER, color="tab:gray", ls=":", lw=1.5, label="fender (stones above it drop)")
    ax.set(yscale="log", xlabel="release angle up the back of the tire, deg", ylabel="launched rocks",
           title="Release angle (recovered from the launch velocity), V = 20 m/s")
    ax.legend(fontsize=7)
    _save(fig, out / PNG["release"])
    names.append(PNG["release"])
    plt.close(fig)
    names += _plot_speed_and_landing(plt, data, out)
    return names


def _plot_speed_and_landing(plt, data: dict, out: Path) -> list[str]:
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2))
    a = np.linspace(0, math.pi, 200)
    s = 1.0 + SLIP
    for k, c in (("V20 dry gravel", "tab:blue"), ("V20 wet gravel", "tab:orange")):
        if k in data:
            ax.plot(np.degrees(data[k]["alpha"]), data[k]["speed_ratio"], ".", ms=2, color=c, label=k)
    ax.plot(np.degrees(a), np.sqrt(1 - 2 * s * np.cos(a) + s * s), "k-", lw=1, label="tread point, slip 0.15")
    ax.plot(np.degrees(a), 2 * np.sin(a / 2), "k--", lw=1, label="rolling: 2 sin(alpha/2)")
    ax.set(xlabel="release angle, deg", ylabel="|v| / V", title="Launch speed (fender-stopped: e |v|)")
    ax.legend(fontsize=7)
    for v in SPEEDS:
        k = f"V{v:g} dry gravel"
        if k in data:
            d = data[k]["behind"]
            bx.hist(d[np.isfinite(d)], bins=np.linspace(-2, 60, 63), histtype="step", lw=1.5, label=k)
    bx.axvline(40, color="black", ls="--", lw=1, label="40 m (Albert 2006, Strobl 1996)")
    bx.set(yscale="log", xlabel="first landing, m behind the tire", ylabel="launched rocks",
           title="Where thrown rocks land")
    bx.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, out / PNG["speed"])
    plt.close(fig)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    # the median is the pinched stones' (most of them); the 99th percentile is the carried few, where wetness
    # (adhesion holds them on longer) and size (small ones are carried) show
    for cx, (q, what) in zip(axes, ((50, "median apex"), (99, "99th percentile of the apex"))):
        for w in ("dry", "wet"):
            for size in SIZES:
                keys = [f"V{v:g} {w} {size}" for v in SPEEDS]
                if all(k in data for k in keys):
                    cx.plot(SPEEDS, [100 * np.percentile(data[k]["apex"], q) for k in keys],
                            "o-" if w == "dry" else "s--", label=f"{w} {size}")
        cx.set(xlabel="V, m/s", ylabel=f"{what}, cm", title=f"{what[0].upper()}{what[1:]} against speed")
        cx.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, out / PNG["trends"])
    plt.close(fig)
    return [PNG["speed"], PNG["trends"]]


# ------------------------------------------------------------------------------------------------ the study
NEEDED = ("V10 dry gravel", "V20 dry gravel", "V30 dry gravel", "V20 wet gravel", "V20 dry small", "V20 dry large",
          "V30 wet gravel")  # the cases the targets read (the quick run runs only these)


def cases(quick: bool) -> list[tuple[str, float, float, str]]:
    out = [(f"V{v:g} {'wet' if w else 'dry'} {s}", v, w, s) for s in SIZES for w in WETNESS for v in SPEEDS]
    return [c for c in out if c[0] in NEEDED] if quick else out


def _report(rows: list[dict], stats: dict, rate: dict, plots: list[str], meta: dict) -> str:
    lines = ["# Launch study", "",
             f"{meta['rocks']} rocks in a still bed of radius {BED_RADIUS:g} m, one car (tire radius {TIRE_R} m, "
             f"contact length {CONTACT} m, slip {SLIP}, fender at {FENDER:g} deg) driving through it; "
             f"accuracy \"balanced\", detection \"patch\", default [launch] parameters. {meta['elapsed_s']:.0f} s"
             f" on {meta['arch']} ({meta['run']} run).", "",
             "| target | measured | met |", "|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['target']} | {r['shown']} | {'-' if r['met'] is None else ('yes' if r['met'] else 'NO')} |")
    lines += ["", "| case | launches | lost in air | median angle | > 25 deg | median apex | 95 % apex | max apex "
                  "| < 1.5 m | landing behind (median) | > 40 m |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for k, s in stats.items():
        lines.append(f"| {k} | {s['launches']} | {s['lost_in_air']} | {s['alpha_median_deg']:.1f} deg | "
                     f"{100 * s['alpha_above_25']:.1f} % | {100 * s['apex_median']:.1f} cm | "
                     f"{100 * s['apex_p95']:.1f} cm | {s['apex_max']:.2f} m | {100 * s['below_1_5']:.2f} % | "
                     f"{s['behind_median']:.2f} m | {100 * s['beyond_40']:.2f} % |")
    lines += ["", "Launches per metre driven (bed following the car, V = 20 m/s): " + ", ".join(
        f"{d}: {r['launches']} in {r['metres']:.0f} m = {r['per_metre']:.2f}/m" for d, r in rate.items()), ""]
    lines += [f"![{p}]({p})" for p in plots]
    return "\n".join(lines) + "\n"


def run_launch_study(out_dir="renders/bench", quick: bool = False, arch: str = "cpu", progress=None,
                     tiny: bool = False, overwrite: bool = False) -> dict:
    """Run the study; write launch_study.md, launch_study.json and PNG plots (:data:`OUTPUTS`, atomically) to
    ``out_dir``, which must not hold them already unless ``overwrite`` (FileExistsError before anything runs);
    the missing folders of ``out_dir`` are created, and removed again if the study fails. Returns the results
    with "table" (the targets), "stats" (per case), "rate", "plots" and "report" (the .md path).
    ``quick``: only the cases the targets read, smaller; ``tiny``: smaller still (tests)."""
    out = Path(out_dir)
    check_out_dir(out, OUTPUTS, overwrite)
    with new_folders(out):
        return _launch_study(out, quick, arch, progress, tiny)


def _launch_study(out: Path, quick: bool, arch: str, progress, tiny: bool) -> dict:
    t0 = time.perf_counter()
    say = _progress(progress)
    size_of_run = "tiny" if tiny else ("quick" if quick else "full")
    rocks, ref_seeds, rate_s, follow_s = SIZES_OF_RUN[size_of_run]
    data, stats = {}, {}
    for name, v, w, size in cases(quick or tiny):
        seeds = ref_seeds if name == "V20 dry gravel" else 1
        runs = []
        for seed in range(1, seeds + 1):
            say(f"{name}, seed {seed}")
            runs.append(follow_throws(throw_scene(v, w, SIZES[size], rocks, seed), v, arch, follow_s))
        data[name] = _merge(runs)
        stats[name] = launch_stats(data[name])
    rate = {}
    for det in ("patch", "swept"):
        say(f"launches per metre, {det}")
        rate[det] = launches_per_metre(det, rocks, 20.0, rate_s, arch)
    rows = targets(stats, rate)
    say("plots")
    plots = plot_all(data, out)
    meta = {"rocks": rocks, "run": size_of_run, "quick": quick or tiny, "arch": arch,
            "elapsed_s": time.perf_counter() - t0}
    report = out / "launch_study.md"
    text = _report(rows, stats, rate, plots, meta)
    write_atomically(report, lambda f: f.write(text.encode()))
    res = {"table": rows, "stats": stats, "rate": rate, "plots": plots, "meta": meta, "report": str(report)}
    blob = json.dumps(res, indent=1, default=lambda x: x.item() if hasattr(x, "item") else str(x))
    write_atomically(out / "launch_study.json", lambda f: f.write(blob.encode()))
    return res
