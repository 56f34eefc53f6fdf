"""A sweep's plots (``DIR/plots/``): each metric's numeric columns against each swept key (every run a grey
point, the mean over the other keys and seeds a black line), and with the launch metric a table of the runs
against the launch bands (bench/launch.py BAND_TARGETS): which settings meet every band. Needs matplotlib
(the test and bench extras); without it no plot is drawn and the function says so in its result."""

from __future__ import annotations

import io
import json
import math
import re
from pathlib import Path

from ...bench.launch import BAND_TARGETS, band_met
from ...output.atomic import new_folders, write_atomically


def _number(v):
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, (int, float)) and math.isfinite(v):
        return float(v)
    return None


def _save(fig, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    write_atomically(path, lambda f: f.write(buf.getvalue()))


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_")


def _axis(values: list) -> tuple:
    """x positions for the values of a key: the numbers themselves, or indices for anything else."""
    nums = [_number(v) for v in values]
    if all(n is not None for n in nums):
        return nums, None
    labels = sorted({json.dumps(v) for v in values})
    return [labels.index(json.dumps(v)) for v in values], labels


def _metric_vs_key(plt, rows: list, metric: str, key: str, path: Path) -> bool:
    cols = []
    for r in rows:
        for c, v in r["metrics"].get(metric, {}).items():
            if c not in cols and _number(v) is not None:
                cols.append(c)
    if not cols:
        return False
    n = len(cols)
    ncol = min(4, n)
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.2 * ncol, 2.6 * nrow), squeeze=False)
    xs, labels = _axis([r["values"][key] for r in rows])
    for ax, c in zip(axes.ravel(), cols):
        pts = [(x, _number(r["metrics"][metric].get(c))) for x, r in zip(xs, rows)]
        pts = [(x, y) for x, y in pts if y is not None]
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o", color="0.6", ms=4)
        means = {}
        for x, y in pts:
            means.setdefault(x, []).append(y)
        order = sorted(means)
        ax.plot(order, [sum(means[x]) / len(means[x]) for x in order], "k-", lw=1.2)
        ax.set_title(c, fontsize=9)
        ax.tick_params(labelsize=7)
        if labels:
            ax.set_xticks(range(len(labels)), labels, fontsize=7)
        if _number(rows[0]["values"][key]) and min(xs) > 0 and max(xs) / min(xs) > 20:
            ax.set_xscale("log")
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    fig.suptitle(f"{metric} against {key} ({len(rows)} runs; line: mean)", fontsize=10)
    fig.supxlabel(key, fontsize=9)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)
    return True


def _bands(plt, rows: list, keys: list, path: Path) -> bool:
    rows = [r for r in rows if "launch" in r["metrics"]]
    if not rows:
        return False
    names = [b[1] for b in BAND_TARGETS]
    fig, ax = plt.subplots(figsize=(2.0 + 1.1 * (len(names) + 1) + 0.09 * max(len(_row_label(r, keys)) for r in rows),
                                    1.1 + 0.2 * len(rows)))
    met_all = 0
    for i, r in enumerate(rows):
        m = r["metrics"]["launch"]
        oks = [band_met(m, k) for k in names]
        met_all += all(oks)
        for j, (k, ok) in enumerate(zip(names, oks)):
            ax.add_patch(plt.Rectangle((j, i), 1, 1, color="#7fc97f" if ok else "#f0837c"))
            v = m[k]
            ax.text(j + 0.5, i + 0.5, f"{v:.4g}" if _number(v) is not None else "-", ha="center", va="center",
                    fontsize=6.5)
        ax.add_patch(plt.Rectangle((len(names), i), 1, 1, color="#238b45" if all(oks) else "#cb181d"))
        ax.text(len(names) + 0.5, i + 0.5, "all met" if all(oks) else f"{sum(oks)}/{len(oks)}", ha="center",
                va="center", fontsize=7, color="white")
    ax.set_xlim(0, len(names) + 1)
    ax.set_ylim(len(rows), 0)
    heads = [f"{k}\n{'<=' if at_most else '>='} {limit:g}" for _, k, limit, at_most in BAND_TARGETS] + ["every band"]
    ax.set_xticks([j + 0.5 for j in range(len(heads))], heads, fontsize=7)
    ax.xaxis.tick_top()
    ax.set_yticks([i + 0.5 for i in range(len(rows))], [_row_label(r, keys) for r in rows], fontsize=6.5)
    ax.set_title(f"Launch bands per run: {met_all} of {len(rows)} runs meet every band", fontsize=9, pad=28)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)
    return True


def _row_label(r: dict, keys: list) -> str:
    return ", ".join(f"{k.split('.')[-1]} {r['values'][k]:g}" if _number(r["values"][k]) is not None
                     else f"{k.split('.')[-1]} {r['values'][k]}" for k in keys) + f", seed {r['seed']}"


def plot_sweep(rows: list, keys: list, metrics: list, folder: Path) -> list[str]:
    """Draw the plots of the finished rows into ``folder``; the file names written."""
    ok = [r for r in rows if r["status"] == "ok"]
    if not ok:
        return []
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    written = []
    with new_folders(folder):
        for metric in metrics:
            for key in keys:
                name = f"{_slug(metric)}_vs_{_slug(key)}.png"
                if _metric_vs_key(plt, ok, metric, key, folder / name):
                    written.append(name)
        if "launch" in metrics and _bands(plt, ok, keys, folder / "launch_bands.png"):
            written.append("launch_bands.png")
    return written
