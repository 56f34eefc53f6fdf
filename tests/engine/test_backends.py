"""The same scenes on the CPU and on Vulkan (Mesa lavapipe here and in CI: tools/setup.sh installs it) give the
same counters, the same launched rocks, and positions equal to f32 round-off; the renderer draws the same
frames.

Taichi starts once per process and this test session runs on the CPU (fixture ``taichi_cpu``): the CPU side runs
in this process (commands_in_turn.py ``run_each``), the Vulkan side in one subprocess that runs every scene in turn
(commands_in_turn.py), both through the command line (``simulate --arch A --out X.npz``, ``render``), side by
side. There is no skip: a machine without a Vulkan driver fails here, saying so (a fallback to the CPU would
compare the CPU with itself)."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cli_util import _env, reaped
from commands_in_turn import run_each
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
    # the default scene as it ships, impacts on: its first frames, where stones thrown in a grazing hop land
    # and are thrown again (the impacts' pass once stopped the thread on Vulkan: such a stone was hashed a step
    # late, one launch short)
    "convoy": ("convoy.toml", 5, 60, []),
    # a live drive (docs/drives.md): the car replays a recorded drive that weaves off its road, its wheels spinning
    # at twice their rolling rate for a while (_write_drive), the poses between the drive's interpolated
    "drive": ("minimal.toml", 16, 60, [("rocks = 2000\n", "rocks = 8000\n"),
                                        ("path = { points = [[0.0, 0.0], [40.0, 0.0]], speed = 10.0 }",
                                         'path = { kind = "recorded", file = "drive.drive" }')]),
}


# per case, the stepping each arch runs (the scene's default, "active", unless given)
STEPPING = {"minimal-swept-all": {"vulkan": "full"}}
DRIVER = Path(__file__).resolve().parent / "commands_in_turn.py"
NO_VULKAN = ("Taichi found no Vulkan device (it would run on {!r}): install a Vulkan driver, e.g. Mesa lavapipe "
             "(apt-get install mesa-vulkan-drivers libvulkan1, as tools/setup.sh does)")


def _commands(scenes_dir, folder: Path, arch: str) -> dict:
    """Name -> the arguments of each command compared, run on ``arch`` into ``folder``: a simulate per case (its
    scene edited, with the [sim] stepping of STEPPING, if given), and the render."""
    commands = {}
    for case, (name, frames, fps, edits) in CASES.items():
        text = _edited((scenes_dir / name).read_text(), edits)
        if arch in STEPPING.get(case, {}):
            text = _edited(text, [("[sim]\n", f'[sim]\nstepping = "{STEPPING[case][arch]}"\n')])
        scene = folder / f"{case}.toml"
        scene.write_text(text)
        if case == "drive":
            _write_drive(folder / "drive.drive")
        commands[case] = ("simulate", scene, "--arch", arch, "--frames", frames, "--fps", fps,
                          "--out", folder / f"{case}.npz")
    commands["render"] = ("render", scenes_dir / "minimal.toml", "--arch", arch, "--frames", 3, "--format", "png",
                          "--resolution", "160x96", "--out", folder / "render")
    return {name: [str(a) for a in args] for name, args in commands.items()}


def _write_drive(path: Path) -> None:
    """A recorded drive of 0.5 s at 30 poses a second: along +x at 10 m/s, weaving 1.5 m to the side, the rear
    wheels at twice their rolling rate from 0.1 s to 0.3 s (R = 0.33 m: minimal.toml's default tire)."""
    from taichi_rocks.config.drivefile import drive_text

    rows = []
    for k in range(16):
        t = k / 30
        vy, ay = 1.5 * 6.0 * np.cos(6.0 * t), -1.5 * 36.0 * np.sin(6.0 * t)
        spin = 2.0 * 10.0 / 0.33 if 0.1 <= t <= 0.3 else float("nan")
        rows.append((t, 10.0 * t, 1.5 * np.sin(6.0 * t), np.arctan2(vy, 10.0), np.hypot(10.0, vy),
                     10.0 * ay / (100.0 + vy * vy), spin))
    path.write_text(drive_text(rows))


def _start_vulkan(folder: Path, commands: dict) -> subprocess.Popen:
    """The process running ``commands`` on Vulkan, once it has said that Taichi started there."""
    vk = subprocess.Popen([sys.executable, str(DRIVER), "vulkan", str(folder), json.dumps(commands)],
                          env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    started = re.fullmatch(r"arch: (\w+)\n", vk.stdout.readline())
    if started is None or started.group(1) != "vulkan":
        _, stderr = vk.communicate(timeout=300)
        assert started, f"vulkan: status {vk.returncode}\n{stderr}"
        raise AssertionError(NO_VULKAN.format(started.group(1)))
    return vk


@pytest.fixture(scope="module")
def runs(taichi_cpu, scenes_dir, tmp_path_factory) -> dict:
    """Every command on both archs, at once: Vulkan's in one subprocess, meanwhile the CPU's here. Per arch, its
    folder and, by command name, (exit status, stdout, stderr)."""
    root = tmp_path_factory.mktemp("backends")
    folders = {a: root / a for a in ("cpu", "vulkan")}
    commands = {}
    for arch, folder in folders.items():
        folder.mkdir()
        commands[arch] = _commands(scenes_dir, folder, arch)
    with reaped(_start_vulkan(folders["vulkan"], commands["vulkan"])) as vk:
        cpu = run_each(commands["cpu"])
        _, stderr = vk.communicate(timeout=900)
    assert vk.returncode == 0 and FALLBACK not in stderr, f"vulkan: status {vk.returncode}\n{stderr}"
    vulkan = {}
    for name in commands["vulkan"]:
        r = json.loads((folders["vulkan"] / f"{name}.json").read_text())
        vulkan[name] = (r["status"], r["stdout"], r["stderr"])
    return {"cpu": (folders["cpu"], cpu), "vulkan": (folders["vulkan"], vulkan)}


def _finished(runs: dict, name: str) -> dict:
    """Per arch, the folder of command ``name``'s outputs and its stdout; it must have succeeded on its
    device."""
    out = {}
    for arch, (folder, results) in runs.items():
        status, stdout, stderr = results[name]
        assert status == 0, f"{arch}: status {status}\n{stderr}"
        assert FALLBACK not in stderr, f"{arch} did not run on its device:\n{stderr}"
        out[arch] = (folder, stdout)
    return out


def _run_both(runs: dict, case: str) -> dict:
    """Per arch, the .npz arrays of ``case`` and the reported launch total."""
    out = {}
    for arch, (folder, stdout) in _finished(runs, case).items():
        m = re.search(r"(\d+) launches", stdout)
        assert m, stdout
        out[arch] = load_run(folder / f"{case}.npz")
        out[arch]["launches_total"] = int(m.group(1))
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
def test_cpu_and_vulkan_agree(case, runs):
    run = _run_both(runs, case)
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
    # with impacts: the same hits, every field. The convoy's first frames hold none yet (its stones reach the
    # vehicles later): the hits themselves are compared in test_impacts_step.py test_vulkan_gives_the_cpu_events
    # (33 hits, every field of them), so here an empty pair is only an empty pair
    assert ("impacts" in vk) == ("impacts" in cpu)
    if "impacts" in cpu:
        assert len(vk["impacts"]) == len(cpu["impacts"])
        for k in cpu["impacts"].dtype.names:
            np.testing.assert_allclose(vk["impacts"][k], cpu["impacts"][k], rtol=1e-4, atol=1e-4, err_msg=k)
    # host-side state is computed in float64 from the same paths: identical
    for key in ("time", "bed_center", "vehicle_positions", "vehicle_headings", "radii"):
        np.testing.assert_array_equal(vk[key], cpu[key], err_msg=key)
    # rock positions: equal to f32 round-off
    tol = _tolerance(cpu)
    err = float(np.max(np.abs(vk["positions"] - cpu["positions"])))
    assert err <= tol, f"positions differ by {err:.3g} m > {tol:.3g} m"


def test_render_same_on_cpu_and_vulkan(runs):
    """The renderer's own kernels (sky, splatted rocks in 64-bit z and colour buffers) on either backend draw
    the same frames (GGUI draws through Vulkan in both). The rocks they draw agree to f32 round-off, not to
    the bit (test_cpu_and_vulkan_agree: active stepping's fused kernel rounds a few rocks' positions a few
    ulps apart on the two backends), which can shift an edge of a rock by a fraction of a pixel: at most one
    level, in at most 0.1 % of the pixels (measured: 3 values of one pixel in 3 frames)."""
    import imageio.v3 as iio

    out = {arch: folder / "render" / "frames" for arch, (folder, _) in _finished(runs, "render").items()}
    names = sorted(p.name for p in out["cpu"].glob("frame_*.png"))
    assert len(names) == 3, names
    for name in names:
        cpu, vk = (iio.imread(out[a] / name) for a in ("cpu", "vulkan"))
        assert cpu.std() > 0  # not blank
        diff = np.abs(vk.astype(np.int16) - cpu.astype(np.int16))
        assert diff.max() <= 1, (name, int(diff.max()))
        assert np.count_nonzero(diff) <= 1e-3 * diff.size, (name, int(np.count_nonzero(diff)))


@pytest.mark.parametrize("real", ["f32", "f64"])
def test_world_groups_hold_one_element_type_and_fields_do_not_overlap(taichi_cpu, real):
    """Each ndarray group of a World holds elements of one type (engine/view.py GROUPS): no 64-bit value shares a
    buffer with 32-bit ones, where Vulkan could place it at 4 mod 8 and read and write it over its neighbour (as
    it did in the SNode trees the World had before). Each field lies inside its group, after the table its
    kernels read, apart from every other field; every field written with values of its own reads them back
    unchanged. Checked on the CPU, whose layout would hide an overlap, with every optional field allocated."""
    import taichi as ti

    from taichi_rocks.engine.view import GROUP_NAMES, GROUPS
    from taichi_rocks.engine.world import World

    w = World(101, getattr(ti, real), hash_table=1031, hash_entries=101, n_tires=2, substeps=2, ray_capacity=5,
              reorder=True, tiles=(3, 3), tile_size=0.5, store=(0.5, 4, 8, True), bodies=(2, 3), events=16,
              drawn=True, parallel_scan=True)
    np_real = np.float64 if real == "f64" else np.float32
    by_group = dict(zip(GROUP_NAMES, w.groups))
    scalar = {"real": getattr(ti, real), "i32": ti.i32, "f64": ti.f64, "i64": ti.i64}
    for g, arr in by_group.items():  # one element type per group, the World's precision for its reals
        kind, width = GROUPS[g]
        assert arr.dtype == scalar[kind] and getattr(arr, "n", 1) == width and len(arr.shape) == 1, g
    used: dict = {g: [] for g in GROUP_NAMES}  # per group: the element ranges taken (start, end, field)
    used["i1"].append((0, len(w.placement.head), "head"))
    used["r1"].append((0, len(w.placement.real_head), "real head"))
    fs = w.fields()
    for f in fs:
        g = next(g for g, arr in by_group.items() if arr is f.arr)
        kind, width = GROUPS[g]
        assert f.np_dtype == (np_real if kind == "real" else {"i32": np.int32, "f64": np.float64,
                                                                "i64": np.int64}[kind]), f.name
        assert f.width == width and (f.row == 0 or width == 1), f.name  # rows only of scalar groups
        start, count = f._elements(0, f.entries)
        used[g].append((start, start + count, f.name))
        assert 0 <= start and start + count <= f.arr.shape[0], f.name
    for g, spans in used.items():
        spans.sort()
        for (_, end, a), (start, _, b) in zip(spans, spans[1:]):
            assert end <= start, (g, a, b)
    rng = np.random.default_rng(7)
    values = {}
    for f in fs:  # values of each field's own: whole numbers from a range no other field draws from
        shape = f.shape + ((f.n,) if f.n > 1 else ())
        values[f.name] = (rng.integers(1, 1000, shape) + 1000 * len(values)).astype(f.np_dtype)
        f.from_numpy(values[f.name])
    w.launches[None] = 2 ** 40 + 3  # a 64-bit value, past 32 bits
    values["launches"] = np.array(2 ** 40 + 3, np.int64)
    for f in fs:
        got = f.to_numpy()
        assert got.dtype == f.np_dtype and got.tobytes() == values[f.name].tobytes(), f.name
    assert w.launches[None] == 2 ** 40 + 3 and np.asarray(w.pos[100]).shape == (3,)
