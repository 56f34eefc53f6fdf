"""Impacts in the export (app/export.py impact_frame, output/usd.py's Impacts prim, output/ply.py's
impacts.ply): scripted events through the export of a real run, read back with pxr and NumPy, against the
events and the vehicles' poses at the time of each hit (computed here with the rotation written out)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from scenes_util import scene as make_scene

FPS = 4.0
FRAMES = 12


class Scripted:
    """A Simulation whose ``impacts()`` hands out scripted events (engine/events.py EVENT_DTYPE) up to its
    time, as the engine's does: each once, since the last call."""

    def __init__(self, sim, events):
        self._sim, self._events, self._given = sim, events, 0
        self.plan = SimpleNamespace(spin=sim.plan.spin, impacts=True)

    def __getattr__(self, name):
        return getattr(self._sim, name)

    def impacts(self):
        upto = int(np.searchsorted(self._events["time"], self._sim.time, side="right"))
        out, self._given = self._events[self._given:upto], upto
        return out


def _scene():
    # 60 m/s: 165 m in the export, so the floating origin steps; a turn makes the heading matter
    return make_scene(rocks=300, radius=4.0, duration=3.0, vehicles=[
        {"name": "player", "kind": "car", "path": {"points": [[0.0, 0.0], [60.0, 0.0], [200.0, 40.0]],
                                                   "speed": 60.0}},
        {"name": "truck", "kind": "truck", "length": 8.0, "width": 2.5, "height": 3.2, "tire_radius": 0.5,
         "path": {"points": [[10.0, 3.0], [220.0, 3.0]], "speed": 60.0}}], world={"ground_z": 0.4})


def _events(scene, origin_z):
    from taichi_rocks.engine.events import EVENT_DTYPE

    rng = np.random.default_rng(5)
    n = 9
    ev = np.zeros(n, EVENT_DTYPE)
    ev["time"] = np.sort(rng.uniform(0.05, (FRAMES - 1) / FPS, n))
    ev["time"][3] = ev["time"][2]  # two hits at the same time
    ev["time"][-1] = 5.0 / FPS  # on a frame time: shown in that frame
    ev["time"] = np.sort(ev["time"])
    ev["step"] = np.round(ev["time"] / scene.sim.dt).astype(np.int64)
    ev["vehicle"] = rng.integers(0, 2, n)
    ev["part"] = rng.integers(0, 7, n)
    ev["damage"] = rng.integers(0, 3, n)
    body = np.stack([rng.uniform(-2, 2, n), rng.uniform(-0.8, 0.8, n), rng.uniform(0.3, 1.4, n)], 1)
    ev["point"] = body + (0.0, 0.0, scene.world.ground_z - origin_z)  # the engine's z: local frame
    nrm = rng.normal(size=(n, 3))
    ev["normal"] = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    ev["energy"] = rng.uniform(0.001, 0.5, n)
    ev["speed"], ev["normal_speed"] = rng.uniform(5, 30, n), rng.uniform(1, 5, n)
    ev["normal_momentum"], ev["radius"] = rng.uniform(1e-4, 1e-2, n), rng.uniform(0.005, 0.02, n)
    ev["rock"], ev["thrower"] = rng.integers(0, 300, n), 1
    return ev, body


def _expected(sim, ev, body):
    """World contact points and normals: the hit vehicle's pose at the hit's time, R_z(heading) written out."""
    pts, nrms = [], []
    for e, b in zip(ev, body):
        p = sim.fleet.poses(float(e["time"]))[int(e["vehicle"])]
        c, s = math.cos(p.heading), math.sin(p.heading)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        pts.append(np.array([p.position[0], p.position[1], sim.scene.world.ground_z]) + rot @ b)
        nrms.append(rot @ e["normal"])
    return np.array(pts), np.array(nrms)


@pytest.fixture(scope="module")
def exported(taichi_cpu, tmp_path_factory):
    from taichi_rocks.app.export import export_run
    from taichi_rocks.engine.simulation import Simulation

    d = tmp_path_factory.mktemp("impacts")
    scene = _scene()
    out = {}
    for fmt, path in (("usd", d / "run.usdc"), ("ply", d / "ply")):
        sim = Simulation(scene, tumble=True)
        ev, body = _events(scene, float(sim.origin[2]))
        export_run(Scripted(sim, ev), path, FRAMES, FPS, fmt=fmt)
        out[fmt] = path
        out["expected"] = _expected(sim, ev, body)
        out["events"] = ev
        del sim  # the next format's simulation takes its World
    return out


def test_the_usd_holds_each_hit_in_its_frame_at_its_world_position(exported):
    from pxr import Usd, UsdGeom

    from taichi_rocks.config.impacts import DAMAGE_CLASSES
    from taichi_rocks.motion.bodies import LABELS

    stage = Usd.Stage.Open(str(exported["usd"]))
    prim = stage.GetPrimAtPath("/World/Bed/Impacts")
    assert prim and prim.IsA(UsdGeom.Points)
    assert list(prim.GetCustomDataByKey("taichi_rocks:damage_classes")) == list(DAMAGE_CLASSES)
    pts = UsdGeom.Points(prim)
    api = UsdGeom.PrimvarsAPI(prim)
    bed = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Bed"))
    ev, (want, want_n) = exported["events"], exported["expected"]
    frame_of = np.ceil(ev["time"] * FPS - 1e-9).astype(int)  # the first frame at or after the hit
    seen = 0
    for f in range(FRAMES):
        sel = np.flatnonzero(frame_of == f)
        local = np.asarray(pts.GetPointsAttr().Get(f), np.float64).reshape(-1, 3)
        assert len(local) == len(sel), f
        origin = np.array(bed.GetLocalTransformation(f).ExtractTranslation())
        np.testing.assert_allclose(local + origin, want[sel], atol=2e-5)
        np.testing.assert_allclose(np.asarray(pts.GetNormalsAttr().Get(f)).reshape(-1, 3), want_n[sel], atol=1e-6)
        np.testing.assert_allclose(np.asarray(api.GetPrimvar("energy").Get(f)), ev["energy"][sel], rtol=1e-6)
        assert list(api.GetPrimvar("damage").Get(f)) == list(ev["damage"][sel])
        assert list(api.GetPrimvar("class").Get(f)) == [DAMAGE_CLASSES[k] for k in ev["damage"][sel]]
        assert list(api.GetPrimvar("vehicle").Get(f)) == list(ev["vehicle"][sel])
        assert list(api.GetPrimvar("part").Get(f)) == [LABELS[k] for k in ev["part"][sel]]
        np.testing.assert_array_equal(np.asarray(api.GetPrimvar("time").Get(f)), ev["time"][sel])
        if len(sel):  # nothing of the frame before slides into it
            assert len(pts.GetPointsAttr().Get(f - 1e-4)) == 0
        seen += len(sel)
    assert seen == len(ev) and len(set(frame_of)) >= 4
    moved = [np.array(bed.GetLocalTransformation(f).ExtractTranslation()) for f in (0, FRAMES - 1)]
    assert np.linalg.norm(moved[1] - moved[0]) > 0  # the floating origin stepped: points stay world-exact


def test_the_ply_holds_every_event_of_the_run(exported):
    from taichi_rocks.output.ply import IMPACT, IMPACTS_FILE

    path = exported["ply"] / IMPACTS_FILE
    data = path.read_bytes()
    header, _, body = data.partition(b"end_header\n")
    assert b"comment damage: mark chip crack" in header
    assert b"element vertex 9" in header
    rows = np.frombuffer(body, dtype=IMPACT)
    ev, (want, want_n) = exported["events"], exported["expected"]
    assert len(rows) == len(ev)
    np.testing.assert_allclose(np.stack([rows["x"], rows["y"], rows["z"]], 1), want, atol=1e-9)
    np.testing.assert_allclose(np.stack([rows["nx"], rows["ny"], rows["nz"]], 1), want_n, atol=1e-6)
    np.testing.assert_array_equal(rows["time"], ev["time"])
    np.testing.assert_array_equal(rows["frame"], np.ceil(ev["time"] * FPS - 1e-9).astype(int))
    for key in ("vehicle", "part", "damage", "rock", "thrower"):
        np.testing.assert_array_equal(rows[key], ev[key])
    np.testing.assert_allclose(rows["energy"], ev["energy"], rtol=1e-6)
    assert len(list(exported["ply"].glob("frame_*.ply"))) == FRAMES


def test_a_ply_folder_with_its_impacts_is_ours_to_overwrite(exported):
    from taichi_rocks.output.ply import PlyWriter

    with pytest.raises(FileExistsError):
        PlyWriter.check_target(exported["ply"], overwrite=False)
    PlyWriter.check_target(exported["ply"], overwrite=True)


def test_the_engines_hits_reach_the_export(taichi_cpu, tmp_path):
    """A stone the player drives into (tests/render/test_marks_engine.py's scene): ``export`` takes the engine's
    event through ``sim.impacts()``; impacts.ply holds it at the windscreen point aimed at, placed with the
    player's pose at the time of the hit."""
    from render.test_marks_engine import ROCK, SCENE, _aim  # tests/render: the same scene and stone

    from taichi_rocks.app.export import export_run
    from taichi_rocks.config.scene import parse_scene
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.motion.bodies import LABELS
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.output.ply import IMPACT, IMPACTS_FILE

    scene = parse_scene(SCENE, source="<test>")
    sim = Simulation(scene, tumble=True)
    start, v, target = _aim(sim, cabin_of(scene.vehicles[0]))
    sim.set_rocks([ROCK], positions=start[None], velocities=v[None], phase=np.array([1], np.int8))
    export_run(sim, tmp_path / "ply", 6, 30.0, fmt="ply")
    rows = np.frombuffer((tmp_path / "ply" / IMPACTS_FILE).read_bytes().partition(b"end_header\n")[2], IMPACT)
    assert len(rows) == 1 and rows["rock"][0] == ROCK and rows["vehicle"][0] == 0
    assert LABELS[rows["part"][0]] == "windscreen"
    pose = sim.fleet.poses(float(rows["time"][0]))[0]
    want = pose.position + target  # heading 0: along +x
    got = np.array([rows["x"][0], rows["y"][0], rows["z"][0]])
    assert np.linalg.norm(got - want) < 0.03, (got, want)
    assert rows["frame"][0] == int(np.ceil(rows["time"][0] * 30.0 - 1e-9))
