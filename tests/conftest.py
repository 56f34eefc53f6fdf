"""Taichi is initialised once per test session (CPU backend)."""

import gc
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
# Taichi's own IR optimisation off for the suite and the processes it starts (engine/runtime.py quick_compile):
# kernels compile 2-2.5x faster and compute the same bits; tests/engine/test_golden.py holds both modes to the
# committed digests. TAICHI_ROCKS_QUICK_COMPILE=0 runs the suite as the package ships.
os.environ.setdefault("TAICHI_ROCKS_QUICK_COMPILE", "1")


# Seconds each of the slowest files takes (a suite run on a 2-core machine, from a per-file timer), slowest first.
# The suite runs whole files on its two workers (``--dist loadfile``, Makefile), handed out in this order: the long
# files start first and the short ones fill in at the end, so neither worker is left with a long file while the
# other idles. A file not listed runs after these; the figures only order the files and need refreshing only when
# the order has changed a lot.
SLOW_FILES = {
    "render/test_render.py": 71, "app/test_sweep.py": 69, "bench/test_bench.py": 67, "engine/test_robustness.py": 54,
    "render/test_view_controls.py": 49, "engine/test_engine.py": 41, "engine/test_lookahead.py": 38,
    "test_cli.py": 31, "engine/test_golden.py": 30, "engine/test_tumble.py": 28, "engine/test_impacts_step.py": 28,
    "engine/test_backends.py": 26, "engine/test_impacts.py": 24, "engine/test_active.py": 20,
    "render/test_view.py": 18, "render/test_view_drive.py": 16, "engine/test_drive.py": 30, "render/test_marks_engine.py": 17, "engine/test_tires.py": 14,
    "bench/test_launch_study.py": 14, "bench/test_impacts_study.py": 14, "render/test_shots.py": 13,
    "output/test_export.py": 13, "render/test_render_stepping.py": 12, "render/test_interior.py": 12,
    "engine/test_rockfields.py": 11, "engine/test_reference_stepping.py": 10, "test_cli_coverage.py": 9,
    "render/test_tumbling.py": 9, "output/test_export_values.py": 9, "test_game.py": 35,
}


def pytest_collection_modifyitems(session, config, items):
    """The slowest files first (SLOW_FILES); each file's tests stay together and in their order."""
    here = Path(__file__).resolve().parent

    def cost(item):
        try:
            return -SLOW_FILES.get(Path(str(item.fspath)).resolve().relative_to(here).as_posix(), 0)
        except ValueError:
            return 0

    items.sort(key=cost)


@pytest.fixture(scope="session")
def taichi_cpu():
    from taichi_rocks.engine.runtime import init_taichi

    return init_taichi("cpu")


@pytest.fixture(scope="session")
def scenes_dir():
    return ROOT / "scenes"


@pytest.fixture(scope="module", autouse=True)
def _release_worlds():
    """After each test module, collect what its tests and fixtures left in reference cycles: their Simulations'
    Worlds and Renderers' buffers are freed (or go back to their pools) before the next modules."""
    yield
    gc.collect()
