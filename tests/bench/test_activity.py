"""The cost-against-activity section (bench/activity.py) on the tiny run of the benchmark: the report, the
results and the plot carry it with numbers, the points are what they say (their scenes, rocks in the air, the
stepping used), and the targets have a verdict. No timing is asserted: a loaded machine may reorder any two
times; only that times are positive and finite."""

import json
import math

import pytest

from taichi_rocks.bench import activity
from taichi_rocks.bench.config import make_config

pytestmark = pytest.mark.usefixtures("taichi_cpu")

ACTIVITY_TARGETS = ("0.5x the streaming floor", "series (a)", "series (b)", "balanced preset")


def _positive_finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def test_the_jobs_of_each_mode():
    """10M points only in the full run; full stepping above 1M only there; series (b) keeps the density;
    the reference point is shared by both series (measured once); the activity sweep, then one process of
    profiled points (one per profiled N, on the fixed bed)."""
    for mode in ("tiny", "quick", "full"):
        cfg = make_config(quick=mode == "quick", tiny=mode == "tiny")
        jobs = activity.plan_jobs(cfg)
        sweep, profile, singles = jobs[-2], jobs[-1], [j[0] for j in jobs[:-2]]
        assert all(len(j) == 1 for j in jobs[:-2]) and all(p["memory"] and p["floor"] for p in singles)
        assert [p["n"] for p in profile] == list(cfg.act_profile_n) and profile
        assert all(p["profile"] and p["group"] == "profile" and p["radius"] == cfg.act_radius for p in profile)
        assert not any(p["profile"] for p in singles + sweep)
        labels = [p["label"] for p in singles]
        assert len(labels) == len(set(labels))
        assert (max(p["n"] for p in singles) == 10_000_000) == (mode == "full")
        if mode != "full":
            assert all(p["n"] <= 1_000_000 for p in singles if p["stepping"] == "full")
        dens = {p["n"] / p["radius"] ** 2 for p in singles if p["label"].startswith("b ")}
        assert dens and max(dens) == pytest.approx(min(dens)) == pytest.approx(cfg.act_ref_n / cfg.act_radius ** 2)
        assert all(p["radius"] == cfg.act_radius for p in singles if p["label"].startswith("a "))
        assert not any(p["label"] == f"b N={cfg.act_ref_n:,} active" for p in singles)
        assert {p["group"] for p in sweep} == {"tires", "speed", "parked", "balanced"}
        assert all(p["n"] == cfg.act_fixed_n for p in sweep)
    full = activity.plan_jobs(make_config())
    assert {p["t_rear"] for p in full[-2]} == {2, 6, 20, 40}
    assert {p["speed"] for p in full[-2]} == {0.0, 10.0, 25.0, 40.0}


def test_field_bytes_count_every_field():
    from taichi_rocks.bench.scenes import fleet_scene
    from taichi_rocks.engine.simulation import Simulation

    sim = Simulation(fleet_scene(20_000, 2, 8.0))
    b = activity.field_bytes(sim.world)
    # at least position and velocity (3 x f32 each), radius, friction, id, phase per rock
    assert b >= 20_000 * (12 + 12 + 4 * 4)
    pos = sim.world.pos
    assert activity.field_bytes(type("W", (), {"fields": lambda self: [pos]})()) == pos.shape[0] * 12


def test_verdicts_say_by_how_much():
    assert activity._verdict(0.25, 0.5, True) == (True, "PASS, 50 % under the limit")
    assert activity._verdict(1.0, 0.5, True) == (False, "MISS, 2.00x the limit")
    assert activity._verdict(0.8, 1.0, False) == (False, "MISS, 20 % short")


def test_the_section_in_results_and_report(bench_run):
    out, res = bench_run
    data = json.loads((out / "results.json").read_text())
    act = data["activity"]
    assert data["errors"] == [] and act["errors"] == []
    cfg = make_config(tiny=True)
    for series in ("a", "b"):
        rows = act["series"][series]
        assert [r["n"] for r in rows] == list(cfg.act_n)
        for r in rows:
            a = r["active"]
            assert a["stepping_plan"] == "active" and a["warm_steps"] == round(cfg.act_warm_s / a["dt"])
            assert _positive_finite(a["step_ms"]) and _positive_finite(r["floor_ms"])
            assert all(_positive_finite(x) for x in a["step_rounds_ms"]) and len(a["step_rounds_ms"]) == cfg.act_rounds
            assert 0 < a["in_air"] <= a["active_count"] < r["n"]  # rocks thrown; most rest in their tiles
            m = a["memory"]
            assert m["hwm_mb"] >= m["rss_mb"] > m["baseline_rss_mb"] > 0
            assert 0 < m["field_mb"] < m["hwm_mb"] and _positive_finite(m["field_bytes_per_rock"])
            if r["full"]:
                f = r["full"]
                assert f["stepping_plan"] == "full" and f["active_count"] == r["n"] and _positive_finite(f["step_ms"])
                assert f["in_air"] > 0 and f["memory"]["field_bytes_per_rock"] > 0
    assert act["series"]["a"][-1]["full"] is not None  # the largest tiny N is timed both ways
    for per in act["memory"].values():
        assert set(per) == {"active", "full"}
        assert all(_positive_finite(m["peak_10m_gb"]) for m in per.values())
    sweep = {p["label"]: p for p in act["sweep"]}
    parked = sweep["parked fleet (0 m/s)"]
    assert parked["in_air"] == 0 and parked["launches_total"] == 0 and parked["steps_coasted"] > 0
    bal = sweep["balanced preset"]
    assert (bal["integrator"], bal["detection"], bal["dt"]) == ("heun", "swept", 0.002)
    tires = [p for p in act["sweep"] if p["group"] == "tires"]
    assert [p["t_rear"] for p in tires] == list(cfg.act_tires)
    assert tires[-1]["in_air"] > tires[0]["in_air"] > 0  # more vehicles throw more rocks
    assert all(_positive_finite(p["step_ms"]) and _positive_finite(p["sim_s_per_wall_s"]) for p in act["sweep"])
    report = (out / "report.md").read_text()
    section = report.split("## 4. Cost against activity", 1)[1].split("\n## ", 1)[0]
    assert "](activity.png)" in section and (out / "activity.png").stat().st_size > 10_000
    assert f"| (a) | {cfg.act_n[-1]:,} | {cfg.act_radius:.1f} | {act['series']['a'][-1]['active']['in_air']:,} |" in section
    assert f"| parked | parked fleet (0 m/s) | {cfg.act_t} | 0 |" in section
    assert "GB** peak" in section


def test_the_targets_have_verdicts(bench_run):
    _, res = bench_run
    rows = [t for t in res["targets"] if any(k in t["target"] for k in ACTIVITY_TARGETS)]
    assert len(rows) == 4
    for t in rows:
        assert _positive_finite(t["value"]) and isinstance(t["met"], bool)
        assert t["detail"].startswith("PASS, " if t["met"] else "MISS, ")
