"""The sweep runner: plain-data tasks run by a function in worker processes, on this machine or a Ray cluster.

``run_tasks(tasks, fn, backend=..., ...)`` calls ``fn(task)`` (``fn`` named as ``"module:function"``, imported in
the worker) for every task (a dict with an ``"id"``, nothing but plain data) and reports each outcome to the
caller as it arrives. No Taichi object crosses a process: a task and its result are dicts.

* ``local``: worker processes, each a fresh interpreter (``python -m taichi_rocks.runner.tasks``, spawned,
  never forked: Taichi allows one runtime per process, and forking after ``ti.init`` can deadlock; nor does
  the caller's main module run again in them, as multiprocessing's spawn would do). Each worker keeps its process, and so its Taichi runtime, its compiled kernels and
  its pool of fields, from task to task. ``TAICHI_ROCKS_THREADS`` (read by engine/runtime.py) gives each
  worker ``threads`` Taichi threads, so that workers x threads <= cores.
* ``ray``: long-lived actors (``num_cpus=threads`` each) holding one Taichi runtime each, with the same thread
  count (Ray's OMP_NUM_THREADS does not bind Taichi's pool). ``address`` joins a running cluster (``ray start
  --head`` on one machine, ``ray start --address`` on the others); without it a local cluster is started for
  the run and stopped after it. The driver's ``taichi_rocks`` package is shipped to the actors (runtime_env
  py_modules), so every node runs the same code.

Faults: an exception in ``fn`` is that task's error (one line), the others go on; the worker is replaced
(a failed build can leave Taichi unable to allocate fields in that process). A worker that dies in the
middle of a task (kill -9, the out-of-memory killer) is replaced and the task is run again on another worker,
up to ``retries`` times; each task is reported exactly once. ``fresh=True`` gives every task a new process
(the benchmark: memory measured per point). Ctrl-C stops the workers and raises KeyboardInterrupt. This
module imports nothing of the project, so that every room may use it.
"""

from __future__ import annotations

import collections
import importlib
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from pathlib import Path

THREADS_ENV = "TAICHI_ROCKS_THREADS"   # engine/runtime.py: Taichi's cpu_max_num_threads
BACKENDS = ("local", "ray")
WHOLE_NODE = 0   # threads=WHOLE_NODE on Ray: each actor holds every CPU of the largest node (timings undisturbed)


@dataclass
class Outcome:
    """What became of one task: its result dict, or the error's line; attempts (> 1 after a worker died)."""
    task: dict
    result: dict | None
    error: str | None
    attempts: int
    worker: str = ""


@dataclass
class Placement:
    """How many workers, with how many Taichi threads each, and where."""
    backend: str = "local"
    workers: int | None = None
    threads: int | None = None
    address: str | None = None
    cores: int = 0


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def error_line(exc: BaseException) -> str:
    text = f"{type(exc).__name__}: {exc}".strip().splitlines()
    return text[0] if text else type(exc).__name__


def _resolve(fn: str):
    module, _, name = fn.partition(":")
    return getattr(importlib.import_module(module), name)


def _call(f, task: dict) -> tuple:
    try:
        return "ok", f(task)
    except Exception as exc:  # a task that fails is reported; the worker goes on
        return "error", error_line(exc)


def plan_placement(backend: str, tasks: int, workers=None, threads=None, cores=None, address=None) -> Placement:
    """Workers and threads so that workers x threads <= cores (``cores``: this machine's, or the cluster's)."""
    cores = int(cores or usable_cores())
    if workers is None:
        threads = threads or 1
        workers = max(1, min(cores // threads, tasks))
    else:
        workers = max(1, min(workers, tasks)) if tasks else workers
        threads = threads or max(1, cores // workers)
    return Placement(backend, workers, threads, address, cores)


# ------------------------------------------------------------------------------------------------ local
def _local_main(rfd: int, wfd: int, fn: str) -> None:
    """A local worker (``python -m taichi_rocks.runner.tasks RFD WFD FN``): tasks from the pipe until None;
    Ctrl-C is the parent's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    tasks, results = Connection(rfd, writable=False), Connection(wfd, readable=False)
    f = _resolve(fn)
    while True:
        try:
            task = tasks.recv()
        except EOFError:
            return
        if task is None:
            return
        results.send(_call(f, task))


def _package_root() -> str:
    return str(Path(__file__).resolve().parents[3])


class _Local:
    """A worker process: a fresh interpreter (so nothing of this process's Taichi or its main module), fed
    tasks through one pipe and answering through another; the answer pipe reads as closed once it dies."""

    def __init__(self, fn: str, threads: int):
        task_r, task_w = os.pipe()
        res_r, res_w = os.pipe()
        path = os.environ.get("PYTHONPATH")
        env = dict(os.environ, **{THREADS_ENV: str(threads)},
                   PYTHONPATH=_package_root() + (os.pathsep + path if path else ""))
        self.proc = subprocess.Popen([sys.executable, "-m", "taichi_rocks.runner.tasks", str(task_r),
                                      str(res_w), fn], pass_fds=(task_r, res_w), env=env)
        os.close(task_r)
        os.close(res_w)
        self.tasks, self.conn = Connection(task_w, readable=False), Connection(res_r, writable=False)
        self.task = None

    @property
    def name(self) -> str:
        return f"local:{self.proc.pid}"

    def give(self, task: dict) -> None:
        self.task, self.started = task, time.monotonic()
        try:
            self.tasks.send(task)
        except OSError:  # died while idle: the closed answer pipe says so, and the task is run again
            pass

    def stop(self, now: bool = False) -> None:
        """Let the worker finish and exit; ``now``: end it at once (Ctrl-C: its run is given up)."""
        if now and self.task is not None and self.proc.poll() is None:
            self.proc.terminate()
        try:
            self.tasks.send(None)
        except (OSError, ValueError):
            pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.terminate()
            self.proc.wait(timeout=5)
        self.tasks.close()
        self.conn.close()


def _death(proc) -> str:
    code = proc.wait()
    if code < 0:
        return f"killed by signal {-code} ({signal.Signals(-code).name})"
    return f"exited with status {code}"


def _overdue(pool, timeout, fn, place, attempts, report) -> None:
    """End the workers whose task has run longer than ``timeout`` s: that task's error, a new worker."""
    for i, w in enumerate(pool):
        if timeout and w.task is not None and time.monotonic() - w.started > timeout:
            w.proc.kill()
            task = w.task
            w.stop()
            pool[i] = _Local(fn, place.threads)
            report(Outcome(task, None, f"timed out after {timeout:.0f} s", attempts[task["id"]], w.name))


def _run_local(tasks, fn, place: Placement, retries: int, report, fresh: bool, timeout=None) -> None:
    queue = collections.deque(tasks)
    attempts = collections.Counter()
    pool = [_Local(fn, place.threads) for _ in range(place.workers)]
    try:
        while queue or any(w.task is not None for w in pool):
            for w in pool:
                if w.task is None and queue:
                    w.give(queue.popleft())
                    attempts[w.task["id"]] += 1
            ready = set(wait([w.conn for w in pool], timeout=timeout and 1.0))
            _overdue(pool, timeout, fn, place, attempts, report)
            for i, w in enumerate(pool):
                if w.conn not in ready:
                    continue
                try:
                    status, value = w.conn.recv()
                except (EOFError, OSError):  # the worker died: its end of the pipe closed with it
                    task, why = w.task, _death(w.proc)
                    w.stop()
                    pool[i] = _Local(fn, place.threads)  # a new worker in place of the dead one
                    if task is not None:
                        _retry(task, why, attempts, retries, queue, report, w.name)
                    continue
                task, w.task = w.task, None
                report(Outcome(task, value if status == "ok" else None, value if status != "ok" else None,
                               attempts[task["id"]], w.name))
                if fresh or status != "ok":  # after an error the runtime may be unusable (a field builder
                    w.stop()                 # left open): a new process
                    pool[i] = _Local(fn, place.threads)
    except BaseException:
        for w in pool:
            w.stop(now=True)
        raise
    for w in pool:
        w.stop()


def _retry(task, why, attempts, retries, queue, report, worker) -> None:
    n = attempts[task["id"]]
    if n > retries:
        report(Outcome(task, None, f"the worker died {'once' if n == 1 else f'{n} times'} (last: {why})", n,
                       worker))
    else:
        queue.appendleft(task)


# ------------------------------------------------------------------------------------------------ ray
class _RayWorker:
    """A Ray actor holding one Taichi runtime (started by its first task)."""

    def __init__(self, fn: str, threads: int):
        os.environ[THREADS_ENV] = str(threads)
        self.fn = fn
        self.f = None

    def pid(self) -> int:
        return os.getpid()

    def run(self, task: dict):
        if self.f is None:
            self.f = _resolve(self.fn)
        return _call(self.f, task)


def ray_connect(address, cores: int | None):
    """Join the cluster at ``address``, or start a local one; returns (ray module, CPUs, started_here)."""
    import ray

    package = str(Path(__file__).resolve().parents[2])  # the taichi_rocks folder: every node runs this code
    env = {"py_modules": [package]}
    if address:
        ray.init(address=address, runtime_env=env, log_to_driver=False, logging_level="ERROR")
    else:
        ray.init(num_cpus=cores or usable_cores(), include_dashboard=False, runtime_env=env, log_to_driver=False,
                 logging_level="ERROR")
    cpus = int(ray.cluster_resources().get("CPU", 1))
    return ray, cpus, not address


def _largest_node(ray) -> int:
    return max([int(n["Resources"].get("CPU", 0)) for n in ray.nodes() if n.get("Alive")] or [1])


def _run_ray(tasks, fn, place: Placement, retries: int, report, fresh: bool) -> None:
    ray, cpus, _ = ray_connect(place.address, None)
    try:
        largest = _largest_node(ray)
        if place.threads == WHOLE_NODE:
            p = plan_placement("ray", len(tasks), place.workers, largest, cpus, place.address)
        else:
            p = plan_placement("ray", len(tasks), place.workers, place.threads, cpus, place.address)
            p.threads = min(p.threads, largest)
        place.workers, place.threads, place.cores = p.workers, p.threads, cpus
        actor_cls = ray.remote(_RayWorker)

        def new():
            return actor_cls.options(num_cpus=place.threads, max_restarts=0).remote(fn, place.threads)

        idle = [(new(), f"ray:{i}") for i in range(place.workers)]
        made = place.workers
        queue, pending = collections.deque(tasks), {}
        attempts = collections.Counter()
        try:
            while queue or pending:
                while queue and idle:
                    (actor, name), task = idle.pop(), queue.popleft()
                    attempts[task["id"]] += 1
                    pending[actor.run.remote(task)] = (actor, name, task)
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    actor, name, task = pending.pop(ref)
                    try:
                        status, value = ray.get(ref)
                    except ray.exceptions.RayActorError as exc:
                        ray.kill(actor)
                        idle.append((new(), f"ray:{made}"))
                        made += 1
                        _retry(task, f"the actor died ({type(exc).__name__})", attempts, retries, queue, report,
                               name)
                        continue
                    report(Outcome(task, value if status == "ok" else None, value if status != "ok" else None,
                                   attempts[task["id"]], name))
                    if fresh or status != "ok":  # after an error the runtime may be unusable
                        ray.kill(actor)
                        actor, name, made = new(), f"ray:{made}", made + 1
                    idle.append((actor, name))
        finally:
            for actor, _, _ in pending.values():
                ray.kill(actor)
            for actor, _ in idle:
                ray.kill(actor)
    finally:
        ray.shutdown()


def run_tasks(tasks: list, fn: str, *, backend: str = "local", workers=None, threads=None, address=None,
              retries: int = 2, report=None, fresh: bool = False, timeout=None) -> Placement:
    """Run ``fn`` on every task (see the module docstring); ``report(outcome)`` is called in this process as
    each task ends, in the order they end. ``timeout`` (local): seconds a task may run before its worker is
    ended and the task reported as timed out. Returns the placement used (workers, threads, cores)."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    report = report or (lambda outcome: None)
    tasks = list(tasks)
    if backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ValueError("the ray backend needs the ray package: pip install 'taichi-rocks[ray]'") from None
        place = Placement("ray", workers, threads, address)
        if tasks:
            _run_ray(tasks, fn, place, retries, report, fresh)
        return place
    if address:
        raise ValueError("--address is for the ray backend")
    place = plan_placement("local", len(tasks), workers, threads)
    if place.workers * place.threads > place.cores:
        raise ValueError(f"{place.workers} workers x {place.threads} threads is more than the {place.cores} "
                         f"cores here")
    if tasks:
        _run_local(tasks, fn, place, retries, report, fresh, timeout)
    return place


if __name__ == "__main__":  # a local worker, started by _Local
    _local_main(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3])
