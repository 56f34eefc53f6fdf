"""Run files: the light layout that `simulate` writes by default, read back by `load_run` as the full layout's
arrays (the same bits), and the full layout on request."""

import numpy as np

from cli_util import ROOT, cli_here, refused, run_here
from taichi_rocks import load_run

MINIMAL = ROOT / "scenes" / "minimal.toml"


def _within(run, f, radius):
    """The rocks of frame f within ``radius`` of the car, horizontally (compared as squares, as the writer does)."""
    d = run["positions"][f][:, :2] - run["vehicle_positions"][f][0][:2]
    return d[:, 0] ** 2 + d[:, 1] ** 2 <= radius ** 2


def test_load_run_gives_the_same_arrays_from_both_layouts(taichi_cpu, tmp_path):
    """The light layout (default) through load_run equals the full layout bit for bit: every array, under the
    same names; --only all too; with --crop, the same where kept and NaN / -1 (missing) elsewhere. And it is
    the lighter file, without a raw `positions` member. (The four runs in this process: one compile.)"""
    common = ("--frames", 30, "--fps", 15)
    names = {"full": ("--layout", "full"), "light": (), "all": ("--only", "all"), "crop": ("--crop", "4")}
    run_here(*(("simulate", MINIMAL, "--out", tmp_path / f"{k}.npz", *v, *common) for k, v in names.items()))
    full = load_run(tmp_path / "full.npz")
    assert full["positions"].shape == (30, 2000, 3) and full["positions"].dtype == np.float64
    for name in ("light", "all", "crop"):
        got = load_run(tmp_path / f"{name}.npz")
        assert list(got) == list(full), name
        for k in full:
            if name == "crop" and k in ("positions", "velocities", "phase"):
                continue
            np.testing.assert_array_equal(got[k], full[k], err_msg=f"{name}: {k}")
            assert got[k].dtype == full[k].dtype, (name, k)
        with np.load(tmp_path / f"{name}.npz") as z:
            assert "positions" not in z.files and str(z["layout"]).startswith("taichi-rocks run")
    size = {k: (tmp_path / f"{k}.npz").stat().st_size for k in names}
    assert size["light"] < 0.2 * size["full"], size
    crop = load_run(tmp_path / "crop.npz")
    inside = np.stack([_within(full, f, 4.0) for f in range(30)])
    assert 0 < inside.mean() < 1
    np.testing.assert_array_equal(crop["phase"] >= 0, inside)
    for k in ("positions", "velocities", "phase"):
        np.testing.assert_array_equal(crop[k][inside], full[k][inside], err_msg=k)
    assert np.isnan(crop["positions"][~inside]).all() and (crop["phase"][~inside] == -1).all()


def test_simulate_full_layout_rejects_only_and_crop(taichi_cpu, capsys, tmp_path):
    refused(cli_here(capsys, "simulate", MINIMAL, "--out", tmp_path / "x.npz", "--layout", "full", "--only", "all"),
            "--layout light")
    assert list(tmp_path.iterdir()) == []
