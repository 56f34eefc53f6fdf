"""Command-line refusals of values that would run forever, overflow or name the wrong thing: one line naming the
flag or key, exit 2, nothing written (issue-style cases: a seed past int64, ...)."""

from pathlib import Path
from types import SimpleNamespace

import pytest

from cli_util import cli_here, reaped, refused, start_cli

ROOT = Path(__file__).resolve().parents[1]
MINIMAL = ROOT / "scenes" / "minimal.toml"


@pytest.mark.parametrize("command", ["simulate", "render", "export"])
def test_seed_out_of_range_names_the_key(taichi_cpu, capsys, tmp_path, command):
    """--seed 2^64 ended in an OverflowError (exit 1): refused as the scene's seed is (tests/bad_scenes)."""
    out = tmp_path / ("o.usdc" if command == "export" else "o")
    line = refused(cli_here(capsys, command, MINIMAL, "--seed", 2**64, "--out", out))
    assert line == f"{MINIMAL}: seed: must be <= 9223372036854775807, got 18446744073709551616"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["simulate", "render", "export"])
def test_runs_of_too_many_steps_are_refused_with_the_estimate(capsys, tmp_path, command):
    """--fps 1e-9 or --frames 2e9 (years of stepping): refused before anything runs, naming the flag and the
    estimate; a scene file with sim.dt = 1e-12 the same, naming sim.dt, and `check` says so too."""
    out = tmp_path / ("o.usdc" if command == "export" else "o")
    for flags, words in ((("--fps=1e-9", "--frames", 5), ("--fps 1e-09", "1e+12 steps", "years")),
                         (("--frames", 2_000_000_000), ("--frames 2000000000", "steps", "days"))):
        refused(cli_here(capsys, command, MINIMAL, *flags, "--out", out), *words)
    scene = tmp_path / "s" / "dt.toml"
    scene.parent.mkdir()
    scene.write_text(MINIMAL.read_text().replace("dt = 0.004", "dt = 1e-12"))
    line = refused(cli_here(capsys, command, scene, "--frames", 5, "--out", out), "sim.dt", "2e+12 steps")
    assert refused(cli_here(capsys, "check", scene)) == line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"]


def test_frames_too_big_for_the_machine_are_refused_before_taichi_allocates(capsys, tmp_path):
    """--resolution 200000x200000 (400 GB of frames) ended in a Taichi allocation error (exit 1): one line
    naming the flag, exit 2, for render and view (before it looks for a display)."""
    for command, out in (("render", ("--out", tmp_path / "o")), ("view", ())):
        refused(cli_here(capsys, command, MINIMAL, "--resolution", "200000x200000", *out),
                "--resolution 200000x200000: a 200000x200000 frame needs about 1600.0 GB")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command, variable, value", [
    ("simulate", "TAICHI_ROCKS_THREADS", "0"), ("render", "TAICHI_ROCKS_THREADS", "1.5"),
    ("export", "TAICHI_ROCKS_PARALLEL_SCAN", "yes")])
def test_a_bad_environment_variable_is_one_line_in_a_new_process(tmp_path, command, variable, value):
    """The bad value found as Taichi starts ended in a traceback (exit 1), a wrong scan switch was ignored: one
    line naming the variable, exit 2, nothing written."""
    out = tmp_path / ("o.usdc" if command == "export" else "o")
    with reaped(start_cli(command, MINIMAL, "--frames", 2, "--out", out, env={variable: value})) as p:
        stdout, stderr = p.communicate(timeout=300)
    line = refused(SimpleNamespace(returncode=p.returncode, stderr=stderr), f"taichi-rocks {command}: {variable}",
                   repr(value))
    assert line.startswith(f"taichi-rocks {command}: {variable} must be")
    assert list(tmp_path.iterdir()) == []


def _taichi_commands(tmp_path) -> dict:
    """Each command that starts Taichi, with arguments that would run it."""
    return {"simulate": (MINIMAL, "--frames", 2, "--out", tmp_path / "o.npz"),
            "render": (MINIMAL, "--frames", 2, "--out", tmp_path / "o"),
            "export": (MINIMAL, "--frames", 2, "--out", tmp_path / "o.usdc"), "view": (MINIMAL, "--quit-after", 1),
            "bench": ("--quick", "--only", "frame", "--out", tmp_path / "b"),
            "sweep": (ROOT / "sweeps" / "example.toml", "--out", tmp_path / "w")}


BAD_VARIABLES = [("TAICHI_ROCKS_THREADS", "-1"), ("TAICHI_ROCKS_THREADS", "abc"), ("TAICHI_ROCKS_PARALLEL_SCAN", "yes"),
                 ("TAICHI_ROCKS_LOOPS", "fast")]


@pytest.mark.parametrize("command, variable, value", [
    (c, v, x) for c in ("simulate", "render", "export", "view", "bench", "sweep") for v, x in BAD_VARIABLES
    if not (c == "sweep" and v == "TAICHI_ROCKS_THREADS")])  # a sweep's workers get theirs from --threads
def test_every_command_that_starts_taichi_checks_the_variables(capsys, monkeypatch, tmp_path, command, variable,
                                                                value):
    """Before anything starts (in this process Taichi runs already: the check does not wait for it)."""
    monkeypatch.setenv(variable, value)
    refused(cli_here(capsys, command, *_taichi_commands(tmp_path)[command]),
            f"taichi-rocks {command}: {variable} must be", repr(value))
    assert list(tmp_path.iterdir()) == []
