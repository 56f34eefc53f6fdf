"""The impacts study (`taichi-rocks bench --only impacts`): its analysis and every target's verdict on canned
events (a flipped comparison fails), the report writer, the lanes' geometry, and one tiny run end to end."""

import dataclasses
import json
import math

import numpy as np
import pytest

from taichi_rocks.bench import impacts, impacts_analysis as A, impacts_report
from taichi_rocks.engine.events import EVENT_DTYPE
from taichi_rocks.motion.bodies import LABELS

WS, ROOF, BONNET = LABELS.index("windscreen"), LABELS.index("roof"), LABELS.index("bonnet")
GAPS = (5.0, 10.0, 20.0, 30.0, 40.0)


def _events(n, follower, thrower, part=WS, z=1.1, radius=0.004, normal_speed=20.0, rock0=0):
    ev = np.zeros(n, EVENT_DTYPE)
    ev["vehicle"], ev["thrower"], ev["part"] = follower, thrower, part
    ev["point"][:, 2] = z
    ev["radius"] = radius
    ev["normal_speed"] = normal_speed
    ev["normal_momentum"] = 2600.0 * 4.0 / 3.0 * math.pi * radius ** 3 * normal_speed
    ev["speed"] = normal_speed
    ev["rock"] = np.arange(rock0, rock0 + n)
    return ev


def _run(rid, counts, leader="car", speed=20.0, wet=0.0, gravel="chippings", flaps=False, km=0.5, parts=None,
         extra=None):
    """A run with lanes of GAPS (leader 2k+1, follower 2k+2) and ``counts[gap]`` windscreen hits each."""
    lanes, evs = [], []
    for k, gap in enumerate(GAPS):
        lanes.append({"gap": gap, "y": 10.0 * k, "leader": 2 * k + 1, "follower": 2 * k + 2})
        evs.append(_events(counts.get(gap, 0), 2 * k + 2, 2 * k + 1, part=(parts or {}).get(gap, WS),
                           rock0=1000 * k))
    if extra is not None:
        evs.append(extra)
    return {"id": rid, "leader": leader, "speed": speed, "wet": wet, "gravel": gravel, "flaps": flaps,
            "lanes": lanes, "distance_m": 1000.0 * km, "events": np.concatenate(evs)}


def _good_study():
    """Runs meeting every target: falling with the gap, no hits at >= 20 m at 10 m/s, hits at 30 and 40 m above,
    flaps cutting the close hits."""
    falling = {5.0: 40, 10.0: 25, 20.0: 10, 30.0: 4, 40.0: 2}
    runs = [_run("slow", {5.0: 6, 10.0: 2}, speed=10.0),
            _run("v20", falling, speed=20.0), _run("v25", falling, speed=25.0),
            _run("v25 flaps", {5.0: 20, 10.0: 12, 20.0: 10, 30.0: 4, 40.0: 2}, speed=25.0, flaps=True),
            _run("v25 coarse", {5.0: 10, 10.0: 4}, speed=25.0, gravel="coarse")]
    return runs


def _verdicts(runs, launch=None):
    rows = A.lane_rows(runs)
    return {t["target"]: t for t in A.all_targets(rows, runs, launch)}, rows


def _find(verdicts, words):
    hits = [t for name, t in verdicts.items() if words in name]
    assert len(hits) == 1, (words, list(verdicts))
    return hits[0]


def test_poisson_bounds():
    assert A.poisson_upper(0) == pytest.approx(-math.log(0.05), rel=1e-9)  # "3 / distance"
    assert A.poisson_lower(0) == 0.0
    for n in (1, 5, 20, 100):
        lo, up = A.poisson_lower(n), A.poisson_upper(n)
        assert lo < n < up
        assert A.poisson_upper(n + 1) > up
    assert A.poisson_upper(1) == pytest.approx(4.7439, abs=1e-3)  # tabulated (Gehrels 1986)


def test_lane_rows_count_own_and_cross_lane_hits():
    cross = _events(3, follower=2, thrower=3)  # lane 0's follower hit by lane 1's leader
    run = _run("r", {5.0: 4, 10.0: 2}, km=0.25, parts={10.0: BONNET}, extra=cross)
    rows = {r["gap"]: r for r in A.lane_rows([run])}
    assert rows[5.0]["hits"] == 4 and rows[5.0]["windscreen"] == 4 and rows[5.0]["cross"] == 3
    assert rows[10.0]["hits"] == 2 and rows[10.0]["windscreen"] == 0
    assert rows[5.0]["hits_per_km"] == pytest.approx(16.0)
    assert rows[20.0]["hits"] == 0 and rows[20.0]["windscreen_upper_per_km"] == pytest.approx(A.poisson_upper(0) / 0.25)
    assert rows[5.0]["windscreen_z"][0] == pytest.approx(1.1)
    assert A.cross_lane(list(rows.values()))["cross"] == 3


def test_every_target_is_met_on_good_events():
    v, _ = _verdicts(_good_study(), {"bands": [{"target": ": band", "met": True, "shown": "99 %"}], "source": "x"})
    for name, t in v.items():
        assert t["met"] is True, (name, t)
    assert _find(v, "mud flaps")["value"] < 1.0
    assert "fewer" in _find(v, "mud flaps")["shown"]


def test_onset_fails_on_a_windscreen_hit_far_back_at_10_m_s():
    runs = _good_study()
    runs[0] = _run("slow", {5.0: 6, 10.0: 2, 20.0: 1}, speed=10.0)
    v, _ = _verdicts(runs)
    t = _find(v, "no windscreen hits at gaps >= 20 m at 10 m/s")
    assert t["met"] is False and "20 m" in t["reason"]


def test_onset_fails_without_hits_at_30_m():
    runs = _good_study()
    runs[1] = _run("v20", {5.0: 40, 10.0: 25, 20.0: 10}, speed=20.0)
    v, _ = _verdicts(runs)
    assert _find(v, "30 m at 20 m/s")["met"] is False and _find(v, "30 m at 20 m/s")["reason"]
    assert _find(v, "30 m at 25 m/s")["met"] is True


def test_long_tail_needs_chippings_at_40_m():
    runs = [r for r in _good_study()]
    for i, r in enumerate(runs):
        if r["speed"] == 25.0 and r["gravel"] == "chippings":
            runs[i] = _run(r["id"], {5.0: 40, 10.0: 25, 20.0: 10, 30.0: 4}, speed=25.0, flaps=r["flaps"])
    v, _ = _verdicts(runs)
    t = _find(v, "long tail")
    assert t["met"] is False and t["value"] == 0.0 and "<" in t["shown"]


def test_flipped_mud_flaps_fail():
    runs = _good_study()
    runs[3] = _run("v25 flaps", {5.0: 80, 10.0: 60, 20.0: 10, 30.0: 4, 40.0: 2}, speed=25.0, flaps=True)
    t = _find(_verdicts(runs)[0], "mud flaps")
    assert t["met"] is False and t["value"] > 1.0


def test_hits_rising_with_the_gap_fail():
    runs = _good_study()
    runs[1] = _run("v20", {5.0: 2, 10.0: 4, 20.0: 10, 30.0: 25, 40.0: 40}, speed=20.0)
    t = _find(_verdicts(runs)[0], "fall with the gap")
    assert t["met"] is False and t["value"] >= 1 and "car 20 m/s" in t["detail"]


def test_a_rise_within_poisson_error_is_no_violation():
    rows = A.lane_rows([_run("v", {5.0: 10, 10.0: 12, 20.0: 3}, speed=20.0)])  # 10 -> 12: noise
    n_bad, pairs, _ = A._series_violations(rows, "hits")
    assert n_bad == 0 and pairs == 4


def test_large_stones_high_and_far_are_reported():
    big = _events(2, follower=6, thrower=5, part=ROOF, z=1.45, radius=0.02)  # lane of 20 m (index 2)
    runs = _good_study() + [_run("v20 coarse", {5.0: 10}, speed=20.0, gravel="coarse", extra=big)]
    t = _find(_verdicts(runs)[0], "large stones")
    assert t["met"] is False and t["value"] == 2
    assert "20 m" in t["detail"] and "roof" in t["detail"] and "r 20.0 mm" in t["detail"]
    low = _events(2, follower=6, thrower=5, part=BONNET, z=0.9, radius=0.02)  # on the bonnet: allowed
    runs[-1] = _run("v20 coarse", {5.0: 10}, speed=20.0, gravel="coarse", extra=low)
    assert _find(_verdicts(runs)[0], "large stones")["met"] is True


def test_launch_bands_missed_fail():
    bands = [{"target": ": a", "met": True, "shown": "1"}, {"target": ": b", "met": False, "shown": "2"}]
    t = A.launch_target({"bands": bands, "source": "s"})
    assert t["met"] is False and "b" in t["reason"]
    assert A.launch_target(None)["met"] is None


def test_damage_classes_at_the_band_edges():
    edges = (0.001, 0.01)
    assert A.damage_counts(np.array([0.0009, 0.001, 0.0099, 0.01, 1.0]), edges) == {"mark": 1, "chip": 2, "crack": 2}
    ev = _events(1, 2, 1, radius=0.005, normal_speed=10.0)
    m = 2600.0 * 4 / 3 * math.pi * 0.005 ** 3
    assert A.normal_energy(ev)[0] == pytest.approx(0.5 * m * 100.0)


def test_lanes_hold_everything_inside_the_bed():
    for leader in impacts.LEADERS:
        p = impacts.placement(leader, GAPS, 30.0)
        assert p["radius"] == 30.0 and sorted(ln["gap"] for ln in p["lanes"]) == list(GAPS)
        ys = sorted(ln["y"] for ln in p["lanes"])
        assert min(np.diff(ys)) == impacts.LANE_SPACING
        middle = next(ln for ln in p["lanes"] if ln["y"] == 0.0)
        assert middle["gap"] == 40.0
    p = impacts.placement("truck", (5.0, 10.0, 40.0), 5.0)  # a bed too small is grown to hold the lanes
    far = max(math.hypot(ln["follower_x"] + 2.5 - p["pacer_x"], ln["y"]) for ln in p["lanes"])
    assert p["radius"] >= far + impacts.INSIDE - 1.0


def test_study_scene_one_layout_for_every_run():
    """Every run of a study has the same rock count, vehicles and tire sizes: one World layout."""
    from taichi_rocks.config.plan import Plan
    from taichi_rocks.engine.layout import world_layout

    cfg = dataclasses.replace(impacts.make_study_config("quick"), gravels=("coarse", "chippings"))
    layouts = set()
    for t in [t for t in impacts.plan_runs(cfg, "cpu") if "kind" not in t][::3]:
        s = impacts.study_scene(t)
        assert [v.name for v in s.vehicles if v.hit] == [f"follower{k}" for k in range(5)]
        assert [v.name for v in s.vehicles if v.splash] == [f"leader{k}" for k in range(5)]
        plan = Plan.from_scene(s)
        layout, _ = world_layout(s, plan, np.full(s.bed.rocks, s.bed.rock_radius[1]))
        layouts.add((s.bed.rocks, repr(sorted(layout.items()))))
    assert len(layouts) == 1


def _report_res(runs, launch=None):
    cfg = impacts.make_study_config("quick")
    imp = A.summary(runs, launch)
    for r in runs:
        r.update(bed_radius=30.0, rocks=1000, steps=100, ms_per_step=1.0, dropped=0)
    imp.update(config=dataclasses.asdict(cfg), placement={"workers": 2, "threads": 1}, elapsed_s=1.0,
               runs=[{k: v for k, v in r.items() if k != "events"} for r in runs], _runs=runs)
    machine = {"cpu_model": "cpu", "usable_cores": 2, "memory_gb": 1, "taichi": "1.7.4", "taichi_arch": "cpu"}
    return {"started": "now", "machine": machine, "mode": "quick", "load_average_start": [1, 1, 1],
            "load_average_end": [1, 1, 1], "impacts": imp}


def test_report_writes_every_output(tmp_path):
    runs = _good_study()
    res = _report_res(runs)
    info = impacts_report.write_outputs(res, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(impacts_report.OUTPUTS)  # and no temporaries
    assert info["plots"] == list(impacts_report.PNG.values()) and not res["impacts"]["errors"]
    text = (tmp_path / "impacts.md").read_text()
    for t in res["impacts"]["targets"]:
        assert f"| {t['target']} | {t['shown']} |" in text
    for p in info["plots"]:
        assert (tmp_path / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"]({p})" in text
    data = json.loads((tmp_path / "impacts.json").read_text())
    assert [t["target"] for t in data["impacts"]["targets"]] == [t["target"] for t in res["impacts"]["targets"]]
    assert "_runs" not in data["impacts"] and "events" not in data["impacts"]["runs"][0]
    with np.load(tmp_path / impacts_report.EVENTS) as z:
        assert sorted(z.files) == sorted(r["id"] for r in runs)
        np.testing.assert_array_equal(z["v20"], runs[1]["events"])


def test_an_earlier_run_is_not_overwritten(tmp_path):
    (tmp_path / "impacts.md").write_text("earlier")
    with pytest.raises(FileExistsError, match="--overwrite"):
        impacts.run_impacts_study(tmp_path, tiny=True)
    assert (tmp_path / "impacts.md").read_text() == "earlier" and len(list(tmp_path.iterdir())) == 1


@pytest.mark.usefixtures("taichi_cpu")
def test_a_tiny_study_end_to_end(tmp_path):
    res = impacts.run_impacts_study(tmp_path, tiny=True, progress=False)
    imp = res["impacts"]
    assert not imp["errors"], imp["errors"]
    (run,) = imp["_runs"]
    assert run["events"].dtype == EVENT_DTYPE
    assert run["distance_m"] == pytest.approx(20.0, abs=0.1) and run["dropped"] == 0
    own = np.isin(run["events"]["thrower"], [ln["leader"] for ln in run["lanes"]])
    assert np.all(np.isin(run["events"]["vehicle"][own], [ln["follower"] for ln in run["lanes"]]))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(impacts_report.OUTPUTS)
    assert len(imp["rows"]) == 2 and all(r["km"] == pytest.approx(0.02, abs=1e-4) for r in imp["rows"])
    assert sum(r["hits"] for r in imp["rows"]) > 0  # a follower 5 m behind a car at 20 m/s is hit


@pytest.mark.parametrize("earlier", ["impacts.md", "impacts_damage.png"])
def test_the_command_refuses_a_folder_holding_results(taichi_cpu, tmp_path, capsys, earlier):
    from taichi_rocks.cli import main

    (tmp_path / earlier).write_text("earlier")
    status = main(["bench", "--only", "impacts", "--quick", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1 and earlier in err[0] and "--overwrite" in err[0], err
    assert [p.name for p in tmp_path.iterdir()] == [earlier]
    status = main(["bench", "--only", "impacts", "--backend", "ray", "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and "impacts study runs on this machine" in err[-1], err


def test_the_full_bench_writes_the_section_files_only_with_the_study():
    from taichi_rocks.bench.config import make_config
    from taichi_rocks.bench.run import OUTPUTS, outputs

    assert outputs(make_config(tiny=True)) == OUTPUTS  # the tiny and quick runs leave the study out
    full = outputs(make_config())
    assert set(full) - set(OUTPUTS) == set(impacts_report.FILES)


def test_the_full_bench_section_and_targets(tmp_path, monkeypatch):
    """run.py's section 5 on canned events: the plots and events beside the report, the section's markdown in
    report.md's sections, every target in the benchmark's table."""
    from taichi_rocks.bench import report, run

    imp = _report_res(_good_study())["impacts"]
    monkeypatch.setattr(run, "impacts_section", lambda cfg, arch, prog: imp)
    res = {"errors": []}
    run._impacts(res, dataclasses.replace(run.make_config(tiny=True), impacts="quick"), "cpu", tmp_path, None)
    assert not res["errors"], res["errors"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(impacts_report.FILES)
    assert report._impacts(res, []) == res["_impacts_md"] and "## Impacts" in res["_impacts_md"][0]
    assert [t["target"] for t in res["_impacts_targets"]] == [t["target"] for t in imp["targets"]]
    assert all(t["at"] == "impacts study" for t in res["_impacts_targets"])
    monkeypatch.setattr(run, "impacts_section", lambda cfg, arch, prog: 1 / 0)  # a failed study: an error line
    res = {"errors": []}
    run._impacts(res, dataclasses.replace(run.make_config(tiny=True), impacts="quick"), "cpu", tmp_path, None)
    assert res["errors"] and "impacts study: ZeroDivisionError" in res["errors"][0] and "_impacts_md" not in res


def test_an_earlier_run_is_reanalysed_from_its_files(tmp_path):
    res = _report_res(_good_study())
    (tmp_path / "a").mkdir()
    impacts_report.write_outputs(res, tmp_path / "a")
    info = impacts_report.reanalyse(tmp_path / "a", tmp_path / "b")
    again = json.loads((tmp_path / "b" / "impacts.json").read_text())["impacts"]
    first = json.loads((tmp_path / "a" / "impacts.json").read_text())["impacts"]
    assert again["targets"] == first["targets"] and again["rows"] == first["rows"]
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == sorted(impacts_report.OUTPUTS)
    assert info["report"] == str(tmp_path / "b" / "impacts.md")
    with pytest.raises(FileExistsError):
        impacts_report.reanalyse(tmp_path / "a", tmp_path / "b")


def test_large_stones_need_coarse_gravel_and_name_the_releases():
    runs = [r for r in _good_study() if r["gravel"] == "chippings"]
    t = _find(_verdicts(runs)[0], "large stones")
    assert t["met"] is None and "not measured" in t["shown"]  # chippings only: nothing to judge
    big = _events(1, follower=6, thrower=5, part=WS, z=1.2, radius=0.012)
    runs.append(_run("v20 coarse", {5.0: 10}, speed=20.0, gravel="coarse", extra=big))
    launch = {"bands": [], "source": "s", "large": {"speed": 20.0, "launched": 200, "high": 3, "z": 0.95,
                                                    "alpha_deg": [15.0, 18.0, 22.0], "radius_mm": [10.5, 12.0, 16.0],
                                                    "apex_m": [1.0, 1.2, 2.0]}}
    t = _find(_verdicts(runs, launch)[0], "large stones")
    assert t["met"] is False and "15-22 deg" in t["reason"] and "3 of 200" in t["reason"]
