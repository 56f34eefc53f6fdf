"""The step's two variants (engine/loops.py: serial loops or parallel ones) and the choice between them
(engine/variant.py): the same rocks, launches, recycles, events and changes either way, and the choice as
documented (backend, CPU threads, work, the override)."""

import numpy as np
import pytest

from scenes_util import scene
from taichi_rocks.config.scene import load_scene, scene_with
from taichi_rocks.engine import variant
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.variant import CROSSOVER, LOOPS, VariantChoice, crossover, loops_from_env

pytestmark = pytest.mark.usefixtures("taichi_cpu")


def test_off_the_cpu_always_parallel():
    c = VariantChoice(on_cpu=False, threads=0)
    assert c.serial is False
    for work in (0, 10, 10**9):
        assert c.update(work) is False


def test_one_thread_always_serial_unless_told():
    c = VariantChoice(on_cpu=True, threads=1)
    assert c.serial is True and c.update(10**9) is True
    assert VariantChoice(on_cpu=True, threads=1, mode="parallel").update(10) is False


def test_the_crossover_with_hysteresis():
    c = VariantChoice(on_cpu=True, threads=2)
    x = crossover(2)
    assert x == CROSSOVER
    assert c.serial is True  # nothing known yet: a game's step
    assert c.update(int(x)) is True  # at the crossover: still serial
    assert c.update(int(x) + 1) is False  # past it: parallel
    assert c.update(int(0.6 * x)) is False  # inside the band: stays parallel (no switch at every fit)
    assert c.update(int(0.5 * x) - 1) is True  # below half: serial again
    assert c.update(int(0.9 * x)) is True


def test_more_threads_cross_over_sooner_and_one_never():
    assert crossover(1) == float("inf")
    assert crossover(16) < crossover(4) < crossover(2)
    # p threads pay off once N s (1 - 1/p) > F: the crossover scales as p / (p - 1) from the measured 2-thread one
    assert crossover(4) == pytest.approx(CROSSOVER * 4 / 6)


def test_forced_modes_ignore_the_work():
    s = VariantChoice(on_cpu=True, threads=2, mode="serial")
    p = VariantChoice(on_cpu=True, threads=2, mode="parallel")
    assert s.update(10**9) is True and p.update(0) is False
    assert VariantChoice(on_cpu=False, threads=0, mode="serial").update(5) is True


def test_the_environment_variable(monkeypatch):
    monkeypatch.delenv(LOOPS, raising=False)
    assert loops_from_env() == "auto"
    for word in ("serial", " Parallel ", "AUTO"):
        monkeypatch.setenv(LOOPS, word)
        assert loops_from_env() == word.strip().lower()
    for bad in ("yes", "1", "threads"):
        monkeypatch.setenv(LOOPS, bad)
        with pytest.raises(ValueError, match=LOOPS):
            loops_from_env()
    with pytest.raises(ValueError, match="loops"):
        VariantChoice(on_cpu=True, threads=2, mode="fast")


def test_the_simulation_reports_and_takes_the_variant(monkeypatch):
    monkeypatch.delenv(LOOPS, raising=False)
    sim = Simulation(scene(rocks=500))
    assert sim.loops == "serial"  # 2 CPU threads at most here (tests/engine/test_threads.py), 500 rocks
    sim.loops = "parallel"
    assert sim.loops == "parallel"
    sim.loops = "auto"
    assert sim.loops == "serial"
    with pytest.raises(ValueError, match="loops"):
        sim.loops = "quick"
    monkeypatch.setattr(variant, "CROSSOVER", 100)  # a list longer than the crossover: parallel (2 threads)
    if sim._stepper.variant.threads > 1:
        sim.loops = "auto"
        assert sim.loops == "parallel"


def _run(sc, loops: str, frames: int):
    sim = Simulation(sc, tumble=True)
    sim.loops = loops
    rows, events = {}, []
    for f in range(1, frames + 1):
        sim.advance_to(f / 30)
        ch = sim.changes()
        rows[f] = (ch.ids.copy(), ch.positions.copy(), ch.phase.copy(), ch.orientations.copy())
        events.append(sim.impacts())
    return sim, rows, np.concatenate(events)


@pytest.mark.parametrize("stepping", ["active", "full"])
def test_both_variants_give_the_same_bits(scenes_dir, stepping):
    """A scene with a truck throwing stones at the player (impacts, tumbling), a second of 30 frames each way:
    every state, the launch and recycle counts, the impact events and the rows changes() gives (as sets: the
    order of the rows follows the threads) are equal to the bit."""
    sc = scene_with(load_scene(scenes_dir / "convoy.toml"),
                    {"bed.rocks": 20_000, "bed.radius": 10.0, "sim.stepping": stepping})
    a, rows_a, ev_a = _run(sc, "serial", 30)
    b, rows_b, ev_b = _run(sc, "parallel", 30)
    assert a.launches_total == b.launches_total > 0 and a.recycles_total == b.recycles_total
    assert len(ev_a) > 0 and ev_a.tobytes() == ev_b.tobytes()
    sa, sb = a.state(), b.state()
    for k in ("positions", "velocities", "phase", "orientations", "angular_velocities"):
        assert np.array_equal(sa[k], sb[k]), k
    for f in rows_a:
        ia, ib = np.argsort(rows_a[f][0]), np.argsort(rows_b[f][0])
        for x, y in zip(rows_a[f], rows_b[f]):
            assert np.array_equal(x[ia], y[ib]), f
