"""The cost-against-activity section (bench/activity.py): its jobs, the bytes of its fields and its verdicts.
The section in the tiny run's results and report is tested in test_bench.py, next to the other tests of that run
(one file, so that the run is made once per test process)."""

import pytest

from taichi_rocks.bench import activity
from taichi_rocks.bench.config import make_config

pytestmark = pytest.mark.usefixtures("taichi_cpu")


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
