"""`taichi-rocks sweep` on both backends (app/sweep/): the same rows from local processes and a real local Ray
cluster (digests included), a worker killed with SIGKILL mid-run on each (every row exactly once, the killed
run retried), Ctrl-C then --resume, a run that fails (a failed row, exit status 1, the next run in a new
worker), the render metric, and bad sweep files (one line, exit status 2, nothing written).

The runs are minimal.toml with 400 rocks on a 4 m bed (written next to each sweep file as its base scene) for
0.4 s; a worker writes runs/<id>/worker.json (its pid) when it starts a run, which is how the kill tests find
the process to kill (the local one runs the command in the test's process, its workers being processes of
their own all the same, and kills from a thread; the Ray one runs it in a process of its own). The Ray cluster
is started with ``ray start --head`` on 127.0.0.1 (2 CPUs, a free port, its session files in a temporary
folder) and its process group is killed at the end, whatever the tests did.

Every sweep's workers have the same number of Taichi threads (those the reference gets by default) and every
run but the failing one has the same bed: Taichi's offline kernel cache is keyed by the compile configuration,
the thread count among it, and by the fields' shapes, and a worker that ends normally writes it. So the failing
run's sweep, first in the file, compiles the kernels, and every later worker loads them."""

import csv
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from cli_util import cli, cli_here, reaped, refused, start_cli, start_held_sweep, wait_for
from taichi_rocks.app.sweep.metrics import METRICS, state_digest
from taichi_rocks.app.sweep.sweep import run_sweep
from taichi_rocks.cli import main
from taichi_rocks.config.sweep import SweepError, load_sweep, sweep_runs
from taichi_rocks.runner.tasks import usable_cores

ROOT = Path(__file__).resolve().parents[2]
MINIMAL = ROOT / "scenes" / "minimal.toml"
# The bed is the base scene's (_base_scene), not single-valued grid keys: the driver draws a figure per metric
# and grid key (~0.5 s of CPU each), and the speed's are the ones the reference checks.
SWEEP = """scene = "base.toml"
seeds = [1, 2]
duration = 0.4
[grid]
"vehicle[0].path.speed" = [8.0, 12.0]
[measure]
metrics = ["launch", "timing", "digest"]
"""
RUNS = 4
# what depends on the machine or the worker, not on the run
VARYING = {"attempts", "seconds", "build_s", "first_step_s", "ms_per_step"}
# Taichi threads per worker: those the reference gets by default for its 2 workers, passed to every other sweep
# (the offline cache's key, module docstring)
THREADS = max(1, usable_cores() // 2)


def _base_scene() -> str:
    """minimal.toml with 400 rocks on a 4 m bed."""
    text = MINIMAL.read_text()
    assert "\nradius = 8.0\n" in text and "\nrocks = 2000\n" in text, "minimal.toml changed: update _base_scene"
    return text.replace("\nradius = 8.0\n", "\nradius = 4.0\n").replace("\nrocks = 2000\n", "\nrocks = 400\n")


BASE = _base_scene()


def _sweep_file(folder: Path, text: str = SWEEP, name: str = "sweep.toml") -> Path:
    """The sweep file, with its base scene (base.toml) beside it."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base.toml").write_text(BASE)
    p = folder / name
    p.write_text(text)
    return p


def _rows(out: Path) -> list[dict]:
    with open(out / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


def _same(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in VARYING} for r in rows]


def test_a_failed_run_is_a_failed_row(tmp_path, capsys):
    """A bed too large to allocate passes validation and fails in the engine: a failed row with the error's
    line, the sweep goes on (the next run in a new worker: the failed build leaves Taichi unusable in its
    process), one line on stderr, exit status 1."""
    # 4 m: the bed of every other run (module docstring). First in the file: its first worker ends normally
    # (after the failure), so it is the one that compiles the kernels the others load.
    sweep = _sweep_file(tmp_path, SWEEP.replace('"vehicle[0].path.speed" = [8.0, 12.0]',
                                                '"bed.radius" = [4.0, 1e12, 4.0]')
                        .replace("seeds = [1, 2]", "seeds = [1]").replace('"launch", "timing", ', ""))
    status = main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--workers", "1", "--threads", str(THREADS)])
    out, err = capsys.readouterr()
    assert status == 1, err
    rows = _rows(tmp_path / "out")
    assert [x["status"] for x in rows] == ["ok", "failed", "ok"]
    assert rows[1]["error"] and rows[1]["digest"] == "" and "\n" not in rows[1]["error"]
    assert len([line for line in err.splitlines() if "run r0001" in line and "failed" in line]) == 1
    assert "1 failed (r0001)" in out
    assert rows[2]["digest"] == rows[0]["digest"]  # the new worker computes what the first one did


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The sweep run once through the Python API, locally on 2 workers: the rows every other run must give."""
    folder = tmp_path_factory.mktemp("sweep_ref")
    table = run_sweep(_sweep_file(folder), folder / "out", workers=2, progress=False)  # default threads: THREADS
    return folder / "out", table


@pytest.fixture(scope="module")
def ray_cluster():
    """A real local Ray cluster: 2 CPUs on 127.0.0.1, with a token of its own (Ray turns token authentication on
    for `ray start` once ~/.ray/auth_token exists, which a local ray.init() writes); its whole process group is
    killed at teardown. Yields (address, the environment a client needs)."""
    ray_bin = Path(sys.executable).parent / "ray"
    assert ray_bin.is_file(), "the ray extra is missing: pip install -e '.[ray]' (tools/setup.sh installs it)"
    auth = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
    ports = []
    for _ in range(2):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            ports.append(s.getsockname()[1])
    temp = tempfile.mkdtemp(prefix="trray", dir="/tmp")  # short: Ray's socket paths live under it
    proc = subprocess.Popen([str(ray_bin), "start", "--head", "--node-ip-address", "127.0.0.1", "--port",
                             str(ports[0]), "--num-cpus", "2", "--include-dashboard", "false",
                             "--dashboard-agent-listen-port", str(ports[1]), "--temp-dir", temp,
                             "--disable-usage-stats"], start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, env=dict(os.environ, **auth))
    try:
        out, _ = proc.communicate(timeout=120)
        assert proc.returncode == 0, out
        yield f"127.0.0.1:{ports[0]}", auth
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)  # the daemons `ray start` left in its process group
        except ProcessLookupError:
            pass
        shutil.rmtree(temp, ignore_errors=True)


def test_the_reference_sweep(reference):
    """Every run once, in order, ok, with the metrics' columns; the Python API returns the same table."""
    out, table = reference
    rows = _rows(out)
    assert [r["id"] for r in rows] == [f"r{i:04d}" for i in range(RUNS)] == [t["id"] for t in table]
    assert all(r["status"] == "ok" and r["attempts"] == "1" for r in rows)
    assert [(float(r["vehicle[0].path.speed"]), int(r["seed"])) for r in rows] == [
        (v, s) for v in (8.0, 12.0) for s in (1, 2)]
    assert len({r["digest"] for r in rows}) == RUNS  # every speed and seed changes the final state
    assert all(int(r["launches"]) > 0 and float(r["ms_per_step"]) > 0 for r in rows)
    assert [t["digest"] for t in table] == [r["digest"] for r in rows]
    meta = json.loads((out / "sweep.json").read_text())
    assert meta["runs"] == RUNS and meta["failed"] == 0 and meta["workers"] == 2 and meta["threads"] == THREADS
    assert "vehicle[0].path.speed" in meta["sweep_text"] and meta["machine"]["usable_cores"] >= 1
    plots = sorted(p.name for p in (out / "plots").glob("*.png"))
    assert "launch_vs_vehicle_0_.path.speed.png" in plots and "timing_vs_vehicle_0_.path.speed.png" in plots
    assert "launch_bands.png" in plots
    assert all((out / "plots" / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in plots)


def test_the_digest_is_the_final_state(reference, taichi_cpu):
    """The digest column is state_digest of the final state of the run's scene simulated here."""
    from taichi_rocks.config.scene import load_scene, scene_with
    from taichi_rocks.engine.simulation import Simulation

    out, table = reference
    row = table[3]
    scene = scene_with(load_scene(MINIMAL), {"bed.rocks": 400, "bed.radius": 4.0,
                                             "vehicle[0].path.speed": row["vehicle[0].path.speed"],
                                             "duration": 0.4, "seed": row["seed"]})
    sim = Simulation(scene)
    sim.step(100)  # 0.4 s at dt 0.004
    assert state_digest(sim.state()) == row["digest"]


def _first_started(out: Path):
    """The worker.json of the first run a worker has started, or None."""
    found = sorted((out / "runs").glob("*/worker.json")) if (out / "runs").is_dir() else []
    return json.loads(found[0].read_text()) if found else None


def _kill_first_worker(proc, out: Path) -> str:
    """Wait for the first run a worker starts (its worker.json), SIGKILL that worker; the run's id."""
    wait_for(lambda: _first_started(out) is not None, proc)
    info = _first_started(out)
    os.kill(info["pid"], signal.SIGKILL)
    return info["run"]


def _sweep_here_killing_first_worker(capsys, args, out: Path):
    """``taichi-rocks sweep ARGS`` in this process while a thread SIGKILLs the worker of the first run started
    (its workers are processes of their own all the same); (the run's id, the command's result)."""
    done, killed = threading.Event(), []

    def kill():
        while not done.is_set():
            info = _first_started(out)
            if info:
                os.kill(info["pid"], signal.SIGKILL)
                killed.append(info["run"])
                return
            time.sleep(0.01)

    killer = threading.Thread(target=kill, daemon=True)
    killer.start()
    try:
        r = cli_here(capsys, *args)
    finally:
        done.set()
        killer.join()
    assert killed, f"the sweep ended before a worker was killed: {r.stderr}"
    return killed[0], r


@pytest.mark.parametrize("backend", ["local", "ray"])
def test_a_killed_worker_has_its_run_retried(backend, reference, request, tmp_path, capsys):
    """kill -9 of the worker (local) or actor (ray, joining the running cluster with --address) running a run:
    the run is run again on another worker (the one started in its place); every row exactly once, and the rows
    (digests included) are the local reference's: on Ray this is also the test that both backends give the same
    rows."""
    out = tmp_path / "out"
    args = ("sweep", _sweep_file(tmp_path), "--out", out, "--backend", backend, "--workers", "1",
            "--threads", THREADS)
    if backend == "local":
        killed, r = _sweep_here_killing_first_worker(capsys, args, out)
        status, err = r.returncode, r.stderr
    else:  # the Ray driver in a process of its own: ray.init here would leave Ray's threads in the test process
        address, env = request.getfixturevalue("ray_cluster")
        proc = start_cli(*args, "--address", address, env=env)
        killed = _kill_first_worker(proc, out)
        _, err = proc.communicate(timeout=300)
        status = proc.returncode
    assert status == 0, err
    rows = _rows(out)
    assert [r["id"] for r in rows] == [f"r{i:04d}" for i in range(RUNS)]
    assert {r["id"]: r["attempts"] for r in rows}[killed] == "2"
    assert _same(rows) == _same(_rows(reference[0]))
    assert json.loads((out / "sweep.json").read_text())["backend"] == backend


def test_ctrl_c_then_resume(reference, tmp_path, capsys):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) after the first finished run (the
    driver holds there: tests/held_sweep.py, so the others cannot finish first on a fast machine): exit 130,
    that row kept; resuming runs only the others and gives the reference's rows."""
    out, marker = tmp_path / "out", tmp_path / "first_row"
    sweep = _sweep_file(tmp_path)
    with reaped(start_held_sweep("row", marker, sweep, "--out", out, "--workers", "1", "--threads", THREADS,
                                 new_session=True)) as proc:
        wait_for(marker.exists, proc)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "interrupted" in err.strip().splitlines()[-1]
    assert err.splitlines()[0].startswith("sweep: 4 runs of up to 100 steps: at least "), err  # said up front
    kept = _rows(out)
    assert len(kept) == 1
    assert main(["sweep", str(sweep), "--out", str(out)]) == 2  # neither --resume nor --overwrite
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--resume" in err[0] and "--overwrite" in err[0], err
    assert _rows(out) == kept
    table = run_sweep(sweep, out, resume=True, workers=1, threads=THREADS, progress=False)  # the API resumes alike
    assert [t["status"] for t in table] == ["ok"] * RUNS
    rows = _rows(out)
    assert _same(rows) == _same(_rows(reference[0]))
    assert [r["seconds"] for r in rows[:len(kept)]] == [k["seconds"] for k in kept]  # not run again


def test_the_render_metric_writes_a_video(tmp_path):
    """metrics = ["render"]: a video per run in runs/<id>/render/, named in its row."""
    text = SWEEP.replace("seeds = [1, 2]", "seeds = [1]").replace("duration = 0.4", "duration = 0.2").replace(
        '"vehicle[0].path.speed" = [8.0, 12.0]', '"render.resolution" = [[160, 96]]').replace(
        '["launch", "timing", "digest"]', '["render"]')
    table = run_sweep(_sweep_file(tmp_path, text), tmp_path / "out", workers=1, threads=THREADS, progress=False)
    assert [t["status"] for t in table] == ["ok"], table
    video = tmp_path / "out" / table[0]["video"]
    assert video.is_file() and video.stat().st_size > 1000 and table[0]["render_frames"] == 6


# ------------------------------------------------------------------------------------------------ bad files
BAD = {
    "bad_key": ('"launch.gripp" = [1e5]', 'grid."launch.gripp" = 100000', 'unknown key "gripp"'),
    "bad_value": ('"launch.grip" = [1e5, -1.0]', 'grid."launch.grip" = -1', "must be >= 0"),
    "bad_type": ('"world.wetness" = ["wet"]', 'grid."world.wetness" = "wet"', "expected a number"),
    "empty_grid": (None, "grid: expected at least one key", ""),
    "empty_values": ('"launch.grip" = []', 'grid."launch.grip": expected at least one value', ""),
    "no_scene": ("", "scene: no such scene file", "nowhere.toml"),
    "bad_metric": ('"launch.grip" = [1e5]', 'measure.metrics: unknown metric "lanuch"', 'did you mean "launch"'),
}


def _bad_text(case: str) -> str:
    grid, _, _ = BAD[case]
    text = f'scene = "{MINIMAL}"\n[grid]\n{grid or ""}\n'
    if case == "no_scene":
        text = 'scene = "nowhere.toml"\n[grid]\n"launch.grip" = [1e5]\n'
    if case == "bad_metric":
        text += '[measure]\nmetrics = ["lanuch"]\n'
    return text


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_sweep_files(case, tmp_path, capsys):
    """One line naming the file, the key and the value; exit status 2; no output folder."""
    sweep = _sweep_file(tmp_path, _bad_text(case), f"{case}.toml")
    status = main(["sweep", str(sweep), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1, err
    _, where, what = BAD[case]
    assert err[0].startswith(f"{sweep}: ") and where in err[0] and what in err[0], err[0]
    assert not (tmp_path / "out").exists()


def test_a_byte_order_mark_is_read_as_in_scene_files(tmp_path):
    """A sweep file saved with a UTF-8 byte-order mark reads as scene files do (it was refused); a seed past
    int64 is refused naming seeds."""
    from taichi_rocks.config import scene, sweep

    path = _sweep_file(tmp_path, "\ufeff" + SWEEP)
    assert load_sweep(path, METRICS)[0].seeds == (1, 2)
    assert sweep._show is scene._show  # one way to show a value in both kinds of file
    big = _sweep_file(tmp_path, SWEEP.replace("seeds = [1, 2]", "seeds = [1, 18446744073709551616]"), "big.toml")
    with pytest.raises(SweepError, match=r"seeds\[1\]: .*9223372036854775807"):
        load_sweep(big, METRICS)


def test_nothing_is_written_before_every_check_passed(tmp_path, capsys):
    """--workers and --threads past the cores: refused, nothing written (sweep.json was, and the corrected
    command was then refused as holding a sweep's results); --overwrite removes nothing when refused."""
    sweep = _sweep_file(tmp_path / "s")
    out = tmp_path / "out"
    too_many = str(usable_cores() + 1)
    assert main(["sweep", str(sweep), "--out", str(out), "--workers", "1", "--threads", too_many]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "threads is more than" in err[0], err
    assert not out.exists()
    (out / "runs").mkdir(parents=True)
    (out / "sweep.json").write_text("{}")
    assert main(["sweep", str(sweep), "--out", str(out), "--workers", "1", "--threads", too_many,
                 "--overwrite"]) == 2
    assert sorted(p.name for p in out.iterdir()) == ["runs", "sweep.json"]


def _big_sweep(tmp_path) -> Path:
    """100,000 runs: 100 x 100 grid values x 10 seeds."""
    grips = ", ".join(f"{1e5 + 1000.0 * i}" for i in range(100))
    speeds = ", ".join(f"{1.0 + 0.1 * i:.1f}" for i in range(100))
    return _sweep_file(tmp_path, f'scene = "base.toml"\nseeds = [{", ".join(map(str, range(1, 11)))}]\n[grid]\n'
                                 f'"launch.grip" = [{grips}]\n"vehicle[0].path.speed" = [{speeds}]\n', "big.toml")


def test_a_sweep_of_too_many_runs_is_refused_without_yes(tmp_path, capsys):
    """100,000 runs started without a word (after 95-150 s of validation): refused at once with the count and the
    estimate, naming --yes; nothing written."""
    out = tmp_path / "out"
    assert main(["sweep", str(_big_sweep(tmp_path)), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "100000 runs of up to 500 steps" in err[0] and "--yes" in err[0], err
    assert not out.exists()


def test_an_interrupt_inside_a_pydantic_dump_is_not_lost():
    """pydantic swallows an exception raised in a discriminator while it serialises (it warns and goes on): a
    Ctrl-C landing there was lost, and a sweep dumping its runs' scenes ran on for a minute. dumped() (what
    scene_to_dict uses) raises it."""
    from pydantic import BaseModel

    from taichi_rocks.config import values
    from taichi_rocks.config.scene import load_scene, scene_to_dict

    calls = []

    def pick(v):
        calls.append(v)
        if len(calls) == 2:  # the first call validates; the second is the dump's
            raise KeyboardInterrupt
        return isinstance(v, str)

    class M(BaseModel):
        x: values._either(str, int, pick) = 1

    m = M(x=3)
    with pytest.warns(UserWarning, match="discriminator"):
        assert m.model_dump() == {"x": 3}  # lost in pydantic's own dump
    calls[:] = [None]  # the next call raises: the one of this dump
    with pytest.raises(KeyboardInterrupt):
        values.dumped(m)
    assert scene_to_dict(load_scene(MINIMAL))["name"] == "minimal"


def test_ctrl_c_stops_a_big_sweep_while_it_builds_its_runs(tmp_path):
    """--yes: the count and estimate said first; a Ctrl-C while the runs are built (the driver keeps building
    once it has begun: tests/held_sweep.py, so the Ctrl-C lands in pydantic's work however fast the machine)
    ends the sweep (exit 130, one line), nothing written."""
    out, marker = tmp_path / "out", tmp_path / "building"
    with reaped(start_held_sweep("build", marker, _big_sweep(tmp_path), "--out", out, "--workers", "1",
                                 "--threads", "1", "--yes")) as proc:
        wait_for(marker.exists, proc)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=300)  # a bound, not a wait: it ends when the sweep does
    lines = err.strip().splitlines()
    assert proc.returncode == 130, err
    assert len(lines) == 2 and lines[0].startswith("sweep: 100000 runs of up to 500 steps"), err
    assert lines[1] == "taichi-rocks sweep: interrupted", err
    assert not out.exists()


def test_one_bad_file_through_the_command_line(tmp_path):
    sweep = _sweep_file(tmp_path, _bad_text("bad_value"))
    refused(cli("sweep", sweep, "--out", tmp_path / "out"), 'grid."launch.grip" = -1')
    assert not (tmp_path / "out").exists()


def test_the_runs_of_a_sweep():
    """Grid combinations in file order (the last key fastest), then seeds; each run's scene has its values;
    a dotted path into a vehicle works; the metric registry holds the documented metrics."""
    sweep, base = load_sweep(_sweep_file(Path(tempfile.mkdtemp()), SWEEP.replace(
        "[grid]\n", '[grid]\n"launch.grip" = [1e5, 4e5]\n"bed.radius" = [4.0]\n')), METRICS)
    runs = sweep_runs(sweep, base, "s.toml")
    assert len(runs) == 2 * 2 * 2 and [r.id for r in runs][:2] == ["r0000", "r0001"]
    assert [(r.values["launch.grip"], r.values["vehicle[0].path.speed"], r.seed) for r in runs[:3]] == [
        (1e5, 8.0, 1), (1e5, 8.0, 2), (1e5, 12.0, 1)]
    assert runs[-1].scene.vehicles[0].path.speed == 12.0 and runs[-1].scene.launch.grip == 4e5
    assert all(r.scene.duration == 0.4 for r in runs)
    assert {"launch", "timing", "digest", "render"} <= set(METRICS)
    with pytest.raises(SweepError, match="seeds are swept by seeds"):
        sweep_runs(*load_sweep(_sweep_file(Path(tempfile.mkdtemp()), SWEEP.replace(
            "[grid]\n", '[grid]\n"seed" = [3]\n'))), "s.toml")


def test_the_shipped_sweeps_validate():
    """sweeps/example.toml (README's example): 18 runs. sweeps/throw.toml: its base scene is the launch bands'
    reference case; 72 runs, the defaults among them."""
    sweep, base = load_sweep(ROOT / "sweeps" / "example.toml", METRICS)
    assert len(sweep_runs(sweep, base, "example.toml")) == 18 and base.name == "minimal"
    sweep, base = load_sweep(ROOT / "sweeps" / "throw.toml", METRICS)
    runs = sweep_runs(sweep, base, "throw.toml")
    assert len(runs) == 72 and sweep.measure.metrics == ("launch",)
    assert base.vehicles[1].path.speed == 20.0 and base.world.wetness == 0.0 and base.bed.follow == "anchor"
    defaults = {"launch.grip": 2e5, "launch.grip_relax": 12.0, "launch.groove": 0.012, "launch.adhesion": 3e4}
    assert any(all(r.values[k] == v for k, v in defaults.items()) for r in runs)
