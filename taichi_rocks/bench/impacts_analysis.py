"""The impacts study's analysis (no Taichi): hits per km by gap from the events of its runs, the height of the
windscreen hits, the damage bands of normal momentum and normal energy, and the issue's targets with their
verdicts.

A run (bench/impacts.py) drives five lanes side by side, each a leader that throws and a follower that is hit at
one gap; its result holds the events (engine/events.py ``EVENT_DTYPE``) recorded over ``distance_m`` metres
after the warm-up, and per lane the scene indices of its leader and follower. A lane's hits are the events on
its follower thrown by its own leader; hits from another lane's leader are counted apart ("cross-lane", they
should be ~0: lanes are 10 m apart and the throw's scatter is +-8 deg).

Rates are hits per km driven. Counts are Poisson: the one-sided 95 % upper bound of a count n is
chi2.ppf(0.95, 2 n + 2) / 2 (Garwood 1936), 3.00 for n = 0 (so a zero count over d km reads "< 3.0 / d per km"),
and the lower bound chi2.ppf(0.05, 2 n) / 2. "Falls with the gap" allows a rise only within Poisson error: the
rate at the larger gap may exceed the smaller's only if the 95 % bounds overlap.

Damage classes (config/impacts.py): mark < chip <= chip < crack <= crack, by normal momentum m u_n (N s) or by
normal kinetic energy 1/2 m u_n^2 = 1/2 normal_momentum x normal_speed (J), the defaults of [impacts].
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from ..config.impacts import DAMAGE_CLASSES, Impacts
from ..motion.bodies import LABELS

WINDSCREEN, ROOF = LABELS.index("windscreen"), LABELS.index("roof")
CL = 0.95  # confidence of the Poisson bounds
BIG_RADIUS = 0.010  # m: "stones over 20 mm" (diameter) of Berner et al. 2003
GRAVEL = {"coarse": (0.0075, 0.025), "chippings": (0.002, 0.008)}  # m, the study's rock radius ranges


def poisson_upper(n: int, cl: float = CL) -> float:
    """One-sided upper bound of a Poisson mean given a count n (n = 0: -ln(1 - cl) = 3.00 at 95 %)."""
    return float(chi2.ppf(cl, 2 * int(n) + 2) / 2.0)


def poisson_lower(n: int, cl: float = CL) -> float:
    return 0.0 if n <= 0 else float(chi2.ppf(1.0 - cl, 2 * int(n)) / 2.0)


def normal_energy(ev: np.ndarray) -> np.ndarray:
    """J: 1/2 m u_n^2 of each event, from its normal momentum and normal speed."""
    return 0.5 * ev["normal_momentum"] * ev["normal_speed"]


def damage_bands(imp: Impacts | None = None) -> dict:
    """The band edges per measure: {"momentum": (chip, crack) N s, "energy": (chip, crack) J}."""
    imp = imp or Impacts()
    return {"momentum": (imp.chip_momentum, imp.crack_momentum), "energy": (imp.chip_energy, imp.crack_energy)}


def damage_counts(values: np.ndarray, edges) -> dict:
    chip, crack = edges
    cls = np.where(values < chip, 0, np.where(values < crack, 1, 2))
    return {name: int(np.count_nonzero(cls == k)) for k, name in enumerate(DAMAGE_CLASSES)}


# --------------------------------------------------------------------------------------------- per lane
CONFIG_KEYS = ("leader", "speed", "wet", "gravel", "flaps")


def lane_events(run: dict, lane: dict) -> tuple[np.ndarray, np.ndarray]:
    """(own, cross): the events on this lane's follower thrown by its own leader, and by anyone else."""
    ev = run["events"]
    on = ev["vehicle"] == lane["follower"]
    own = on & (ev["thrower"] == lane["leader"])
    return ev[own], ev[on & ~own]


def lane_rows(runs: list) -> list:
    """One row per (run, lane): the run's configuration, the gap, counts of hits (all, windscreen, roof, by
    stones over 20 mm on windscreen or roof, cross-lane), their rates per km and bounds."""
    rows = []
    for run in runs:
        if run.get("error"):
            continue
        km = run["distance_m"] / 1000.0
        for lane in run["lanes"]:
            own, cross = lane_events(run, lane)
            ws = own["part"] == WINDSCREEN
            big_high = (own["radius"] > BIG_RADIUS) & ((own["part"] == WINDSCREEN) | (own["part"] == ROOF))
            row = {k: run[k] for k in CONFIG_KEYS}
            row.update(run=run["id"], gap=float(lane["gap"]), km=km, hits=int(len(own)),
                       windscreen=int(ws.sum()), roof=int((own["part"] == ROOF).sum()),
                       big_high=int(big_high.sum()), stones=int(len(np.unique(own["rock"]))),
                       cross=int(len(cross)))
            for what in ("hits", "windscreen", "stones"):
                n = row[what]
                row[f"{what}_per_km"] = n / km if km > 0 else math.nan
                row[f"{what}_upper_per_km"] = poisson_upper(n) / km if km > 0 else math.nan
                row[f"{what}_lower_per_km"] = poisson_lower(n) / km if km > 0 else math.nan
            z = own["point"][ws, 2] if len(own) else np.zeros(0)
            row["windscreen_z"] = [float(q) for q in np.quantile(z, (0.5, 0.9))] + [float(z.max())] if len(z) else []
            rows.append(row)
    return rows


def select(rows: list, **want) -> list:
    """The rows whose keys match: a value, a tuple of allowed values, or a predicate."""
    def ok(r, k, v):
        if callable(v):
            return bool(v(r[k]))
        if isinstance(v, tuple):
            return r[k] in v
        return r[k] == v
    return [r for r in rows if all(ok(r, k, v) for k, v in want.items())]


def pooled(rows: list, what: str = "windscreen") -> dict:
    """Count, km, rate and 95 % upper bound per km of ``what`` over a set of rows."""
    n = int(sum(r[what] for r in rows))
    km = float(sum(r["km"] for r in rows))
    return {"count": n, "km": km, "per_km": n / km if km else math.nan,
            "upper_per_km": poisson_upper(n) / km if km else math.nan, "rows": len(rows)}


def _rate_text(p: dict, what: str = "windscreen hits") -> str:
    if not p["rows"]:
        return "not measured"
    if p["count"] == 0:
        return f"0 {what} in {p['km']:.2f} km (< {p['upper_per_km']:.2g} /km, 95 %)"
    return f"{p['count']} {what} in {p['km']:.2f} km = {p['per_km']:.3g} /km"


# --------------------------------------------------------------------------------------------- targets
def _target(name, value, met, shown, detail="", reason=""):
    return {"target": name, "value": value, "met": met, "shown": shown, "detail": detail, "reason": reason}


def onset_targets(rows: list) -> list:
    """Spittel & Mueller 2001: no windscreen hits at >= 20 m at 10 m/s; windscreen hits at 30 m at >= 20 m/s."""
    out = []
    slow = select(rows, speed=10.0, gap=lambda g: g >= 20.0, flaps=False)
    p = pooled(slow)
    bad = sorted({(r["leader"], r["gravel"], "wet" if r["wet"] else "dry", r["gap"]) for r in slow if r["windscreen"]})
    out.append(_target("onset: no windscreen hits at gaps >= 20 m at 10 m/s (flaps off)", p["count"],
                       None if not p["rows"] else p["count"] == 0, _rate_text(p),
                       reason="" if not bad else "hit at " + "; ".join(f"{a} leader, {b}, {c}, {g:g} m"
                                                                        for a, b, c, g in bad)))
    for v in sorted({r["speed"] for r in rows if r["speed"] >= 20.0}):
        sel = select(rows, speed=v, gap=30.0, flaps=False)
        p = pooled(sel)
        per = "; ".join(f"{g}: {pooled(select(sel, gravel=g))['count']}" for g in sorted({r["gravel"] for r in sel}))
        out.append(_target(f"onset: windscreen hits at 30 m at {v:g} m/s (flaps off)", p["count"],
                           None if not p["rows"] else p["count"] > 0, _rate_text(p), f"by gravel: {per}",
                           reason="" if p["count"] or not p["rows"] else
                           "no stone of this throw stays in the air long enough at windscreen height to meet a "
                           "follower 30 m back (see the hits-by-gap plot for where hits stop)"))
    return out


def long_tail_target(rows: list) -> dict:
    """Albert, Nover & Nover 2006; Strobl 1996: windscreen hits at 40 m for chippings at 22-25 m/s."""
    sel = select(rows, gravel="chippings", gap=40.0, speed=lambda v: 22.0 <= v <= 25.0, flaps=False)
    p = pooled(sel)
    z = [r["windscreen_z"][-1] for r in sel if r["windscreen_z"]]
    return _target("long tail: windscreen hits at 40 m, chippings at 22-25 m/s (flaps off)", p["per_km"],
                   None if not p["rows"] else p["count"] > 0, _rate_text(p),
                   f"highest windscreen hit {max(z):.2f} m" if z else "",
                   reason="" if p["count"] or not p["rows"] else
                   "chippings slowed by drag fall out of the air before the follower 40 m back reaches them")


def _large_releases(launch: dict | None) -> str:
    """What the launch case says of the stones over 20 mm that rise above the bonnet line (impacts.py)."""
    big = (launch or {}).get("large")
    if not big:
        return ""
    a = big["alpha_deg"]
    text = (f"launch case, coarse gravel at {big['speed']:g} m/s: {big['high']} of {big['launched']} stones over "
            f"20 mm rise above {big['z']:g} m")
    if a:
        text += (f", released at {min(a):.0f}-{max(a):.0f} deg (median {np.median(a):.0f}) up the back of the "
                 f"tire, r {min(big['radius_mm']):.1f}-{max(big['radius_mm']):.1f} mm: carried by the tread past "
                 "the contact patch")
    return text


def large_stones_target(rows: list, runs: list, launch: dict | None = None) -> dict:
    """Berner et al. 2003: stones over 20 mm on windscreen or roof at gaps >= 20 m up to 25 m/s (reported;
    met when none), with the runs and stones that do it."""
    sel = select(rows, gap=lambda g: g >= 20.0, speed=lambda v: v <= 25.0,
                 gravel=lambda g: GRAVEL.get(g, (0.0, 1.0))[1] > BIG_RADIUS)
    p = pooled(sel, "big_high")
    where = []
    by_id = {r["id"]: r for r in runs if not r.get("error")}
    for r in sel:
        if not r["big_high"]:
            continue
        run = by_id[r["run"]]
        lane = next(ln for ln in run["lanes"] if float(ln["gap"]) == r["gap"])
        own, _ = lane_events(run, lane)
        e = own[(own["radius"] > BIG_RADIUS) & ((own["part"] == WINDSCREEN) | (own["part"] == ROOF))]
        where += [f"{r['leader']} {r['speed']:g} m/s {'wet' if r['wet'] else 'dry'} flaps "
                  f"{'on' if r['flaps'] else 'off'}, {r['gap']:g} m: r {1e3 * x['radius']:.1f} mm on "
                  f"{LABELS[x['part']]} at {x['point'][2]:.2f} m, {x['speed']:.1f} m/s" for x in e[:3]]
    return _target("large stones stay low: windscreen + roof hits by stones > 20 mm at gaps >= 20 m, <= 25 m/s",
                   p["count"], None if not p["rows"] else p["count"] == 0,
                   _rate_text(p, "such hits") if p["rows"] else "not measured (no gravel with stones over 20 mm)",
                   "; ".join(where[:6] + ([_large_releases(launch)] if _large_releases(launch) else [])),
                   reason="" if not p["count"] else "they occur (the runs above): " + (
                       _large_releases(launch) or "the events do not carry the release angle"))


def flaps_target(rows: list) -> dict:
    """Mud flaps cut the hits on a close follower (5 and 10 m): the ratio on / off over the configurations run
    both ways (same leader, speed, ground, gravel and gap), per leader and pooled."""
    key = lambda r: (r["leader"], r["speed"], r["wet"], r["gravel"], r["gap"])
    close = [r for r in rows if r["gap"] in (5.0, 10.0)]
    both = {key(r) for r in close if r["flaps"]} & {key(r) for r in close if not r["flaps"]}
    paired = [r for r in close if key(r) in both]
    out, ratios = [], {}
    for leader in sorted({r["leader"] for r in paired}) + [None]:
        sel = paired if leader is None else select(paired, leader=leader)
        on, off = pooled(select(sel, flaps=True), "hits"), pooled(select(sel, flaps=False), "hits")
        ratio = on["per_km"] / off["per_km"] if off["per_km"] else math.nan
        ratios[leader or "all"] = ratio
        w_on, w_off = pooled(select(sel, flaps=True)), pooled(select(sel, flaps=False))
        w = w_on["per_km"] / w_off["per_km"] if w_off["per_km"] else math.nan
        out.append(f"{leader or 'all'}: {off['count']} -> {on['count']} hits, {off['per_km']:.3g} -> "
                   f"{on['per_km']:.3g} /km" + (f" ({100 * (1 - ratio):.0f} % fewer)" if math.isfinite(ratio) else "")
                   + (f", windscreen {w_off['per_km']:.3g} -> {w_on['per_km']:.3g} /km" if math.isfinite(w) else ""))
    r = ratios.get("all", math.nan)
    met = None if not math.isfinite(r) else bool(r < 1.0)
    return _target("mud flaps cut the hits on a close follower (5 and 10 m, all parts)", r, met,
                   f"on / off = {r:.3f} ({100 * (1 - r):.0f} % fewer)" if math.isfinite(r) else "not measured",
                   "; ".join(out), reason="" if met or met is None else
                   "the flaps stop stones thrown back low from the tread; what reaches a follower is not thrown low")


def _series_violations(rows: list, what: str) -> tuple[int, int, list]:
    """Per configuration, the consecutive gaps where the rate rises beyond Poisson error (the larger gap's
    95 % lower bound above the smaller's 95 % upper bound)."""
    series, bad, pairs = {}, [], 0
    for r in rows:
        series.setdefault(tuple(r[k] for k in CONFIG_KEYS), []).append(r)
    for key, rs in series.items():
        rs = sorted(rs, key=lambda r: r["gap"])
        for a, b in zip(rs, rs[1:]):
            pairs += 1
            if b[f"{what}_lower_per_km"] > a[f"{what}_upper_per_km"]:
                bad.append(f"{key[0]} {key[1]:g} m/s {'wet' if key[2] else 'dry'} {key[3]} flaps "
                           f"{'on' if key[4] else 'off'}: {a['gap']:g} m {a[what]} -> {b['gap']:g} m {b[what]}")
    return len(bad), pairs, bad


def gap_target(rows: list) -> dict:
    """Hits fall with the gap: pooled over every configuration and per configuration, within Poisson error."""
    gaps = sorted({r["gap"] for r in rows})
    pool = [pooled(select(rows, gap=g), "hits") for g in gaps]
    rises = [f"{a:g} m -> {b:g} m" for a, b, p, q in zip(gaps, gaps[1:], pool, pool[1:])
             if poisson_lower(q["count"]) / q["km"] > poisson_upper(p["count"]) / p["km"]]
    n_bad, pairs, bad = _series_violations(rows, "hits")
    met = None if not rows else bool(not rises and n_bad == 0)
    why = (["the pooled rate rises " + ", ".join(rises)] if rises else []) + \
          ([f"{n_bad} rises within configurations, e.g. " + "; ".join(bad[:3])] if bad else [])
    return _target("hits fall with the gap (all parts)", n_bad, met,
                   ", ".join(f"{g:g} m: {p['per_km']:.3g}" for g, p in zip(gaps, pool)) + " /km (pooled); "
                   f"{n_bad} of {pairs} steps rise beyond Poisson error", "; ".join(bad[:5]),
                   reason="" if met or met is None else "; ".join(why))


def cross_lane(rows: list) -> dict:
    n = int(sum(r["cross"] for r in rows))
    own = int(sum(r["hits"] for r in rows))
    return {"cross": n, "own": own, "share": n / max(1, n + own)}


def _band_value(band: dict) -> str:
    v = band.get("value")
    if not isinstance(v, (int, float)):
        return band.get("shown", "")
    return f"{v:.2f} deg" if "deg" in band["target"] and "released" not in band["target"] else f"{100 * v:.2f} %"


def launch_target(launch: dict | None) -> dict:
    """The throw's bands (bench --only launch, V 20 dry gravel): measured in this study or read from a run."""
    if not launch:
        return _target("the throw's own bands (bench --only launch) still hold", None, None, "not measured",
                       reason="the launch case was not run")
    rows = launch["bands"]
    met = all(r["met"] for r in rows)
    return _target("the throw's own bands (bench --only launch) still hold", sum(bool(r["met"]) for r in rows),
                   bool(met), f"{sum(bool(r['met']) for r in rows)} of {len(rows)} bands met ({launch['source']})",
                   "; ".join(f"{r['target'].lstrip(':, ')}: {_band_value(r)}" for r in rows),
                   reason="" if met else "bands missed: " + "; ".join(r["target"] for r in rows if not r["met"]))


def all_targets(rows: list, runs: list, launch: dict | None = None) -> list:
    return (onset_targets(rows) + [long_tail_target(rows), large_stones_target(rows, runs, launch), flaps_target(rows),
                                   gap_target(rows), launch_target(launch)])


# --------------------------------------------------------------------------------------------- summaries
def by_gap_table(rows: list, what: str = "hits") -> list:
    """Rates per km by gap per configuration (the report's table and the plots' lines)."""
    out = {}
    for r in rows:
        key = tuple(r[k] for k in CONFIG_KEYS)
        d = out.setdefault(key, dict(zip(CONFIG_KEYS, key), gaps=[], count=[], per_km=[], upper_per_km=[], km=[]))
        d["gaps"].append(r["gap"])
        d["count"].append(r[what])
        d["per_km"].append(r[f"{what}_per_km"])
        d["upper_per_km"].append(r[f"{what}_upper_per_km"])
        d["km"].append(r["km"])
    for d in out.values():
        order = np.argsort(d["gaps"])
        for k in ("gaps", "count", "per_km", "upper_per_km", "km"):
            d[k] = [d[k][i] for i in order]
    return list(out.values())


def own_events(runs: list, **want) -> np.ndarray:
    """Every lane's own hits, concatenated, of the runs whose configuration matches ``want`` (as select)."""
    parts = []
    for run in runs:
        if run.get("error") or not select([{k: run[k] for k in CONFIG_KEYS}], **want):
            continue
        for lane in run["lanes"]:
            parts.append(lane_events(run, lane)[0])
    return np.concatenate(parts) if parts else np.zeros(0, runs[0]["events"].dtype if runs else None)


def windscreen_heights(runs: list) -> dict:
    """Body-frame heights (m) of the windscreen hits per gap (every configuration)."""
    out = {}
    for run in runs:
        if run.get("error"):
            continue
        for lane in run["lanes"]:
            own, _ = lane_events(run, lane)
            z = own["point"][own["part"] == WINDSCREEN, 2]
            out.setdefault(float(lane["gap"]), []).extend(round(float(q), 3) for q in z)  # mm: the JSON stays small
    return dict(sorted(out.items()))


def summary(runs: list, launch: dict | None = None) -> dict:
    """Everything the report and results.json hold, from the runs' events."""
    rows = lane_rows(runs)
    ok = [r for r in runs if not r.get("error")]
    ev = own_events(ok) if ok else None
    bands = damage_bands()
    out = {"rows": rows, "targets": all_targets(rows, runs, launch), "cross_lane": cross_lane(rows),
           "by_gap": by_gap_table(rows, "hits"), "by_gap_windscreen": by_gap_table(rows, "windscreen"),
           "windscreen_heights": {str(g): v for g, v in windscreen_heights(ok).items()},
           "bands": bands, "errors": [f"{r['id']}: {r['error']}" for r in runs if r.get("error")]}
    if ev is not None and len(ev):
        out["damage"] = {"momentum": damage_counts(ev["normal_momentum"], bands["momentum"]),
                         "energy": damage_counts(normal_energy(ev), bands["energy"])}
        ws = ev[ev["part"] == WINDSCREEN]
        out["damage_windscreen"] = {"momentum": damage_counts(ws["normal_momentum"], bands["momentum"]),
                                    "energy": damage_counts(normal_energy(ws), bands["energy"])}
    return out
