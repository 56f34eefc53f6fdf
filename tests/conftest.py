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
