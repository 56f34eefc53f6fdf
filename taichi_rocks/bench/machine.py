"""The run's surroundings: the machine it ran on, the load average, a progress bar, and the engine's source
pinned for the run (so that a kernel compiled late in a long run is compiled from the source imported)."""

from __future__ import annotations

import linecache
import os
import platform
import sys
from pathlib import Path

import numpy as np
import scipy
import taichi as ti
from tqdm import tqdm


def _is_kernel(obj) -> bool:
    return bool(getattr(obj, "_is_wrapped_kernel", False))


def pin_sources() -> None:
    """Keep the source Taichi compiles kernels from fixed for this run. Taichi reads a kernel's source (through
    linecache) when it first compiles it, so a file edited during a long run would mix two versions of the
    engine; pinned entries (no mtime) are never re-read. Each kernel's def line is checked against it."""
    for name, mod in list(sys.modules.items()):
        if not (name == "taichi_rocks" or name.startswith("taichi_rocks.")):
            continue
        f = getattr(mod, "__file__", None)
        if not f or not f.endswith(".py"):
            continue
        try:
            text = Path(f).read_text()
        except OSError:
            continue
        lines = text.splitlines(keepends=True)
        for obj in vars(mod).values():
            fn = getattr(obj, "__wrapped__", None)
            if _is_kernel(obj) and fn is not None and getattr(fn, "__module__", None) == name:
                first = fn.__code__.co_firstlineno
                window = "".join(lines[max(0, first - 1):first + 2])
                if f"def {fn.__name__}" not in window:
                    raise RuntimeError(f"{f} changed since it was imported ({fn.__name__} moved); run the "
                                       "benchmark again")
        linecache.cache[f] = (len(text), None, lines, f)


def loadavg():
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (OSError, AttributeError):
        return None


def was_busy(load_start, load_end, cores) -> bool:
    """Whether other work shared the machine during a run, from the 1-minute load averages at its start and
    end: at the start more than 3/4 of the cores busy, or at the end more than that on top of the run's own
    processes (which keep up to every core busy)."""
    cores = cores or 1
    return load_start[0] > 0.75 * cores or load_end[0] > 1.75 * cores


def machine(arch: str) -> dict:
    model = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()
    mem = None
    try:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 1e9
    except (ValueError, OSError, AttributeError):
        pass
    info = {"cpu_model": model, "logical_cores": os.cpu_count(), "usable_cores": usable,
            "memory_gb": round(mem, 1) if mem else None, "python": platform.python_version(),
            "platform": platform.platform(), "taichi": ".".join(str(x) for x in ti.__version__),
            "numpy": np.__version__, "scipy": scipy.__version__, "taichi_arch": arch,
            "taichi_threads": os.environ.get("TAICHI_ROCKS_THREADS", "default (every core up to 4)")}
    try:
        import matplotlib

        info["matplotlib"] = matplotlib.__version__
    except ImportError:
        info["matplotlib"] = None
    return info


class Progress:
    def __init__(self, total: int, enabled):
        self.bar = None
        if enabled is not False:
            self.bar = tqdm(total=total, file=sys.stderr, disable=None if enabled is None else False,
                            unit="task", dynamic_ncols=True)

    def __call__(self, desc: str, n: int = 1):
        if self.bar is not None:
            self.bar.set_description(desc[:48])
            self.bar.update(n)

    def note(self, desc: str):
        if self.bar is not None:
            self.bar.set_description(desc[:48])
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.n = self.bar.total
            self.bar.refresh()
            self.bar.close()
