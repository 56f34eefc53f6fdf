"""The Python API under bad input (engine/arguments.py): each public method of Simulation refuses what it cannot
do with a ValueError or TypeError naming the parameter (or the checkpoint's key), and the simulation is then as it
was: the same clock, the same rocks to the bit. Also the backends' refusals of config/arches.py, which the API
shares with the command line.

A call that would never return on bad input (``advance_to(inf)`` stepped forever) runs under :func:`deadline`, so
that such a failure fails the test instead of hanging the suite (the good case takes milliseconds)."""

import contextlib
import signal

import numpy as np
import pytest

from scenes_util import scene
from taichi_rocks.config.scene import SceneError, scene_with
from taichi_rocks.engine.arguments import STEP_LIMIT
from taichi_rocks.engine.simulation import Simulation

pytestmark = pytest.mark.usefixtures("taichi_cpu")


@contextlib.contextmanager
def deadline(seconds: float = 30.0):
    """Raise TimeoutError in the block after ``seconds`` (a call that loops without end fails, not hangs)."""
    def expired(signum, frame):
        raise TimeoutError(f"still running after {seconds} s")

    old = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture(scope="module")
def sim():
    s = Simulation(scene(rocks=300, radius=4.0, effects={"impacts": False}))
    s.step(20)
    return s


def snapshot(sim) -> tuple:
    """The clock and every rock field, as bytes: what "unchanged" means."""
    return (sim.time, sim.step_count, *(a.tobytes() for a in sim.rock_arrays().values()))


@pytest.mark.parametrize("t, error, words", [
    (float("inf"), ValueError, "t must be a finite time in seconds, got inf"),
    (float("-inf"), ValueError, "t must be a finite time"),
    (float("nan"), ValueError, "t must be a finite time in seconds, got nan"),
    (1e12, ValueError, r"t = 1e\+12 s is past the last step"),
    ("1.0", TypeError, "t must be a time in seconds"),
    (None, TypeError, "t must be a time in seconds"),
    (True, TypeError, "t must be a time in seconds")])
def test_advance_to_refuses_a_time_it_cannot_reach(sim, t, error, words):
    before = snapshot(sim)
    with deadline(), pytest.raises(error, match=words):
        sim.advance_to(t)
    assert snapshot(sim) == before


def test_advance_to_takes_a_numpy_time_and_one_in_the_past():
    s = Simulation(scene(rocks=50, radius=4.0))
    s.advance_to(np.float32(0.02))
    s.advance_to(np.float64(0.01))  # in the past: no step
    assert s.time == pytest.approx(0.02)


@pytest.mark.parametrize("n, error, words", [
    (-1, ValueError, "n must be >= 0, got -1"), (1.5, TypeError, "n must be a whole number of steps, got 1.5"),
    (STEP_LIMIT, ValueError, f"past {STEP_LIMIT} steps"), ("3", TypeError, "n must be a whole number"),
    (True, TypeError, "n must be a whole number")])
def test_step_refuses_a_count_it_cannot_take(sim, n, error, words):
    before = snapshot(sim)
    with deadline(), pytest.raises(error, match=words):
        sim.step(n)
    assert snapshot(sim) == before


def test_step_takes_numpy_integers_and_zero(sim):
    t = sim.time
    sim.step(np.int64(0))
    assert sim.time == t
    sim.step(np.int32(2))
    assert sim.time == pytest.approx(t + 2 * sim.dt)


@pytest.mark.parametrize("kwargs, error, words", [
    (dict(ids=[-1], phase=1), ValueError, r"ids must be rock ids 0 \.\. 299, got -1"),
    (dict(ids=[300], phase=1), ValueError, "ids must be rock ids 0 .. 299, got 300"),
    (dict(ids=[2, 2], phase=1), ValueError, "ids must name each rock once"),
    (dict(ids=[1.0], phase=1), TypeError, "ids must be whole rock ids"),
    (dict(ids=[3], phase=7), ValueError, "phase must hold phase codes 0 .+, got 7"),
    (dict(ids=[3], phase=1.5), ValueError, "phase must hold whole numbers"),
    (dict(ids=[3], positions=[[0.0, np.nan, 1.0]]), ValueError, "positions must be finite, got nan"),
    (dict(ids=[3, 4], positions=[[0.0, 0.0, 1.0]] * 3), ValueError, r"positions must have shape \(2, 3\)"),
    (dict(ids=[3], velocities=[[np.inf, 0.0, 0.0]]), ValueError, "velocities must be finite"),
    (dict(ids=[3], radius=0.0), ValueError, "radius must be > 0 m"),
    (dict(ids=[3], friction=-1.0), ValueError, "friction must be >= 0"),
    (dict(ids=[3], colour=1.0), TypeError, "no rock field 'colour'"),
    (dict(ids=[3], rock_id=5), TypeError, "no rock field 'rock_id'"),
    (dict(ids=[3], phase="flying"), TypeError, "phase must hold numbers")])
def test_set_rocks_refuses_what_no_rock_can_be(sim, kwargs, error, words):
    before = snapshot(sim)
    with pytest.raises(error, match=words):
        sim.set_rocks(**kwargs)
    assert snapshot(sim) == before


def test_set_rocks_sets_what_it_is_given(sim):
    p = sim.state().positions[[5, 6]] + [0.0, 0.0, 1.0]
    sim.set_rocks(np.array([5, 6], np.uint16), positions=p, phase=np.int8(1), velocities=[0.0, 0.0, 2.0])
    st = sim.state()
    np.testing.assert_allclose(st.positions[[5, 6]], p, atol=1e-5)
    assert st.phase[[5, 6]].tolist() == [1, 1] and st.velocities[5].tolist() == [0.0, 0.0, 2.0]


@pytest.fixture(scope="module")
def saved(sim):
    return sim.checkpoint().as_dict()


def _cut(a):
    return a[:-1]


@pytest.mark.parametrize("key, change, words", [
    ("rock_pos", _cut, r"checkpoint: rock_pos must have shape \(300, 3\) \(one row per rock\), got \(299, 3\)"),
    ("rock_phase", lambda a: np.where(np.arange(len(a)) == 4, 9, a), "checkpoint: rock_phase must hold phase codes"),
    ("rock_radius", lambda a: -a, "checkpoint: rock_radius must be > 0 m"),
    ("rock_vel", lambda a: a * np.nan, "checkpoint: rock_vel must be finite"),
    ("rock_rock_id", lambda a: np.zeros_like(a), r"checkpoint: rock_rock_id must hold the ids 0 \.\. 299, each once"),
    ("time", lambda a: np.float64(np.nan), "checkpoint: time must be finite"),
    ("step_count", lambda a: np.float64(3.5), "checkpoint: step_count must be a whole number"),
    ("lead", lambda a: np.zeros(2), "checkpoint: lead must be a unit vector"),
    ("origin", lambda a: np.zeros(2), r"checkpoint: origin must have shape \(3,\)"),
    ("rocks", lambda a: np.int64(299), "checkpoint does not belong to this scene"),
    ("seed", lambda a: "x", "checkpoint: not a checkpoint of a Simulation")])
def test_restore_refuses_a_malformed_checkpoint_and_changes_nothing(sim, saved, key, change, words):
    bad = {**saved, key: change(saved[key])}
    before = snapshot(sim)
    with pytest.raises(ValueError, match=words):
        sim.restore(bad)
    assert snapshot(sim) == before
    sim.check_health()


@pytest.mark.parametrize("key", ["rock_pos", "time", "lead"])
def test_restore_names_a_missing_key(sim, saved, key):
    before = snapshot(sim)
    with pytest.raises(ValueError, match=f"checkpoint: no {key}"):
        sim.restore({k: v for k, v in saved.items() if k != key})
    assert snapshot(sim) == before


def test_a_good_checkpoint_still_restores(sim, saved):
    sim.restore(saved)
    assert sim.step_count == int(saved["step_count"])
    assert sim.rock_arrays()["pos"].tobytes() == saved["rock_pos"].tobytes()


@pytest.mark.parametrize("key, value, words", [
    ("sim.hash.insert", "aabb", 'sim.hash.insert: "aabb" gives wrong answers with arch="vulkan"'),
    ("sim.precision", "f64", 'sim.precision: "f64" cannot run with arch="vulkan"')])
def test_the_api_refuses_what_vulkan_cannot_run_as_the_command_line_does(key, value, words):
    """The same refusal as ``--arch vulkan`` (config/arches.py arch_problem), here before Taichi is asked (this
    process runs Taichi on the CPU, so the old API ran such a scene there without a word)."""
    sc = scene_with(scene(rocks=50, radius=4.0), {key: value})
    with pytest.raises(SceneError, match=words) as e:
        Simulation(sc, arch="vulkan")
    assert isinstance(e.value, ValueError) and "\n" not in str(e.value)
    Simulation(sc, arch="cpu")  # the CPU runs it


def test_an_unknown_arch_is_a_value_error():
    with pytest.raises(ValueError, match="arch must be one of cpu, gpu, cuda, vulkan, got 'metal'"):
        Simulation(scene(rocks=50, radius=4.0), arch="metal")
