"""The cost-against-activity section (bench/activity.py): its jobs, the bytes of its fields and its verdicts.
The section in the tiny run's results and report is tested in test_bench.py, next to the other tests of that run
(one file, so that the run is made once per test process)."""

import pytest

from taichi_rocks.bench import activity
from taichi_rocks.bench.config import make_config
from taichi_rocks.engine.world import SCAN_LEVELS

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
    w = sim.world
    b = activity.field_bytes(w)
    # at least position and velocity (3 x f32 each), radius, friction, id, phase per rock
    assert b >= 20_000 * (12 + 12 + 4 * 4)
    # the bytes the World's groups hold: every field, the table its kernels read, rows aligned, nothing else
    size = {"f32": 4, "f64": 8, "i32": 4, "i64": 8}
    held = sum(arr.shape[0] * getattr(arr, "n", 1) * size[str(arr.dtype)] for arr in w.groups)
    fields = sum(f.nbytes() for f in w.fields())
    assert b == held and fields <= b <= fields + 4 * len(w.placement.head) + 8 * len(w.placement.real_head) + 6 * 48
    assert w.pos.nbytes() == 20_000 * 12


def test_verdicts_say_by_how_much():
    assert activity._verdict(0.25, 0.5, True) == (True, "PASS, 50 % under the limit")
    assert activity._verdict(1.0, 0.5, True) == (False, "MISS, 2.00x the limit")
    assert activity._verdict(0.8, 1.0, False) == (False, "MISS, 20 % short")


TASK_SCRIPT = """
import os, sys
import taichi as ti
from taichi_rocks.bench.activity import task_rows
from taichi_rocks.engine import timing
from taichi_rocks.engine.runtime import init_taichi
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.world import PARALLEL_SCAN
init_taichi("cpu", profiler=True)
for scene, scan in (("minimal", "0"), ("convoy", "1")):
    os.environ[PARALLEL_SCAN] = scan
    sim = Simulation.from_scene(os.path.join(sys.argv[1], scene + ".toml"))
    for loops in ("parallel", "serial"):
        sim.loops = loops
        sim.step(2)
        ti.sync()
        ti.profiler.clear_kernel_profiler_info()
        sim.step(3)
        rows = task_rows(timing.kernel_tasks(), 3)
        print(scene if loops == "parallel" else "serial", sim.world.scan_levels,
              ";".join(r["kernel"] + ":" + r["what"] for r in rows))
"""


def test_every_task_of_a_step_has_its_label(tmp_path):
    """The benchmark's task table names every task of the step's kernels (engine/active.py task_labels): in the
    parallel variant with and without impacts, with the CPU's serial scan and with the parallel one of the GPU
    backends (run here on the CPU: TAICHI_ROCKS_PARALLEL_SCAN=1), and in the serial variant (one serial task per
    kernel), Taichi's kernel profiler on, in a process of its own."""
    import subprocess
    import sys

    from cli_util import ROOT, _env

    out = subprocess.run([sys.executable, "-c", TASK_SCRIPT, str(ROOT / "scenes")], env=_env(), capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    lines = dict(line.split(" ", 1) for line in out.stdout.splitlines() if line.startswith(("minimal ", "convoy ")))
    levels = {k: int(v.split(" ", 1)[0]) for k, v in lines.items()}
    assert levels == {"minimal": 0, "convoy": SCAN_LEVELS}  # whatever the table's size: not in the layout
    serial = [line.split(" ", 2)[2] for line in out.stdout.splitlines() if line.startswith("serial ")]
    assert len(serial) == 2
    for text in serial:
        rows = [r for r in text.split(";") if r.startswith(("active_step:", "active_finish:"))]
        assert [r.split(":", 1)[0] for r in rows] == ["active_step", "active_finish"], rows  # one task each
        assert all(r.split(":", 1)[1].startswith("serial variant: ") for r in rows), rows
    for scene, text in lines.items():
        rows = text.split(" ", 1)[1].split(";")
        step = [r for r in rows if r.startswith(("active_step:", "active_finish:"))]
        assert len(step) >= 19, (scene, rows)
        assert not [r for r in step if ":task " in r], (scene, rows)  # a label for every task
    assert "active_finish:hash scan: down-sweep, level 1" in lines["convoy"]
    assert "active_step:impacts: flying rocks against the vehicles" in lines["convoy"]
