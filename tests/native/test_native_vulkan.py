"""The native host on Vulkan (Mesa's lavapipe here, any Vulkan device in a game): a module of tests/native/native.toml
(4,000 rocks, one step a frame) made for ``--arch vulkan`` and run by rocks_run gives Python's twin's run on the
CPU up to the CPU-vs-Vulkan round-off of tools/compare_runs.py: the same launches, recycles, impact events and
phases, every position within one f32 ulp of the scene's coordinates per step. About 60-90 s here: lavapipe runs
each step's kernels in about 0.6 s on the CPU, and compiling the module's pipelines takes 10-40 s the first time."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from native_util import FPS, ROOT, SCENE, aot, build, event_columns, run, twin_run
from taichi_rocks.config.scene import load_scene

FRAMES = 40
NO_VULKAN = ("Taichi found no Vulkan device: install a Vulkan driver, e.g. Mesa lavapipe (apt-get install "
             "mesa-vulkan-drivers libvulkan1, as tools/setup.sh does)")
spec = importlib.util.spec_from_file_location("compare_runs", ROOT / "tools" / "compare_runs.py")
compare_runs = importlib.util.module_from_spec(spec)
spec.loader.exec_module(compare_runs)


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    text = SCENE.read_text().replace("rocks = 20000", "rocks = 4000").replace("dt = 0.008333333333333333\n", "")
    path = tmp_path_factory.mktemp("scene") / "native-vulkan.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def runs(scene_file, tmp_path_factory, taichi_cpu):
    built = build(tmp_path_factory.mktemp("native"))
    module = tmp_path_factory.mktemp("aot") / "native-vulkan"
    r = aot(scene_file, "vulkan", module)
    if r.returncode != 0 and "needs Taichi on vulkan" in r.stderr:
        pytest.fail(NO_VULKAN + f"\n{r.stderr}")
    assert r.returncode == 0, f"aot: status {r.returncode}\n{r.stdout}\n{r.stderr}"
    cpp = run(built, module, tmp_path_factory.mktemp("dump"), FRAMES)
    py = twin_run(load_scene(scene_file), module, FRAMES)
    return cpp, py


def test_vulkan_module_gives_the_cpu_run_to_round_off(runs):
    cpp, py = runs
    sim, st = py["sim"], py["state"]
    assert sim.launches_total > 50  # (rocks thrown from the first frames on)
    assert cpp["counts"] == {"launches": sim.launches_total, "recycles": sim.recycles_total,
                             "impacts": len(py["events"]), "steps": sim.step_count}
    one = lambda pos, phase: {"positions": pos[None], "phase": phase[None], "launches": np.array([0]),  # noqa: E731
                              "time": np.array([FRAMES / FPS]), "dt": np.float64(sim.dt)}
    res = compare_runs.compare(one(st.positions, st.phase), one(cpp["positions"], cpp["phase"]))
    assert res["same"], compare_runs.report(res, 1)
    ev = event_columns(py["events"])
    assert cpp["impacts"].shape == ev.shape and np.array_equal(cpp["impacts"][:, 1:], ev[:, 1:])
    assert np.allclose(cpp["impacts"][:, 0], ev[:, 0], rtol=0, atol=1e-5)
