"""The benchmark on its tiny configuration: files, sections, identical hits across hash settings, sane ratios.

No timing is asserted (the machine may be busy); only that every number that should be a positive finite ratio
is one. The tiny run takes about 35 s with cold Taichi caches on 2 cores, its cost-against-activity section
included (its points run in the test's process, but the profiled one). Its tests are all in this file, so that
the run is made once per test process (the suite runs a file per process at a time).
"""

import json
import math

import numpy as np
import pytest

from taichi_rocks.bench.run import OUTPUTS
from taichi_rocks.bench.config import CASE_OF_DRAG
from taichi_rocks.config.keys import choices

pytestmark = pytest.mark.usefixtures("taichi_cpu")


def _positive_finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def test_files_written(bench_run):
    out, res = bench_run
    assert (out / "report.md").is_file() and (out / "results.json").is_file()
    assert res["report"] == str(out / "report.md")
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs == sorted(res["plots"]) and len(pngs) == 7
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUTS)  # what a run checks its out folder for
    for p in out.glob("*.png"):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
    report = (out / "report.md").read_text()
    for name in pngs:
        assert f"]({name})" in report
    for heading in ("## Targets", "## Proposed presets", "## 1a.", "## 1b.", "## 1c.", "## 1d.", "## 2.",
                    "## 4. Cost against activity"):
        assert heading in report


def test_every_section_present(bench_run):
    out, _ = bench_run
    data = json.loads((out / "results.json").read_text())
    for key in ("machine", "config", "warp", "accuracy", "speed", "targets", "build_s", "elapsed_s", "activity"):
        assert key in data, key
    for key in ("integrator_dt", "detection", "precision", "hash_settings", "presets", "preset_costs",
                "flight_cost"):
        assert key in data["accuracy"], key
    for key in ("grid", "effects", "overheads"):
        assert key in data["speed"], key
    m = data["machine"]
    assert m["cpu_model"] and m["logical_cores"] >= 1 and m["taichi"] == "1.7.4" and m["numpy"]
    assert data["errors"] == []
    # accuracy rows cover every integrator and case, with finite errors
    rows = data["accuracy"]["integrator_dt"]["rows"]
    assert {(r["integrator"], r["case"]) for r in rows} == {
        (i, CASE_OF_DRAG[d]) for i in choices("sim.integrator") for d in choices("effects.drag")}
    assert all(math.isfinite(r["max_error_m"]) and r["max_error_m"] >= 0 for r in rows)
    # the closed forms are right: Heun and RK4 are exact for gravity (f32 rounding only), symplectic Euler is
    # off by g dt t / 2 at t = 2 s (about 0.196 m at dt = 0.02)
    grav = {(r["integrator"], r["dt"]): r["max_error_m"] for r in rows if r["case"] == "gravity"}
    assert grav[("heun", 0.02)] < 1e-3 and grav[("rk4", 0.02)] < 1e-3
    assert grav[("symplectic_euler", 0.02)] == pytest.approx(9.81 * 0.02 * 2.0 / 2.0, rel=0.05)


def test_identical_hits_across_hash_settings(bench_run):
    _, res = bench_run
    hs = res["accuracy"]["hash_settings"]
    rows = hs["settings"]
    assert len(rows) >= 2 and all("error" not in r for r in rows), rows  # every setting was built and run
    assert hs["identical"] is True and hs["verdict"] == "PASS"
    assert all(r["identical"] is True for r in rows)  # the default too: a fresh build reproduces its record
    assert rows[0]["launched"] > 0  # the comparison is not vacuous


def test_detection_and_precision_sane(bench_run):
    _, res = bench_run
    det = res["accuracy"]["detection"]["modes"]
    for mode, d in det.items():
        assert d["false_positives"] == 0, mode
        for row in d["per_speed"]:
            assert row["contacts"] > 0 and 0.0 <= row["recall"] <= 1.0
    assert min(r["recall"] for r in det["swept"]["per_speed"]) == 1.0
    # a single ray misses contacts at speed; the swept test does not
    assert det["ray"]["per_speed"][-1]["recall"] < det["swept"]["per_speed"][-1]["recall"]
    prec = res["accuracy"]["precision"]["configs"]
    # the reference is the f64 flight launched at the origin: f64 anywhere stays on it to round-off, f32 near
    # the origin is off by its rounding only, f32 with a world origin drifts far away from it
    dist = res["accuracy"]["precision"]["distances_m"]
    assert dist[0] == 0.0 and dist[-1] >= 1e5
    if "f64 floating" in prec:
        assert max(prec["f64 floating"]["max_error_m"] + prec["f64 world"]["max_error_m"]) < 1e-6
    assert 0.0 < prec["f32 floating"]["max_error_m"][0] < 1e-3 and max(prec["f32 floating"]["max_error_m"]) < 1e-3
    assert prec["f32 world"]["max_error_m"][-1] > 100 * prec["f32 floating"]["max_error_m"][-1]


def test_ratios_positive_finite(bench_run):
    _, res = bench_run
    for e in res["speed"]["grid"]:
        for key in ("step_ms", ):
            assert _positive_finite(e[key])
        for key in ("floor_ms", "numpy_ms", "kdtree_ms"):
            assert _positive_finite(e["peers"][key]), key
        assert res["warp"]["available"] is True, res["warp"]  # warp-lang is in the test extra
        for key, value in e["ratios"].items():
            assert _positive_finite(value), (key, value)
        assert _positive_finite(e["peers"]["warp_ms"])
        check = e["peers"]["check"]
        assert check["kdtree_equals_numpy"] and check["taichi_launched_subset_of_geometric_hits"]
        assert check["geometric_hits_not_launched_are_flying"]
        assert check["warp_sym_diff_vs_numpy"] == 0  # Warp's HashGrid query found exactly NumPy's hits
    for t in res["targets"]:
        if t["value"] is not None:
            assert _positive_finite(t["value"]), t
    for p in res["accuracy"]["presets"]:
        if "integrator" in p:
            assert _positive_finite(p["ms_per_simulated_s"]) and _positive_finite(p["step_ms"])


def test_closed_forms():
    from taichi_rocks.bench.flight import exact_gravity, exact_linear, exact_quadratic_vertical

    t = np.linspace(0.0, 2.0, 201)
    x0, v0 = np.array([0.0, 0.0, 1.0]), np.array([3.0, 1.0, 15.0])
    # linear drag tends to the parabola as tau grows
    np.testing.assert_allclose(exact_linear(x0, v0, 1e4, t), exact_gravity(x0, v0, t), atol=2e-3)
    # and its velocity decays: far from the launch it falls at the terminal speed g tau
    z = exact_linear(x0, v0, 0.5, np.array([20.0, 21.0]))[:, 2]
    assert z[0] - z[1] == pytest.approx(9.81 * 0.5, rel=1e-6)
    # quadratic drag, vertical: continuous at the apex, slower than without drag, v(0) = w0
    z = exact_quadratic_vertical(1.0, 20.0, 40.0, t)
    assert np.all(np.abs(np.diff(z)) < 0.25)
    assert np.all(z <= exact_gravity(x0, np.array([0.0, 0.0, 20.0]), t)[:, 2] + 1e-12)
    h = 1e-6
    dz = (exact_quadratic_vertical(1.0, 20.0, 40.0, [h])[0] - 1.0) / h
    assert dz == pytest.approx(20.0, rel=1e-4)


def test_passes_inside_a_step_are_timed_by_the_engine(bench_run):
    """The per-pass breakdown inside real steps comes from the engine's timing hook (PassTimer): the fused rock
    pass and the fused hash + tire pass are there (full stepping), or the one launch of active stepping, each
    a positive share of the step."""
    _, res = bench_run
    for e in res["speed"]["grid"]:
        prof = e["in_step"]["per_pass_ms"]
        active = [v for k, v in prof.items() if k.startswith("active step")]
        if active:
            assert len(active) == 1 and _positive_finite(active[0])
        else:
            assert _positive_finite(prof["rock pass (fused)"])
            assert _positive_finite(prof["hash scan+scatter+tires (fused)"])
        assert sum(v for k, v in prof.items() if k != "host and launch overhead") <= e["in_step"][
            "mean_step_ms_with_syncs"] * 1.001


def _small_scene():
    from taichi_rocks.bench.scenes import fleet_scene

    return fleet_scene(20_000, 2, 8.0)  # the tiny run's grid scene: its kernels are compiled after it


def test_rebuild_carries_on_bit_identically_in_the_same_layout():
    """A rebuild under another plan keeps the World's layout (the kernels compiled for it serve the new one), and
    a rebuild back to a scene run before compiles nothing; the run carries on bit for bit."""
    from compiles import compiled
    from taichi_rocks.bench.measure import Built
    from taichi_rocks.config.scene import scene_with

    scene = _small_scene()
    b = Built(scene, "cpu", "straight")
    b.sim.step(12)
    straight = b.sim.state()
    del b
    b = Built(scene, "cpu", "rebuilt")
    layout = b.sim.world.layout
    b.sim.step(5)
    b.rebuild(scene_with(scene, {"effects.drag": "none"}))  # another plan, the same fields
    assert b.sim.world.layout == layout and b.sim.plan.drag == "none" and b.sim.step_count == 5
    with compiled() as names:
        b.rebuild(scene)
        b.sim.step(7)
        again = b.sim.state()
    assert names == [], names
    assert b.sim.world.layout == layout and b.sim.step_count == 12 and b.layout_switches == 0
    for key in ("positions", "velocities", "phase", "launches_total"):
        np.testing.assert_array_equal(again[key], straight[key], err_msg=key)
    assert straight["launches_total"] > 0  # the comparison is not vacuous
    held = b.sim
    with pytest.raises(RuntimeError, match="still referenced"):
        b.rebuild(scene)  # a Simulation referenced elsewhere keeps its World: refused, not held beside the new one
    del held


def test_fly_only_flies_test_rocks_and_restores_the_rocks():
    from taichi_rocks.bench.flight import exact_gravity
    from taichi_rocks.engine import probes
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.engine.world import IPar

    sim = Simulation(_small_scene())
    sim.step(5)
    before = sim.checkpoint()
    n0 = sim.active_count  # every rock with full stepping; the active list's length with active stepping
    x0 = np.array([[0.0, 0.0, 1.0], [2.0, -1.0, 0.5]])
    v0 = np.array([[12.0, 2.0, 15.0], [-3.0, 1.0, 9.0]])
    xs = probes.fly_only(sim, x0, v0, [0.03, 0.02], 0.01, steps=100, every=10, integrator="heun", drag="none")
    assert xs.shape == (2, 10, 3)
    t = np.arange(10, 101, 10) * 0.01
    for j in range(2):  # Heun is exact for a parabola: f32 rounding only
        np.testing.assert_allclose(xs[j], exact_gravity(x0[j], v0[j], t), atol=1e-3)
    after = sim.checkpoint()
    for key, value in before.items():
        np.testing.assert_array_equal(after[key], value, err_msg=key)
    assert int(sim.world.ipar[IPar.N_ROCKS]) == n0
    with probes.active_rocks(sim, 0):
        assert int(sim.world.ipar[IPar.N_ROCKS]) == 0
    assert int(sim.world.ipar[IPar.N_ROCKS]) == n0


def test_separate_passes_in_step_order():
    from taichi_rocks.bench.measure import separate_passes_ms
    from taichi_rocks.engine import probes
    from taichi_rocks.engine.simulation import Simulation

    sim = Simulation(_small_scene())
    sim.step(3)
    names = [name for name, _ in probes.separate_passes(sim)]
    assert names == ["flight", "recycle", "hash clear", "hash count", "hash scan", "hash scatter", "trace rays",
                     "tire pass"]
    ms = separate_passes_ms(sim, 1)
    assert set(names) < set(ms) and all(_positive_finite(v) for v in ms.values())
    sim.step(3)  # the passes left a state the step carries on from
    sim.check_health()


def test_rebuild_across_layouts_carries_on():
    """Active stepping's tile store has a layout per recycling switch: a rebuild across it takes a World of the
    other layout (its kernels compiled the first time) and carries on from the same rocks and clock."""
    from taichi_rocks.bench.measure import Built
    from taichi_rocks.config.scene import scene_with

    scene = scene_with(_small_scene(), {"sim.stepping": "active"})
    off = scene_with(scene, {"effects.recycle": False})
    b = Built(scene, "cpu", "across layouts")
    world = b.sim.world
    b.sim.step(5)
    before = b.sim.state()
    b.rebuild(off)
    assert b.sim.world.layout != world.layout and b.sim.step_count == 5 and b.layout_switches == 1
    now = b.sim.state()
    for key in ("positions", "velocities", "phase"):
        np.testing.assert_array_equal(now[key], before[key], err_msg=key)
    b.sim.step(2)
    b.rebuild(scene)
    assert b.layout_switches == 2 and b.sim.step_count == 7 and b.sim.plan.recycle
    b.sim.step(2)
    b.sim.check_health()


# ------------------------------------------------------------------------------- cost against activity
# The section of bench/activity.py in the tiny run: the report, the results and the plot carry it with numbers,
# the points are what they say (their scenes, rocks in the air, the stepping used), and the targets have a
# verdict. No timing is asserted: a loaded machine may reorder any two times; only that times are positive and
# finite.
ACTIVITY_TARGETS = ("0.5x the streaming floor", "series (a)", "series (b)", "balanced preset")


def test_the_section_in_results_and_report(bench_run):
    out, res = bench_run
    data = json.loads((out / "results.json").read_text())
    act = data["activity"]
    assert data["errors"] == [] and act["errors"] == []
    from taichi_rocks.bench.activity import plan_jobs
    from taichi_rocks.bench.config import make_config

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
            # no order between them is asserted: in a process that ran other points before, a collection may
            # free more than the World takes (the resident size drops below the point's baseline), and Linux
            # brings VmHWM up to date lazily (per-thread RSS counters): seen 0.2 MB below the baseline
            assert m["hwm_mb"] > 0 and m["rss_mb"] > 0 and m["baseline_rss_mb"] > 0
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
    # the tiny run measures its points in the test's process (but the profiled one): the report says so
    assert act["isolated"] is False and "the points in one process, one after another" in section
    assert [p["label"] for p in act["points"]] == [p["label"] for job in plan_jobs(cfg) for p in job]
    # the profiled point (Taichi's kernel profiler, in a process of its own): active stepping's kernels and tasks,
    # per step, with times; the report's table and task list carry them
    assert [p["n"] for p in act["profile"]] == list(cfg.act_profile_n)
    for p in act["profile"]:
        assert "error" not in p and p["in_air"] > 0 and _positive_finite(p["step_ms"])
        assert p["launches_per_step"] >= 1 and p["tasks_per_step"] >= p["parallel_tasks_per_step"] >= 0
        # the serial variant (2 CPU cores, a small active list: engine/variant.py) is one task per kernel
        assert (p["parallel_tasks_per_step"] > 0) == (p["loops"] == "parallel"), p
        assert _positive_finite(p["device_ms"]) and p["host_ms"] >= 0 and p["passes_ms"]
        kernels = [t["kernel"] for t in p["tasks"]]
        assert kernels[0] == "active_step" and "active_finish" in kernels
        assert all(t["per_step"] > 0 and 0 <= t["min_ms"] <= t["median_ms"] for t in p["tasks"])
        assert f"Tasks of a step at N = {p['n']:,}" in section and f"| {p['n']:,} | {p['in_air']:,} |" in section


def test_the_targets_have_verdicts(bench_run):
    _, res = bench_run
    rows = [t for t in res["targets"] if any(k in t["target"] for k in ACTIVITY_TARGETS)]
    assert len(rows) == 4
    for t in rows:
        assert _positive_finite(t["value"]) and isinstance(t["met"], bool)
        assert t["detail"].startswith("PASS, " if t["met"] else "MISS, ")
