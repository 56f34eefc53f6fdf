"""Taichi is initialised once per test session (CPU backend)."""

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))


@pytest.fixture(scope="session")
def taichi_cpu():
    from taichi_rocks.engine.runtime import init_taichi

    return init_taichi("cpu")


@pytest.fixture(scope="session")
def scenes_dir():
    return ROOT / "scenes"
