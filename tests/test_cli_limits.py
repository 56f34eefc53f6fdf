"""Command-line refusals of values that would run forever, overflow or name the wrong thing: one line naming the
flag or key, exit 2, nothing written (issue-style cases: a seed past int64, ...)."""

from pathlib import Path

import pytest

from cli_util import cli_here, refused

ROOT = Path(__file__).resolve().parents[1]
MINIMAL = ROOT / "scenes" / "minimal.toml"


@pytest.mark.parametrize("command", ["simulate", "render", "export"])
def test_seed_out_of_range_names_the_flag(capsys, tmp_path, command):
    for seed in ("18446744073709551616", "-1"):
        r = cli_here(capsys, command, MINIMAL, "--seed", seed, "--out", tmp_path / "o")
        refused(r, "--seed", seed)
    assert list(tmp_path.iterdir()) == []
