"""The sweep runner on its own (runner/tasks.py), with plain task functions and no Taichi: results,
an exception as the task's one-line error (and a new worker after it), a worker that dies (retried, or
reported once retries are spent), a task that runs past its timeout, a new process per task with fresh=True,
and the placement (workers x threads <= cores)."""

from pathlib import Path

import pytest

from taichi_rocks.runner.tasks import plan_placement, run_tasks, usable_cores

FN = "runner_tasks:task"


@pytest.fixture(autouse=True)
def tasks_importable(monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(Path(__file__).parent))


def _run(xs, **kw):
    out = []
    run_tasks([{"id": str(i), "x": x} for i, x in enumerate(xs)], FN, report=out.append, **kw)
    return {o.task["id"]: o for o in out}, out


def test_results_errors_deaths_and_timeouts():
    by_id, out = _run([1, 0, -1, -2, 3], workers=2, retries=0, timeout=2)
    assert len(out) == 5 and sorted(by_id) == ["0", "1", "2", "3", "4"]
    assert by_id["0"].result["double"] == 2 and by_id["4"].result["double"] == 6
    assert by_id["0"].result["threads"] == str(max(1, usable_cores() // 2))  # 2 workers share the cores
    assert by_id["1"].error == "ValueError: no zero" and by_id["1"].result is None
    assert by_id["2"].error.startswith("the worker died once") and "SIGKILL" in by_id["2"].error
    assert by_id["3"].error == "timed out after 2 s"


def test_a_worker_keeps_its_process_but_not_after_an_error():
    by_id, _ = _run([1, 2, 0, 3], workers=1)
    assert by_id["0"].result["pid"] == by_id["1"].result["pid"] != by_id["3"].result["pid"]


def test_a_dying_task_is_retried_then_reported():
    by_id, out = _run([-1, 5], workers=1, retries=2)
    assert by_id["0"].attempts == 3 and by_id["0"].error.startswith("the worker died 3 times")
    assert by_id["1"].result["double"] == 10 and len(out) == 2


def test_fresh_gives_every_task_its_own_process():
    by_id, _ = _run([1, 2, 3], workers=1, fresh=True)
    assert len({o.result["pid"] for o in by_id.values()}) == 3


def test_placement_keeps_workers_times_threads_within_the_cores():
    p = plan_placement("local", 8, cores=2)
    assert (p.workers, p.threads) == (2, 1)
    p = plan_placement("local", 8, workers=1, cores=2)
    assert (p.workers, p.threads) == (1, 2)
    assert plan_placement("local", 1, cores=4).workers == 1
    with pytest.raises(ValueError, match="more than the"):
        run_tasks([{"id": "0", "x": 1}, {"id": "1", "x": 1}, {"id": "2", "x": 1}], FN, workers=3, threads=2)
