"""Dust in the export (app/export.py's frame, output/dust.py's Points prim in the USD stage): a real run with
[effects] dust, read back with pxr, against the positions and opacities of the same run stepped again."""

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


def test_ply_export_with_dust_runs(taichi_cpu, tmp_path):
    res = export_run(Simulation(_scene(), tumble=True), tmp_path / "p", 3, FPS, fmt="ply")
    assert res["frames"] == 3
