"""The command line as a user meets it: exit codes, one-line errors, outputs never clobbered or half-written,
reproducible across processes."""

import ctypes
import hashlib
import json
import os
import signal
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from cli_util import ROOT, cli, cli_here, refused, start_cli, start_held_writer, wait_for

BAD = sorted((ROOT / "tests" / "bad_scenes").glob("*.toml"))


def test_check_good_scenes(capsys):
    r = cli_here(capsys, "check", *sorted((ROOT / "scenes").glob("*.toml")))
    assert r.returncode == 0, r.stderr
    assert "passes per step" in r.stdout and "convoy" in r.stdout


def test_check_bad_scenes_one_line_each_exit_2(capsys):
    r = cli_here(capsys, "check", *BAD)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    for path in BAD:  # every file is reported, each line starts with the file
        assert any(line.startswith(str(path)) for line in lines), path
    for line in lines:
        assert line.startswith(str(ROOT / "tests" / "bad_scenes")), line


def test_check_takes_a_recorded_drive_and_refuses_a_broken_one_naming_the_file_and_line(capsys):
    good = ROOT / "examples" / "swerve.drive"
    r = cli_here(capsys, "check", good)
    assert r.returncode == 0 and r.stdout.strip() == f"drive {good}: 481 poses from t = 0 s to 8 s", r.stderr
    for name, where in (("times", ":6: t: times must increase, got 0.5 after 0.5"),
                        ("nan", ":4: heading: must be finite"), ("header", ":1: expected the header")):
        bad = ROOT / "tests" / "bad_scenes" / f"recorded_drive_{name}.drive"
        r = cli_here(capsys, "check", bad)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith(f"{bad}{where}"), r.stderr


def test_simulate_bad_scene_creates_nothing(taichi_cpu, capsys, tmp_path):
    out = tmp_path / "x.npz"
    r = cli_here(capsys, "simulate", BAD[0], "--out", out)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().startswith(str(BAD[0]))
    assert list(tmp_path.iterdir()) == []


def test_a_scene_too_big_for_the_machine_is_refused_by_simulate_in_one_line(taichi_cpu, capsys, tmp_path):
    """The engine's memory check (engine/layout.py) refuses it before allocating: exit 2, nothing written."""
    huge = ROOT / "tests" / "bad_scenes" / "too_many_rocks.toml"
    r = cli_here(capsys, "simulate", huge, "--out", tmp_path / "x.npz")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    [line] = r.stderr.strip().splitlines()
    assert line.startswith(f"{huge}: bed.rocks: needs about ") and "more than this machine has" in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["check", "simulate", "render"])
def test_deeply_nested_scene_is_bad_input_for_every_command(taichi_cpu, capsys, tmp_path, command):
    """5,000 levels of arrays once ended in a RecursionError (exit 1); it is bad input: one line with the place."""
    deep = ROOT / "tests" / "bad_scenes" / "deep_nesting.toml"
    out = tmp_path / "out"
    r = cli_here(capsys, command, deep, *([] if command == "check" else ["--out", out / "x.npz" if command == "simulate" else out]))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().splitlines() == [f"{deep}: line 2, column 37: arrays and inline tables nested deeper "
                                             "than 32 levels in the value of a"]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args", [["--frames", "0"], ["--frames", "-3"], ["--fps", "nan"], ["--arch", "tpu"]])
def test_usage_errors(taichi_cpu, capsys, tmp_path, args):
    r = cli_here(capsys, "simulate", ROOT / "scenes" / "minimal.toml", "--out", tmp_path / "x.npz", *args)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_missing_file_and_directory(capsys, tmp_path):
    for target in (tmp_path / "nope.toml", tmp_path):
        r = cli_here(capsys, "check", target)
        assert r.returncode == 2 and "Traceback" not in r.stderr
        assert r.stderr.startswith(str(target)) and "cannot read scene" in r.stderr


def test_schema_is_json_with_the_enums(capsys):
    r = cli_here(capsys, "schema")
    assert r.returncode == 0
    schema = json.loads(r.stdout)
    assert "rk4" in json.dumps(schema) and "quadratic" in json.dumps(schema)


def test_simulate_writes_reproducible_npz_and_refuses_to_overwrite(taichi_cpu, capsys, tmp_path):
    """``a`` from a process of its own, ``b`` and the rest in this one: the same bytes across processes."""
    scene = ROOT / "scenes" / "minimal.toml"
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    r = cli("simulate", scene, "--out", a, "--frames", "12")
    assert r.returncode == 0, r.stderr
    assert cli_here(capsys, "simulate", scene, "--out", b, "--frames", "12").returncode == 0
    from taichi_rocks import load_run

    da, db = np.load(a), np.load(b)
    assert load_run(a)["positions"].shape == (12, 2000, 3) and load_run(a)["positions"].dtype == np.float64
    assert da["vehicle_positions"].shape == (12, 1, 3) and list(da["vehicle_names"]) == ["car"]
    np.testing.assert_allclose(da["time"], np.arange(12) / 30.0)
    for k in da.files:
        np.testing.assert_array_equal(da[k], db[k])
    assert da["launches"].sum() > 0
    # the same bytes: stored members, no time stamps (the zip epoch), fixed permissions and order
    assert hashlib.sha256(a.read_bytes()).hexdigest() == hashlib.sha256(b.read_bytes()).hexdigest()
    with zipfile.ZipFile(a) as z:
        members = z.infolist()
    assert sorted(m.filename for m in members) == sorted(f"{k}.npy" for k in da.files)
    for m in members:
        assert m.date_time == (1980, 1, 1, 0, 0, 0) and m.compress_type == zipfile.ZIP_STORED, m
        assert m.external_attr >> 16 == 0o100644, m
    before = a.read_bytes()
    r = cli_here(capsys, "simulate", scene, "--out", a, "--frames", "3")
    assert r.returncode == 2 and "--overwrite" in r.stderr and "Traceback" not in r.stderr
    assert a.read_bytes() == before
    assert cli_here(capsys, "simulate", scene, "--out", a, "--frames", "3", "--overwrite").returncode == 0
    assert load_run(a)["positions"].shape[0] == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz", "b.npz"]  # no temporaries left


def _bytes_in(folder) -> int:
    """Bytes in the files under ``folder`` now (files may vanish while it looks)."""
    total = 0
    for q in folder.rglob("*"):
        try:
            total += q.stat().st_size if q.is_file() else 0
        except FileNotFoundError:
            pass
    return total


def _start(command, out, *extra, env=None):
    """``simulate`` into ``out/x.npz`` or ``render`` into ``out`` (160x96) of the minimal scene, in the background."""
    args = [command, ROOT / "scenes" / "minimal.toml", "--out"]
    args += [out / "x.npz"] if command == "simulate" else [out, "--resolution", "160x96"]
    return start_cli(*args, *extra, env=env)


def _interrupt(p) -> str:
    """Ctrl-C: the run ends as an interrupt (exit 130, one line saying so, no traceback). Returns stderr."""
    p.send_signal(signal.SIGINT)
    try:
        _, err = p.communicate(timeout=120)
    except subprocess.TimeoutExpired:  # the Ctrl-C was lost: do not leave a long run behind
        p.kill()
        raise
    assert p.returncode == 130, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and "interrupted" in err, err
    return err


def _entries(folder, test) -> bool:
    return folder.is_dir() and any(test(q) for q in folder.iterdir())


@pytest.mark.parametrize("command", ["simulate", "render"])
def test_ctrl_c_while_starting_is_a_clean_interrupt(tmp_path, tmp_path_factory, command):
    """Ctrl-C while the command is still importing its libraries or starting Taichi: exit 130, one line, no
    traceback, nothing written. (Without holding it back until the imports are done, a Ctrl-C inside SciPy's
    import ended in an ImportError, and one inside another import was swallowed: the run went on.) The
    process reports through TAICHI_ROCKS_STARTED that it holds Ctrl-C back, before it imports anything else."""
    started = tmp_path_factory.mktemp("started") / "started"
    p = _start(command, tmp_path / "out", "--frames", 100000, env={"TAICHI_ROCKS_STARTED": started})
    wait_for(started.exists, p, poll=0.001)
    assert "--resume" not in _interrupt(p)  # nothing was kept to resume from
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("until", ["folder made", "simulating"])
def test_ctrl_c_while_simulating_removes_the_folder_it_made(tmp_path, until):
    """Ctrl-C as soon as `out` exists, or while simulating (its memory-mapped temporaries exist and frames are
    being appended to them): no file and no `out` folder left, the folder around it (which existed) kept.
    (Right after `out` was made, a Ctrl-C once landed in NumPy's first import of mmap and was swallowed there:
    the CLI now imports such modules during start-up.)"""
    out = tmp_path / "out"
    p = _start("simulate", out, "--frames", 100000)
    if until == "folder made":
        wait_for(out.exists, p, poll=0.002)
    else:
        wait_for(lambda: _entries(out, lambda q: q.name.startswith(".x.npz.") and _entries(q, lambda f: True)), p)
        first = _bytes_in(out)
        wait_for(lambda: _bytes_in(out) > first, p, poll=0.05)
    _interrupt(p)
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_while_writing_the_npz_removes_the_folder_it_made(tmp_path, tmp_path_factory):
    """Ctrl-C while the .npz is being assembled (its .part temporary holds its first megabyte; the writer
    waits there, tests/held_writer.py, so the Ctrl-C lands inside the write on any machine): nothing left."""
    out = tmp_path / "out"
    marker = tmp_path_factory.mktemp("held") / "writing"
    p = start_held_writer(marker, "simulate", ROOT / "scenes" / "minimal.toml", "--out", out / "x.npz",
                          "--frames", 60, "--layout", "full")
    wait_for(marker.exists, p, poll=0.05)
    assert _entries(out, lambda q: q.name.endswith(".part"))  # interrupted inside the write
    _interrupt(p)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("until", ["frames", ".resume/render.json"])
def test_ctrl_c_before_the_first_frame_removes_the_render_folder(tmp_path, until):
    """Ctrl-C as soon as the render has made its folders (`out/frames`), or once it has noted what it renders
    (`out/.resume/render.json`) and draws its first frame: nothing to resume from, so no folder left, and the
    message does not suggest --resume."""
    out = tmp_path / "out"
    p = _start("render", out, "--frames", 100000)
    wait_for((out / until).exists, p, poll=0.002)
    assert "--resume" not in _interrupt(p)  # the message suggests it only when frames were kept
    assert list(tmp_path.iterdir()) == [], sorted(str(q) for q in tmp_path.rglob("*"))


# Ctrl-C and kill -9 after a render has finished frames, and its --resume: tests/render/test_render.py
# ("interrupted CLI renders"), which also compares the resumed render with an uninterrupted one.


def test_new_folders_removes_on_failure_only_the_empty_folders_it_made(tmp_path):
    from taichi_rocks.output.atomic import new_folders

    old = tmp_path / "old"
    old.mkdir()
    with pytest.raises(KeyboardInterrupt):
        with new_folders(old / "a" / "b", tmp_path / "c") as made:
            assert made == [old / "a", old / "a" / "b", tmp_path / "c"]
            assert all(d.is_dir() for d in made)
            raise KeyboardInterrupt
    assert os.listdir(tmp_path) == ["old"] and os.listdir(old) == []  # deepest first, what existed stays
    with pytest.raises(ValueError):
        with new_folders(old / "a" / "b" / "c", tmp_path / "d" / "e"):
            (old / "a" / "b" / "kept").write_bytes(b"finished")
            raise ValueError("failed")
    assert sorted(os.listdir(tmp_path)) == ["old"]
    assert os.listdir(old / "a" / "b") == ["kept"]  # holding finished output: kept, with the folders above
    with new_folders(tmp_path / "f" / "g") as made:  # success keeps them all
        pass
    assert made == [tmp_path / "f", tmp_path / "f" / "g"] and (tmp_path / "f" / "g").is_dir()
    (tmp_path / "file").write_bytes(b"")
    with pytest.raises(FileExistsError):  # a file in the way
        with new_folders(tmp_path / "h", tmp_path / "file" / "x"):
            pass
    assert sorted(os.listdir(tmp_path)) == ["f", "file", "old"]


def test_killed_simulate_leaves_no_final_file_and_the_next_run_cleans_up(taichi_cpu, capsys, tmp_path,
                                                                          tmp_path_factory):
    """kill -9 while the .npz is being assembled (its .part temporary holds its first megabyte): nothing appears
    under the final name; the next run (in this process: the killed one is the process that matters) removes
    the dead writer's temporaries and writes a complete file."""
    out = tmp_path / "k.npz"
    marker = tmp_path_factory.mktemp("held") / "writing"
    p = start_held_writer(marker, "simulate", ROOT / "scenes" / "minimal.toml", "--out", out, "--frames", 60,
                          "--layout", "full")
    wait_for(marker.exists, p, poll=0.05)  # the writer holds inside the write (tests/held_writer.py)
    p.kill()
    p.communicate(timeout=60)
    assert p.returncode == -signal.SIGKILL
    left = sorted(q.name for q in tmp_path.iterdir())
    assert not out.exists()
    assert any(name.endswith(".part") for name in left), left  # the half-written temporary stays, hidden
    assert all(name.startswith(f".k.npz.{p.pid}.") for name in left), left
    # a writer that is still running keeps its temporaries: only dead ones are removed (the live writer is
    # another process, this one's parent, not the process that cleans up)
    live = tmp_path / f".k.npz.{os.getppid()}.abcd1234.part"
    live.write_bytes(b"x")
    r = cli_here(capsys, "simulate", ROOT / "scenes" / "minimal.toml", "--out", out, "--frames", "3", "--overwrite")
    assert r.returncode == 0, r.stderr
    assert sorted(q.name for q in tmp_path.iterdir()) == sorted(["k.npz", live.name])
    from taichi_rocks import load_run

    assert load_run(out)["positions"].shape == (3, 2000, 3)


def _cuda_device_present() -> bool:
    """Whether the NVIDIA driver reports a CUDA device, asked directly (not through Taichi, whose answer is
    what the test checks)."""
    try:
        lib = ctypes.CDLL("libcuda.so.1")
    except OSError:
        return False
    count = ctypes.c_int(0)
    return lib.cuInit(0) == 0 and lib.cuDeviceGetCount(ctypes.byref(count)) == 0 and count.value > 0


def test_gpu_runs_on_cuda_or_falls_back_to_cpu_with_one_warning(tmp_path):
    """``--arch gpu``: CUDA where the driver has a device (no warning), else the CPU with one warning line."""
    r = cli("simulate", ROOT / "scenes" / "minimal.toml", "--out", tmp_path / "g.npz", "--frames", "2", "--arch", "gpu")
    assert r.returncode == 0, r.stderr
    warnings = [line for line in r.stderr.splitlines() if "warning" in line.lower()]
    if _cuda_device_present():
        assert warnings == [], r.stderr
    else:
        assert len(warnings) == 1 and "CPU" in warnings[0], r.stderr
    assert r.stdout.startswith("wrote ")  # nothing else on stdout (no Taichi banner)
    from taichi_rocks import load_run

    assert load_run(tmp_path / "g.npz")["positions"].shape == (2, 2000, 3)


F64_SCENE = """name = "f64"
duration = 0.2
[bed]
rocks = 100
radius = 4.0
[sim]
{sim}
[[vehicle]]
name = "car"
path = {{ points = [[0.0, 0.0], [40.0, 0.0]], speed = 10.0 }}
"""


def test_f64_on_vulkan_is_refused_before_anything(tmp_path):
    """Taichi's Vulkan backend cannot compile the f64 kernels (it failed after start-up with exit 1): the
    command refuses the scene up front, one line naming the file and the key, nothing written."""
    scene = tmp_path / "f64.toml"
    scene.write_text(F64_SCENE.format(sim='precision = "f64"'))
    out = tmp_path / "out"
    r = cli("simulate", scene, "--arch", "vulkan", "--out", out / "x.npz")
    line = refused(r, f"{scene}: sim.precision:", '"f64"', "--arch vulkan")
    assert line.startswith(str(scene)) and not out.exists()


def _main(capsys, *args) -> tuple:
    """The command line in this process (Taichi is already started on the CPU: a start-up asking for another
    arch keeps it); (exit status, stderr lines)."""
    from taichi_rocks.cli import main

    status = main([str(a) for a in args])
    return status, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("command", ["render", "export", "view"])
@pytest.mark.parametrize("sim", ['precision = "f64"', 'accuracy = "reference"'])
def test_f64_on_vulkan_is_refused_by_every_command(taichi_cpu, tmp_path, capsys, command, sim):
    scene = tmp_path / "f64.toml"
    scene.write_text(F64_SCENE.format(sim=sim))
    out = ["--out", tmp_path / "out" / ("x.usdc" if command == "export" else "")] if command != "view" else []
    status, err = _main(capsys, command, scene, "--arch", "vulkan", *out)
    assert status == 2 and len(err) == 1 and err[0].startswith(f"{scene}: sim.precision: \"f64\""), err
    assert ("reference" in err[0]) == ("reference" in sim)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f64.toml"]


@pytest.mark.parametrize("command", ["simulate", "render"])
def test_aabb_insertion_on_vulkan_is_refused(taichi_cpu, tmp_path, capsys, command):
    """Vulkan loses some of aabb insertion's atomics (config/arches.py): the scene is refused up front, one line
    naming the file and sim.hash.insert; centre insertion and the CPU are not refused."""
    from taichi_rocks.config.arches import arch_problem
    from taichi_rocks.config.scene import load_scene

    scene = tmp_path / "aabb.toml"
    scene.write_text(F64_SCENE.format(sim='[sim.hash]\ninsert = "aabb"'))
    out = ["--out", tmp_path / "out" / ("x.npz" if command == "simulate" else "")]
    status, err = _main(capsys, command, scene, "--arch", "vulkan", *out)
    assert status == 2 and len(err) == 1 and err[0].startswith(f'{scene}: sim.hash.insert: "aabb"'), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["aabb.toml"]
    assert arch_problem(load_scene(scene), "cpu") is None
    scene.write_text(F64_SCENE.format(sim='[sim.hash]\ninsert = "center"'))
    assert arch_problem(load_scene(scene), "vulkan") is None


@pytest.fixture
def no_study(monkeypatch):
    """A study that starts fails the test at once (the refusals below come before any)."""
    from taichi_rocks.bench import activity, launch, run

    def ran(*args, **kwargs):
        raise AssertionError("the study ran")

    for module, name in ((run, "_run_bench"), (launch, "_launch_study"), (activity, "activity_section")):
        monkeypatch.setattr(module, name, ran)


def test_bench_on_vulkan_is_refused_unless_one_f32_study(taichi_cpu, no_study, tmp_path, capsys):
    status, err = _main(capsys, "bench", "--arch", "vulkan", "--out", tmp_path / "b")
    assert status == 2 and len(err) == 1 and "sim.precision" in err[0] and "--only" in err[0], err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("only, earlier", [(None, "report.md"), (None, "accuracy_precision.png"),
                                           ("launch", "launch_study.json"), ("activity", "activity.png")])
def test_bench_refuses_a_folder_holding_results(taichi_cpu, no_study, tmp_path, capsys, only, earlier):
    """Like every other output: an earlier run's results are replaced only with --overwrite (refused before
    anything runs: exit 2, one line, the folder untouched)."""
    (tmp_path / earlier).write_text("earlier")
    status, err = _main(capsys, "bench", "--out", tmp_path, *(["--only", only] if only else []))
    assert status == 2 and len(err) == 1 and str(tmp_path) in err[0] and earlier in err[0], err
    assert "--overwrite" in err[0]
    assert [p.name for p in tmp_path.iterdir()] == [earlier] and (tmp_path / earlier).read_text() == "earlier"
    (tmp_path / "file").write_text("")
    status, err = _main(capsys, "bench", "--out", tmp_path / "file", "--overwrite")
    assert status == 2 and len(err) == 1 and "is a file" in err[0], err


def test_a_gif_render_imports_nothing_after_start_up(tmp_path):
    """What a GIF render imports, it imports at start-up, while Ctrl-C is held back (a Ctrl-C inside a late
    first import can be swallowed): Pillow and its format plugins, which imageio loads when the GIF is
    assembled. Start-up here skips Taichi (this is about imports), then a FrameWriter writes a 2-frame GIF."""
    code = f"""
import sys
import numpy as np
import taichi_rocks.engine.runtime as runtime
runtime.init_taichi = lambda arch="cpu", **kw: "cpu"
from taichi_rocks import cli
cli._start(["render", {str(ROOT / "scenes" / "minimal.toml")!r}, "--format", "gif", "--out", {str(tmp_path)!r}])
from taichi_rocks.output.video import FrameWriter
before = set(sys.modules)
w = FrameWriter({str(tmp_path)!r}, "g", 10.0, "gif")
for k in range(2):
    w.write(np.full((32, 48, 3), 60 * k, np.uint8))
print(w.close(), sorted(set(sys.modules) - before))
"""
    r = subprocess.run([sys.executable, "-c", code], env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    video, late = r.stdout.strip().split(" ", 1)
    assert video.endswith("g.gif") and (tmp_path / "g.gif").read_bytes()[:6] == b"GIF89a"
    assert late == "[]", late
