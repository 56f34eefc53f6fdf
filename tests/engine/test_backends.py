"""The same scenes on the CPU and on Vulkan (Mesa lavapipe here and in CI: tools/setup.sh installs it) give the
same counters, the same launched rocks, and positions equal to f32 round-off; the renderer draws the same
frames.

Taichi starts once per process and this test session runs on the CPU (fixture ``taichi_cpu``), so both
backends run in subprocesses, through the command line (``simulate --arch A --out X.npz``), side by side.
There is no skip: a machine without a Vulkan driver fails here, saying so (a fallback to the CPU would
compare the CPU with itself)."""

import re
import subprocess
import sys

import numpy as np
import pytest

from cli_util import _env, start_cli
from taichi_rocks import load_run

RESTING = 0
F32_EPS = float(np.finfo(np.float32).eps)
FALLBACK = "running on the CPU"  # runtime.init_taichi's warning when the asked-for device is missing


def _edited(text: str, edits) -> str:
    """``text`` with each (old, new) replaced exactly once (a scene file that changed fails loudly here)."""
    for old, new in edits:
        assert text.count(old) == 1, f"expected {old!r} once in the scene file"
        text = text.replace(old, new)
    return text


# name: (scene file, frames, fps, edits of its text). Small: a few seconds per backend (Vulkan on lavapipe
# costs tens of milliseconds a step, launching kernels), so a short stretch of a denser bed.
CASES = {
    # one car, patch detection and the tread model with fenders (the shipped scenes'), rocks hashed near the
    # tires (scope "tires"): the default passes
    "minimal": ("minimal.toml", 16, 60, [("rocks = 2000\n", "rocks = 8000\n")]),
    # swept detection and every rock hashed; Vulkan runs it with full stepping (the reference, with its
    # re-sorting of the rocks: tire_pass runs as a kernel of its own), the CPU with active stepping
    "minimal-swept-all": ("minimal.toml", 16, 60, [
        ("rocks = 2000\n", "rocks = 8000\n"), ('detection = "patch"', 'detection = "swept"'),
        ("dt = 0.004\n", 'dt = 0.004\n\n[sim.hash]\nscope = "all"\nreorder_every = 8\n')]),
    # two splashing vehicles in tight curves (four rear tires), fewer rocks than the scene's
    "slalom": ("slalom.toml", 11, 100, [("rocks = 100000\n", "rocks = 30000\n")]),
}


def _vulkan_device() -> str:
    """The arch Taichi really starts for ``vulkan`` in a fresh process (``vulkan``, or ``cpu`` on fallback)."""
    code = "from taichi_rocks.engine.runtime import init_taichi; print(init_taichi('vulkan', warn=lambda m: None))"
    r = subprocess.run([sys.executable, "-c", code], env=_env(), capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip().splitlines()[-1]


@pytest.fixture(scope="module")
def vulkan():
    arch = _vulkan_device()
    assert arch == "vulkan", (
        f"Taichi found no Vulkan device (it would run on {arch!r}): install a Vulkan driver, e.g. Mesa lavapipe "
        "(apt-get install mesa-vulkan-drivers libvulkan1, as tools/setup.sh does)")
    return arch


# per case, the stepping each arch runs (the scene's default, "active", unless given)
STEPPING = {"minimal-swept-all": {"vulkan": "full"}}


def _run_both(scene, frames, fps, tmp_path, stepping=None) -> dict:
    """Run ``scene`` on cpu and vulkan at once (with ``stepping[arch]``, if given: a copy of the scene with
    that [sim] stepping); per arch the .npz arrays and the reported launch total."""
    files = {}
    for a in ("cpu", "vulkan"):
        files[a] = scene
        if stepping and a in stepping:
            files[a] = tmp_path / f"{a}-{scene.name}"
            files[a].write_text(_edited(scene.read_text(), [("[sim]\n", f'[sim]\nstepping = "{stepping[a]}"\n')]))
    procs = {a: start_cli("simulate", files[a], "--arch", a, "--frames", frames, "--fps", fps,
                          "--out", tmp_path / f"{a}.npz") for a in ("cpu", "vulkan")}
    out = {}
    for arch, stdout in _finish(procs).items():
        m = re.search(r"(\d+) launches", stdout)
        assert m, stdout
        out[arch] = load_run(tmp_path / f"{arch}.npz")
        out[arch]["launches_total"] = int(m.group(1))
    return out


def _finish(procs: dict) -> dict:
    """Wait for the per-arch processes; each must succeed on its own device. Their stdout by arch."""
    out = {}
    for arch, p in procs.items():
        stdout, stderr = p.communicate(timeout=600)
        assert p.returncode == 0, f"{arch}: status {p.returncode}\n{stderr}"
        assert FALLBACK not in stderr, f"{arch} did not run on its device:\n{stderr}"
        out[arch] = stdout
    return out


def _launched(d) -> set:
    """Ids of the rocks that left RESTING in some frame (the arrays are in rock-id order)."""
    return set(np.flatnonzero((d["phase"] != RESTING).any(axis=0)).tolist())


def _phase_counts(d) -> np.ndarray:
    return np.stack([np.bincount(p, minlength=3) for p in d["phase"].astype(np.int64)])


def _tolerance(d) -> float:
    """Positions agree to f32 round-off. Kernels work in f32 on local coordinates of at most ``scale``
    metres, where one rounding is at most eps * scale / 2; the two backends may round a step differently
    (contracted multiply-adds, their own sin / cos / sqrt), and a difference carries on to later steps. The
    bound: one ulp of the largest coordinate per step, every step's difference adding up. (Measured: 0 to
    3e-7 m, a few ulps; a real disagreement, e.g. a rock launched a step later, is centimetres.)"""
    steps = int(round(float(d["time"][-1]) / float(d["dt"])))
    scale = float(np.max(np.abs(d["positions"]))) + 1.0
    return F32_EPS * scale * max(steps, 1)


@pytest.mark.parametrize("case", list(CASES))
def test_cpu_and_vulkan_agree(case, vulkan, scenes_dir, tmp_path):
    name, frames, fps, edits = CASES[case]
    scene = tmp_path / name
    scene.write_text(_edited((scenes_dir / name).read_text(), edits))
    run = _run_both(scene, frames, fps, tmp_path, STEPPING.get(case))
    cpu, vk = run["cpu"], run["vulkan"]

    # the scene does something: rocks are thrown in several frames, not only at the start
    assert cpu["launches_total"] > 0 and np.count_nonzero(cpu["launches"]) >= 2, cpu["launches"]
    # counters: per frame and total, and each backend's total is the sum of its frames
    np.testing.assert_array_equal(vk["launches"], cpu["launches"])
    assert vk["launches_total"] == cpu["launches_total"] == int(cpu["launches"].sum())
    # the same rocks launched, the same number in each phase in every frame
    assert _launched(vk) == _launched(cpu)
    assert len(_launched(cpu)) > 0
    np.testing.assert_array_equal(_phase_counts(vk), _phase_counts(cpu))
    # host-side state is computed in float64 from the same paths: identical
    for key in ("time", "bed_center", "vehicle_positions", "vehicle_headings", "radii"):
        np.testing.assert_array_equal(vk[key], cpu[key], err_msg=key)
    # rock positions: equal to f32 round-off
    tol = _tolerance(cpu)
    err = float(np.max(np.abs(vk["positions"] - cpu["positions"])))
    assert err <= tol, f"positions differ by {err:.3g} m > {tol:.3g} m"


def test_render_same_on_cpu_and_vulkan(vulkan, scenes_dir, tmp_path):
    """The renderer's own kernels (sky, splatted rocks in 64-bit z and colour buffers) on either backend draw
    the same frames (GGUI draws through Vulkan in both). The rocks they draw agree to f32 round-off, not to
    the bit (test_cpu_and_vulkan_agree: active stepping's fused kernel rounds a few rocks' positions a few
    ulps apart on the two backends), which can shift an edge of a rock by a fraction of a pixel: at most one
    level, in at most 0.1 % of the pixels (measured: 3 values of one pixel in 3 frames)."""
    import imageio.v3 as iio

    procs = {a: start_cli("render", scenes_dir / "minimal.toml", "--arch", a, "--frames", 3, "--format", "png",
                          "--resolution", "160x96", "--out", tmp_path / a) for a in ("cpu", "vulkan")}
    _finish(procs)
    names = sorted(p.name for p in (tmp_path / "cpu" / "frames").glob("frame_*.png"))
    assert len(names) == 3, names
    for name in names:
        cpu, vk = (iio.imread(tmp_path / a / "frames" / name) for a in ("cpu", "vulkan"))
        assert cpu.std() > 0  # not blank
        diff = np.abs(vk.astype(np.int16) - cpu.astype(np.int16))
        assert diff.max() <= 1, (name, int(diff.max()))
        assert np.count_nonzero(diff) <= 1e-3 * diff.size, (name, int(np.count_nonzero(diff)))


@pytest.mark.parametrize("real", ["f32", "f64"])
def test_world_trees_hold_one_element_size(taichi_cpu, real):
    """Each SNode tree of a World holds fields of one element size (world.FieldTrees): in a tree mixing 4- and
    8-byte fields, Vulkan can place a 64-bit field at 4 mod 8 and read and write it over its neighbour.
    Checked on the CPU, whose layout would hide the problem, with every optional field allocated."""
    import taichi as ti
    from taichi.lang.util import to_numpy_type

    from taichi_rocks.engine.world import World

    w = World(101, getattr(ti, real), hash_table=1031, hash_entries=101, n_tires=2, substeps=2, ray_capacity=5,
              reorder=True, tiles=(3, 3))
    sizes: dict = {}
    for f in w.fields():
        sizes.setdefault(f.snode.ptr.get_snode_tree_id(), set()).add(np.dtype(to_numpy_type(f.dtype)).itemsize)
    assert all(len(s) == 1 for s in sizes.values()), sizes
    assert sorted(s.pop() for s in sizes.values()) == [4, 8]  # the i64 counter and the rest: two trees
    # the fields work as before: the counter, a vector field, a 0-d int
    w.launches[None] = 2 ** 40 + 3
    w.n_listed[None] = 7
    w.pos.from_numpy(np.arange(303, dtype=w.np_real()).reshape(101, 3))
    assert w.launches[None] == 2 ** 40 + 3 and w.n_listed[None] == 7
    assert w.pos.to_numpy()[100, 2] == 302
