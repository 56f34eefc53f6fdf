"""bench/targets.py and the activity targets (bench/activity.py) on canned results: each verdict is met on
one side of its limit and missed on the other (a flipped comparison fails here), the limits are inclusive,
and the report writer's Targets table says what the verdicts say. Nothing is run."""

import copy

import pytest

from taichi_rocks.bench import activity, config, hashing, report, targets  # the modules under test

MAIN = (1_000_000, 20)


def _results(step=10.0, warp=40.0, floor=2.5, numpy=1500.0, bed=3.0, small_step=2.0):
    """A results dict with what evaluate_targets reads: the speed grid at 100k and 1M rocks (20 rear tires),
    the bed-only step, the hash settings."""
    def entry(n, ms):
        return {"n": n, "t": 20, "step_ms": ms, "peers": {"warp_ms": warp, "floor_ms": floor, "numpy_ms": numpy}}

    return {"speed": {"grid": [entry(100_000, small_step), entry(1_000_000, step)],
                      "effects": {"splash off (bed only: recycle)": {"step_ms": bed}}},
            "warp": {"available": warp is not None},
            "accuracy": {"hash_settings": {"n": 100_000, "t": 20, "settings": [
                {"name": config.DEFAULT_HASH, "step_ms": 1.0}, {"name": config.DESIGN_HASH, "step_ms": 3.0}]}}}


def _cfg(**changes):
    cfg = config.make_config()  # the full run: the targets are stated at its main scene
    assert cfg.main == MAIN
    return config.Config(**{**cfg.__dict__, **changes})


def _verdict(res, prefix, cfg=None):
    rows = [t for t in targets.evaluate_targets(res, cfg or _cfg()) if t["target"].startswith(prefix)]
    assert len(rows) == 1, [t["target"] for t in targets.evaluate_targets(res, cfg or _cfg())]
    return rows[0]


@pytest.mark.parametrize("prefix, key, met, missed, limit", [
    ("full step <= 1.0x Warp", "warp", 10.1, 9.9, 1.0),  # step 10 ms: step / warp against 1
    ("full step <= 3x streaming floor", "floor", 3.34, 3.33, 3.0),
    (">= 100x faster than NumPy", "numpy", 1000.0, 999.0, 100.0),
    ("bed-only scene", "bed", 3.25, 3.26, 1.3),  # floor 2.5 ms: bed / floor against 1.3
    ("linear in N", "step", 21.9, 22.1, 11.0),  # 100k step 2 ms: step(1M) / step(100k) against 11
])
def test_each_speed_target_flips_at_its_limit(prefix, key, met, missed, limit):
    a = _verdict(_results(**{key: met}), prefix)
    b = _verdict(_results(**{key: missed}), prefix)
    assert a["met"] is True and b["met"] is False, (a, b)
    assert a["limit"] == pytest.approx(limit) and b["limit"] == pytest.approx(limit)


def test_limits_are_inclusive_and_values_are_the_ratios():
    """Values exactly at their limits (exact in binary) are met; the values are the stated ratios."""
    res = _results(step=6.0, warp=6.0, floor=2.0, numpy=600.0, bed=2.6, small_step=1.0)
    got = {t["target"]: (t["value"], t["met"]) for t in targets.evaluate_targets(res, _cfg()) if t["met"] is not None}
    assert got["full step <= 1.0x Warp HashGrid build+query"] == (1.0, True)
    assert got["full step <= 3x streaming floor"] == (3.0, True)
    assert got[">= 100x faster than NumPy brute force"] == (100.0, True)
    assert got["bed-only scene (no splash) <= 1.3x streaming floor"] == (1.3, True)
    assert got["linear in N: step(1,000,000)/step(100,000) <= 11"] == (6.0, True)


def test_warp_not_measured_is_no_verdict():
    res = _results(warp=None)
    res["warp"]["error"] = "ModuleNotFoundError: No module named 'warp'"
    t = _verdict(res, "full step <= 1.0x Warp")
    assert t["met"] is None and t["value"] is None and "No module named 'warp'" in t["detail"]


def test_design_hash_comparison_is_reported_not_judged():
    t = [x for x in targets.evaluate_targets(_results(), _cfg()) if x["target"].startswith("design hash")]
    assert len(t) == 1 and t[0]["met"] is None and t[0]["value"] == pytest.approx(3.0)


def _activity(step_1m=0.5, floor_1m=2.0, step_100k=0.25, full_100k=1.0, step_10m=0.75, b_1m=1.0, b_10m=1.5,
              realtime=2.0):
    """Canned activity results: series (a) at 100k (active and full), 1M (with the floor) and 10M; series (b)
    at 1M and 10M; the balanced preset. The defaults sit exactly at every limit (exact in binary)."""
    def point(ms, floor=None):
        return {"step_ms": ms, "floor_ms": floor, "in_air": 1000}

    return {"series": {"a": [{"n": 100_000, "active": point(step_100k), "full": point(full_100k)},
                             {"n": 1_000_000, "active": point(step_1m, floor_1m)},
                             {"n": 10_000_000, "active": point(step_10m)}],
                       "b": [{"n": 1_000_000, "active": point(b_1m)}, {"n": 10_000_000, "active": point(b_10m)}]},
            "sweep": [{"group": "balanced", "sim_s_per_wall_s": realtime, "step_ms": 1.0, "dt": 0.002,
                       "integrator": "heun", "detection": "swept"}]}


ACTIVITY_TARGETS = [  # (prefix, key, met, missed, limit): the targets of a step whose cost is the work
    ("step at 1,000,000 rocks, 20 rear tires <= 0.5x", "step_1m", 1.0, 1.01, 0.5),  # floor 2 ms
    ("step at 100,000 rocks", "step_100k", 0.5, 0.51, 0.25),  # against the floor of 1M, 2 ms
    ("step(10,000,000) <= 1.5x step(1,000,000), series (a)", "step_10m", 0.75, 0.76, 1.5),  # step(1M) 0.5 ms
    ("step(10,000,000) <= 1.5x step(1,000,000), series (b)", "b_10m", 1.5, 1.51, 1.5),
    ("1,000,000 rocks with the balanced preset >= 2x real time", "realtime", 2.0, 1.99, 2.0),
]


def _activity_row(act, prefix):
    rows = [t for t in activity.activity_targets(act, _cfg()) if t["target"].startswith(prefix)]
    assert len(rows) == 1, [t["target"] for t in activity.activity_targets(act, _cfg())]
    return rows[0]


@pytest.mark.parametrize("prefix, key, met, missed, limit", ACTIVITY_TARGETS)
def test_each_activity_target_flips_at_its_limit(prefix, key, met, missed, limit):
    a, b = _activity_row(_activity(**{key: met}), prefix), _activity_row(_activity(**{key: missed}), prefix)
    assert a["met"] is True and a["detail"].startswith("PASS"), a
    assert b["met"] is False and b["detail"].startswith("MISS"), b
    assert a["limit"] == pytest.approx(limit) and b["limit"] == pytest.approx(limit)


def test_activity_values_are_the_stated_ratios_and_limits_inclusive():
    rows = activity.activity_targets(_activity(), _cfg())
    assert len(rows) == len(ACTIVITY_TARGETS)
    assert [(t["value"], t["met"]) for t in rows] == [(0.25, True), (0.125, True), (2.0, True), (1.5, True),
                                                       (1.5, True)]


def test_small_bed_must_also_beat_full_stepping():
    """Under 0.25x the floor is not enough: at or above full stepping's time the 100k target is missed."""
    row = _activity_row(_activity(step_100k=0.25, full_100k=0.25), "step at 100,000 rocks")
    assert row["met"] is False and "not below full stepping" in row["detail"], row
    assert _activity_row(_activity(step_100k=0.25, full_100k=0.2501), "step at 100,000 rocks")["met"] is True


def test_activity_target_without_a_measurement_is_no_verdict():
    act = _activity()
    act["series"]["a"][1]["active"] = {"error": "killed"}  # the 1M point: its floor is gone too
    act["sweep"] = []
    assert [t["met"] for t in activity.activity_targets(act, _cfg())] == [None, None, None, None, True]


def test_hash_verdict_fails_on_a_difference_an_error_or_nothing_compared():
    ok = [{"name": "default", "identical": True}, {"name": "design", "identical": True}]
    assert hashing.hash_verdict(ok) is True
    assert hashing.hash_verdict([ok[0], {**ok[1], "identical": False}]) is False
    assert hashing.hash_verdict(ok + [{"name": "table 4 N", "error": "SceneError: ..."}]) is False
    assert hashing.hash_verdict(ok[:1]) is False  # the default alone compares nothing
    assert hashing.hash_verdict([{**ok[0], "identical": False}, ok[1]]) is False  # the default does not reproduce


def test_report_targets_table_says_what_the_verdicts_say():
    rows = targets.evaluate_targets(_results(warp=9.0, floor=2.5), _cfg())
    res = {"targets": rows}
    lines = [line for line in report._targets(res, []) if line.startswith("| ") and "---" not in line][1:]
    assert len(lines) == len(rows)
    for line, t in zip(lines, rows):
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[0] == t["target"]
        assert cells[3] == {True: "**met**", False: "**NOT met**", None: "-"}[t["met"]], line
    flipped = copy.deepcopy(rows)
    flipped[0]["met"] = not flipped[0]["met"]
    assert report._targets({"targets": flipped}, [])[3] != report._targets(res, [])[3]


def test_verdicts_and_report_on_the_committed_results(tmp_path):
    """The committed full run (docs/results/bench.json, the README's figures) as canned results: evaluating
    its targets again gives the verdicts it holds, and the report writer writes every section of it, its
    Targets table saying what the verdicts say."""
    import json
    from pathlib import Path

    results = Path(__file__).resolve().parents[2] / "docs" / "results"
    res = json.loads((results / "bench.json").read_text())
    cfg = config.Config(**{k: tuple(v) if isinstance(v, list) else v for k, v in res["config"].items()})
    act = json.loads((results / "activity.json").read_text())  # the newer activity run the README shows
    again = activity.activity_targets(act["activity"], cfg)
    assert [(t["target"], t["met"]) for t in again] == [(t["target"], t["met"]) for t in act["targets"]]
    assert len(again) == 5 and all(t["met"] is not None for t in again)
    # bench.json's own targets but its activity section's, which activity.json supersedes
    without = dict(res, activity=None)
    stored = [t for t in res["targets"] if t["target"] in {x["target"] for x in targets.evaluate_targets(without, cfg)}]
    again = targets.evaluate_targets(without, cfg)
    assert [(t["target"], t["met"]) for t in again] == [(t["target"], t["met"]) for t in stored]
    path = report.write_report(res, tmp_path, res["plots"])
    text = path.read_text()
    for heading in ("## Targets", "## Proposed presets", "## 1a.", "## 1b.", "## 1c.", "## 1d.", "## 2.",
                    "## 4. Cost against activity"):
        assert heading in text
    for t in res["targets"]:
        verdict = {True: "**met**", False: "**NOT met**", None: "-"}[t["met"]]
        assert f"| {t['target']} | {report._fmt(t['value'])} | {report._fmt(t['limit'])} | {verdict} |" in text
