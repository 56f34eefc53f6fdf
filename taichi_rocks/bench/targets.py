"""3. The performance targets, met or not, with the numbers (stated at N = 1M rocks, T = 20 rear tires):
the full step against Warp's HashGrid (<= 1x) and the streaming floor (<= 3x), >= 100x faster than NumPy brute
force, the bed-only scene <= 1.3x the floor, linear in N; active stepping's targets (activity.py: the step
against the floor at 1M, 10M against 1M, real time with the balanced preset); and how much slower the design hash
is (reported)."""

from __future__ import annotations

from .activity import activity_targets
from .config import DEFAULT_HASH, DESIGN_HASH, Config


def _hash_comparisons(res: dict) -> list:
    hs = res["accuracy"]["hash_settings"]
    d = {r["name"]: r for r in hs["settings"] if "error" not in r}
    at = f"N={hs['n']:,}, T={hs['t']}"
    out = []
    if DESIGN_HASH in d and DEFAULT_HASH in d:
        r = d[DESIGN_HASH]["step_ms"] / d[DEFAULT_HASH]["step_ms"]
        out.append({"target": "design hash (aabb, cell r_min) vs default (center, 2 r_max): far slower?",
                    "value": r, "limit": 2.0, "met": None,
                    "detail": f"{'yes' if r > 2.0 else 'no'}: {d[DESIGN_HASH]['step_ms']:.2f} ms vs "
                              f"{d[DEFAULT_HASH]['step_ms']:.2f} ms per step (x{r:.2f})", "at": at})
    if "design, scope all" in d and "scope all" in d:
        r = d["design, scope all"]["step_ms"] / d["scope all"]["step_ms"]
        out.append({"target": "design hash vs centre insert, both hashing every rock (scope all)", "value": r,
                    "limit": 2.0, "met": None, "detail": f"x{r:.2f}", "at": at})
    return out


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
    bed = res["speed"]["effects"]["splash off (bed only: recycle)"]["step_ms"]
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
    if res.get("activity"):
        out += activity_targets(res["activity"], cfg)
    return out + _hash_comparisons(res)
