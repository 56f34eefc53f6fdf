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


# Seconds each of the slowest files takes (the mean of two suite runs on a 2-core machine, from
# ``pytest --junitxml``), slowest first. The suite runs whole files on its two workers (``--dist loadfile``,
# Makefile), handed out in this order: the long files start first and the short ones fill in at the end, so
# neither worker is left with a long file while the other idles. A file not listed runs after these; the
# figures only order the files and need refreshing only when the order has changed a lot.
SLOW_FILES = {
    "app/test_sweep.py": 105, "render/test_render.py": 89, "engine/test_robustness.py": 85, "test_cli.py": 66,
    "engine/test_impacts_step.py": 66, "bench/test_bench.py": 62, "render/test_view.py": 25,
    "engine/test_impacts.py": 56, "engine/test_lookahead.py": 53, "render/test_view_controls.py": 55,
    "engine/test_golden.py": 45, "engine/test_engine.py": 44, "engine/test_backends.py": 39,
    "engine/test_tumble.py": 32, "render/test_marks_engine.py": 28, "engine/test_rockfields.py": 27,
    "engine/test_active.py": 25, "engine/test_tires.py": 22, "engine/test_tuning.py": 21,
    "render/test_render_stepping.py": 20, "bench/test_impacts_study.py": 18, "output/test_export.py": 18,
    "output/test_impact_export.py": 17, "engine/test_translation.py": 17, "bench/test_launch_study.py": 17,
    "engine/test_properties.py": 15, "render/test_tumbling.py": 15, "engine/test_hashgrid.py": 13,
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
    Worlds go back to the pool (engine/world.py ``acquire``) for the next modules instead of a new compile."""
    yield
    gc.collect()
