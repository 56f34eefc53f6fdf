"""Taichi start-up, once per process: architecture choice with a CPU fallback.

Taichi can be initialised only once per process in practice (a second ``ti.init`` drops every field and
compiled kernel), so every entry point calls :func:`init_taichi`, which is idempotent.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys

import taichi as ti

from ..config.arches import ARCHES
from ..config.environment import (PARALLEL_SCAN, THREADS, loops_wanted, parallel_scan_wanted,  # noqa: F401
                                  threads_wanted)
from . import frontend

_state: dict = {"arch": None}
CACHE_BYTES = 1 << 30  # the offline kernel cache's size limit (Taichi's default: 100 MB)
QUICK_COMPILE = "TAICHI_ROCKS_QUICK_COMPILE"  # the environment variable of quick_compile()


def init_taichi(arch: str = "cpu", *, warn=None, profiler: bool = False) -> str:
    """Initialise Taichi once; return the arch actually used ("cpu", "cuda" or "vulkan").

    ``gpu``/``cuda``/``vulkan`` fall back to the CPU with one warning line when unavailable.
    Calling again with another arch keeps the first one (and says so once). ``profiler``: turn on Taichi's
    kernel profiler (engine/timing.py ``kernel_tasks``; every task then times itself: for the benchmark).
    Raises ValueError (one line naming it) for a bad ``arch`` or a bad value of an environment variable of
    config/environment.py, before Taichi starts.
    """
    if arch not in ARCHES:
        raise ValueError(f"arch must be one of {', '.join(ARCHES)}, got {arch!r}")
    # a bad value is refused at every start, not only the first
    threads_wanted(), parallel_scan_wanted(), loops_wanted()
    warn = warn or (lambda msg: print(f"taichi-rocks: warning: {msg}", file=sys.stderr))
    if _state["arch"] is not None:
        return _state["arch"]
    frontend.install()  # the same kernels, compiled with less of the front end's repeated work
    threads = auto_threads()
    # fast_math off: x / l must round exactly like NumPy for cells on boundaries to agree everywhere. The offline
    # kernel cache may hold CACHE_BYTES: Taichi's 100 MB default is less than the package's kernels (the test
    # suite's, every scene's and the renderer's: about 140 MB), and past it Taichi drops a quarter of the files
    # at every exit, so every run compiled again
    opts = dict(log_level=ti.ERROR, random_seed=0, fast_math=False, offline_cache_max_size_of_files=CACHE_BYTES)
    if quick_compile():
        opts["advanced_optimization"] = False
    if profiler:
        opts["kernel_profiler"] = True
    opts["cpu_max_num_threads"] = threads
    quiet = contextlib.redirect_stdout(io.StringIO())  # Taichi prints its banner on stdout
    if arch == "cpu":
        with quiet:
            ti.init(arch=ti.cpu, **opts)
    else:
        # "gpu" means CUDA: on a machine without one, Taichi's generic ti.gpu would pick a software
        # Vulkan device (Mesa lavapipe), which computes slower than the CPU backend.
        wanted = {"gpu": ti.cuda, "cuda": ti.cuda, "vulkan": ti.vulkan}[arch]
        with quiet:
            ti.init(arch=wanted, **opts)
        if ti.lang.impl.current_cfg().arch in (ti.x64, ti.arm64):
            warn(f"no {arch} device found, running on the CPU")
    used = ti.lang.impl.current_cfg().arch
    _state["arch"] = "cpu" if used in (ti.x64, ti.arm64) else str(used).split(".")[-1]
    return _state["arch"]


AUTO_THREADS_MAX = 4  # the engine's choice: every core up to this many (bench --only frame measures it)


def threads_set() -> bool:
    return threads_wanted() is not None


def auto_threads() -> int:
    """The CPU backend's thread pool: ``TAICHI_ROCKS_THREADS`` if set (a whole number >= 1), else every core up
    to AUTO_THREADS_MAX. A step is a chain of small parallel tasks (a few hundred rocks each in a game's
    frame); each wakes the whole pool, so past a few threads a step gets slower, not faster (measured on 16
    cores: 13.7 ms a frame against 5.5-9.4 ms on 2). A bad value: ValueError (config/environment.py)."""
    n = threads_wanted()
    if n is not None:
        return n
    return max(1, min(os.cpu_count() or 1, AUTO_THREADS_MAX))


def threads_in_use() -> int:
    """The CPU thread pool's size of this process's Taichi runtime (after init_taichi)."""
    return int(ti.lang.impl.current_cfg().cpu_max_num_threads)


def quick_compile() -> bool:
    """True if ``TAICHI_ROCKS_QUICK_COMPILE=1``: Taichi's own optimisation of its IR is off
    (``advanced_optimization=False``; LLVM still optimises the code it is given). Kernels compile 2-2.5x faster
    (the default scene's first step: 10.0 s -> 3.8 s of CPU) and compute the same bits (the golden digests of
    every shipped scene, tests/engine/test_golden.py, checked in both modes); a step may run slower (1,000,000
    rocks, three alternating runs: full stepping 6-42 % longer, active stepping -24 % to +50 %, the machine's
    noise). For short runs that compile much: the test suite sets it (tests/conftest.py), a sweep of many
    layouts, the viewer's recompile buttons."""
    return os.environ.get(QUICK_COMPILE, "") == "1"


def current_arch():
    return _state["arch"]


def on_cpu() -> bool:
    return _state["arch"] == "cpu"
