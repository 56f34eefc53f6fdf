"""Dust in the export (app/export.py's frame, output/dust.py's Points prim in the USD stage, its PLY files): a
real run with [effects] dust, read back with pxr and NumPy, against the positions and opacities of the same run
stepped again."""

import numpy as np
from pxr import Usd, UsdGeom

from scenes_util import scene as make_scene
from taichi_rocks.app.export import export_run
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.output.dust import DUST_PRIM

FPS = 4.0
FRAMES = 10


def _scene():
    # 70 m/s: 158 m in the export, so the floating origin steps (128 m) under the dust
    return make_scene(rocks=100, radius=4.0, duration=3.0, effects={"dust": True}, dust={"rate": 0.05},
                      vehicles=[{"name": "car", "path": {"points": [[0.0, 0.0], [300.0, 0.0]], "speed": 70.0}}])


def test_usd_dust_points_are_the_engines(taichi_cpu, tmp_path):
    out = tmp_path / "d.usdc"
    export_run(Simulation(_scene(), tumble=True), out, FRAMES, FPS, fmt="usd")
    again = Simulation(_scene(), tumble=True)
    stage = Usd.Stage.Open(str(out))
    pts = UsdGeom.Points(stage.GetPrimAtPath(DUST_PRIM))
    bed = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Bed"))
    opacity = UsdGeom.PrimvarsAPI(pts).GetPrimvar("displayOpacity")
    seen, origins = 0, set()
    for f in range(FRAMES):
        again.advance_to(f / FPS)
        d = again.effect_arrays()["dust"]
        local = np.asarray(pts.GetPointsAttr().Get(f), np.float64).reshape(-1, 3)
        origin = np.asarray(bed.ComputeLocalToWorldTransform(f).ExtractTranslation(), np.float64)
        assert len(local) == len(d["positions"])
        np.testing.assert_allclose(local + origin, d["positions"], atol=1e-3)
        np.testing.assert_array_equal(np.asarray(opacity.Get(f), np.float32), d["opacity"])
        assert len(pts.GetWidthsAttr().Get(f)) == len(local)
        seen += len(local)
        origins.add(tuple(origin))
    assert seen > 100 and len(origins) > 1


def test_ply_dust_files_hold_the_engines_particles(taichi_cpu, tmp_path):
    """dust_00000.ply ... beside the rock frames: each frame's particles (world metres in doubles), their drawn
    width and opacity, read back with NumPy against the same run stepped again."""
    from taichi_rocks.output.dust import DUST_VERTEX
    from taichi_rocks.output.ply import PlyWriter

    res = export_run(Simulation(_scene(), tumble=True), tmp_path / "p", FRAMES, FPS, fmt="ply")
    assert res["frames"] == FRAMES
    names = sorted(p.name for p in (tmp_path / "p").iterdir())
    assert names == sorted([f"frame_{f:05d}.ply" for f in range(FRAMES)] + [f"dust_{f:05d}.ply" for f in
                                                                              range(FRAMES)])
    assert all(PlyWriter.owned(n) for n in names) and not PlyWriter.owned("dust_notes.ply")
    again, seen = Simulation(_scene(), tumble=True), 0
    for f in range(FRAMES):
        again.advance_to(f / FPS)
        d = again.effect_arrays()["dust"]
        header, _, body = (tmp_path / "p" / f"dust_{f:05d}.ply").read_bytes().partition(b"end_header\n")
        assert f"element vertex {len(d['opacity'])}".encode() in header
        rows = np.frombuffer(body, dtype=DUST_VERTEX)
        np.testing.assert_array_equal(np.column_stack([rows["x"], rows["y"], rows["z"]]), d["positions"])
        np.testing.assert_array_equal(rows["opacity"], d["opacity"])
        np.testing.assert_allclose(rows["width"], 2 * again.scene.dust.size * (0.4 + 0.6 * d["opacity"]), rtol=1e-6)
        seen += len(rows)
    assert seen > 100
