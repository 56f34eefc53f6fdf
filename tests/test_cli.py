"""The command line as a user meets it: exit codes, one-line errors, outputs never clobbered or half-written,
reproducible across processes."""

import json
import os
import signal
import time

import numpy as np
import pytest

from cli_util import ROOT, cli, start_cli, wait_for

BAD = sorted((ROOT / "tests" / "bad_scenes").glob("*.toml"))


def test_check_good_scenes():
    r = cli("check", *sorted((ROOT / "scenes").glob("*.toml")))
    assert r.returncode == 0, r.stderr
    assert "passes per step" in r.stdout and "convoy" in r.stdout


def test_check_bad_scenes_one_line_each_exit_2():
    r = cli("check", *BAD)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    for path in BAD:  # every file is reported, each line starts with the file
        assert any(line.startswith(str(path)) for line in lines), path
    for line in lines:
        assert line.startswith(str(ROOT / "tests" / "bad_scenes")), line


def test_simulate_bad_scene_creates_nothing(tmp_path):
    out = tmp_path / "x.npz"
    r = cli("simulate", BAD[0], "--out", out)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().startswith(str(BAD[0]))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["check", "simulate", "render"])
def test_deeply_nested_scene_is_bad_input_for_every_command(tmp_path, command):
    """5,000 levels of arrays once ended in a RecursionError (exit 1); it is bad input: one line with the place."""
    deep = ROOT / "tests" / "bad_scenes" / "deep_nesting.toml"
    out = tmp_path / "out"
    r = cli(command, deep, *([] if command == "check" else ["--out", out / "x.npz" if command == "simulate" else out]))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().splitlines() == [f"{deep}: line 2, column 37: arrays and inline tables nested deeper "
                                             "than 32 levels in the value of a"]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args", [["--frames", "0"], ["--frames", "-3"], ["--fps", "nan"], ["--arch", "tpu"]])
def test_usage_errors(tmp_path, args):
    r = cli("simulate", ROOT / "scenes" / "minimal.toml", "--out", tmp_path / "x.npz", *args)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert list(tmp_path.iterdir()) == []


def test_missing_file_and_directory(tmp_path):
    for target in (tmp_path / "nope.toml", tmp_path):
        r = cli("check", target)
        assert r.returncode == 2 and "Traceback" not in r.stderr
        assert r.stderr.startswith(str(target)) and "cannot read scene" in r.stderr


def test_schema_is_json_with_the_enums():
    r = cli("schema")
    assert r.returncode == 0
    schema = json.loads(r.stdout)
    assert "rk4" in json.dumps(schema) and "quadratic" in json.dumps(schema)


def test_simulate_writes_reproducible_npz_and_refuses_to_overwrite(tmp_path):
    scene = ROOT / "scenes" / "minimal.toml"
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    r = cli("simulate", scene, "--out", a, "--frames", "12")
    assert r.returncode == 0, r.stderr
    assert cli("simulate", scene, "--out", b, "--frames", "12").returncode == 0
    da, db = np.load(a), np.load(b)
    assert da["positions"].shape == (12, 2000, 3) and da["positions"].dtype == np.float64
    assert da["vehicle_positions"].shape == (12, 1, 3) and list(da["vehicle_names"]) == ["car"]
    np.testing.assert_allclose(da["time"], np.arange(12) / 30.0)
    for k in da.files:
        np.testing.assert_array_equal(da[k], db[k])
    assert da["launches"].sum() > 0
    before = a.read_bytes()
    r = cli("simulate", scene, "--out", a, "--frames", "3")
    assert r.returncode == 2 and "--overwrite" in r.stderr and "Traceback" not in r.stderr
    assert a.read_bytes() == before
    assert cli("simulate", scene, "--out", a, "--frames", "3", "--overwrite").returncode == 0
    assert np.load(a)["positions"].shape[0] == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.npz", "b.npz"]  # no temporaries left


def test_interrupted_simulate_leaves_no_file(tmp_path):
    out = tmp_path / "big.npz"
    p = start_cli("simulate", ROOT / "scenes" / "minimal.toml", "--out", out, "--frames", "100000")
    wait_for(lambda: any(tmp_path.iterdir()), p, poll=0.2)  # it is writing its temporaries
    time.sleep(1.0)
    p.send_signal(signal.SIGINT)
    err = p.communicate(timeout=60)[1]
    assert p.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["simulate", "render"])
@pytest.mark.parametrize("delay", [0.2, 0.6, 1.0])
def test_ctrl_c_during_start_up_is_a_clean_interrupt(tmp_path, command, delay):
    """Ctrl-C while the command is still importing its libraries or starting Taichi: exit 130, one line, no
    traceback, nothing written. (Without holding it back until the imports are done, a Ctrl-C inside SciPy's
    import ended in an ImportError, and one inside another import was swallowed: the run went on.)"""
    out = tmp_path / "out"
    args = [command, ROOT / "scenes" / "minimal.toml", "--frames", "100000", "--out"]
    args += [out / "x.npz"] if command == "simulate" else [out, "--resolution", "160x96"]
    p = start_cli(*args)
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and "interrupted" in err, err
    assert list(tmp_path.iterdir()) == []


def test_killed_simulate_leaves_no_final_file_and_the_next_run_cleans_up(tmp_path):
    """kill -9 while the .npz is being assembled (its temporary exists, ~110 MB): nothing appears under the
    final name; the next run removes the dead writer's temporaries and writes a complete file."""
    out = tmp_path / "k.npz"
    p = start_cli("simulate", ROOT / "scenes" / "minimal.toml", "--out", out, "--frames", "1500", "--fps", "250")
    wait_for(lambda: any(q.name.endswith(".part") for q in tmp_path.iterdir()), p, poll=0.002)
    p.kill()
    p.communicate(timeout=60)
    assert p.returncode == -signal.SIGKILL
    left = sorted(q.name for q in tmp_path.iterdir())
    if out.exists():  # the kill came after the rename (not seen here): then the file must be whole
        assert np.load(out)["positions"].shape == (1500, 2000, 3)
    else:
        assert left and all(name.startswith(f".k.npz.{p.pid}.") for name in left), left
    # a writer that is still running keeps its temporaries: only dead ones are removed
    live = tmp_path / f".k.npz.{os.getpid()}.abcd1234.part"
    live.write_bytes(b"x")
    r = cli("simulate", ROOT / "scenes" / "minimal.toml", "--out", out, "--frames", "3", "--overwrite")
    assert r.returncode == 0, r.stderr
    assert sorted(q.name for q in tmp_path.iterdir()) == sorted(["k.npz", live.name])
    assert np.load(out)["positions"].shape == (3, 2000, 3)


def test_gpu_falls_back_to_cpu_with_one_warning(tmp_path):
    r = cli("simulate", ROOT / "scenes" / "minimal.toml", "--out", tmp_path / "g.npz", "--frames", "2", "--arch", "gpu")
    assert r.returncode == 0, r.stderr
    warnings = [line for line in r.stderr.splitlines() if "warning" in line.lower()]
    assert len(warnings) == 1 and "CPU" in warnings[0]
    assert r.stdout.startswith("wrote ")  # nothing else on stdout (no Taichi banner)
