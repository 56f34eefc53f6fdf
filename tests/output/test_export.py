"""Export for other tools (USD, PLY) and the light run files: read back as those tools would, compared with
what `simulate` writes for the same scene."""

import math
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from cli_util import ROOT, _env, cli_here, refused, run_here, start_cli, wait_for
from taichi_rocks import load_run

MINIMAL = ROOT / "scenes" / "minimal.toml"
FRAMES, FPS = 16, 8.0  # 2 s of the minimal scene: rocks are launched, land and are recycled
FAR = 100_000.0  # m: the "far" scene is the minimal one moved this far along x and y


def _far_scene(folder):
    """The minimal scene 100 km from the world origin (x and y)."""
    text = MINIMAL.read_text().replace("points = [[0.0, 0.0], [40.0, 0.0]]",
                                       f"points = [[{FAR}, {FAR}], [{FAR + 40.0}, {FAR}]]")
    assert str(FAR) in text
    path = folder / "far.toml"
    path.write_text(text)
    return path


def _fast_scene(folder):
    """The minimal scene at 80 m/s: the bed travels 160 m in 2 s, so the floating origin steps (by 128 m)."""
    text = MINIMAL.read_text().replace("points = [[0.0, 0.0], [40.0, 0.0]], speed = 10.0",
                                       "points = [[0.0, 0.0], [400.0, 0.0]], speed = 80.0")
    assert "80.0" in text
    path = folder / "fast.toml"
    path.write_text(text)
    return path


def _ok(r):
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def runs(tmp_path_factory, taichi_cpu):
    """USD exports (every rock, only the flying ones), a PLY export and the full .npz of the same frames,
    for the minimal scene and for it 100 km away (the commands run in this process: one compile)."""
    d = tmp_path_factory.mktemp("export")
    far, fast = _far_scene(d), _fast_scene(d)
    common = ("--frames", FRAMES, "--fps", FPS)
    run_here(("export", MINIMAL, "--out", d / "all.usdc", *common),
             ("simulate", MINIMAL, "--out", d / "run.npz", "--layout", "full", *common),
             ("export", MINIMAL, "--out", d / "flying.usdc", "--only", "flying", *common),
             ("export", MINIMAL, "--format", "ply", "--out", d / "ply", "--crop", "5", *common),
             ("export", far, "--out", d / "far.usdc", *common),
             ("simulate", far, "--out", d / "far.npz", "--layout", "full", *common),
             ("export", fast, "--out", d / "fast.usdc", *common),
             ("simulate", fast, "--out", d / "fast.npz", "--layout", "full", *common))
    return d


def _stage(path):
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    assert stage, path
    return stage


def _rocks(stage, frame):
    """(ids, world positions float64, velocities, local positions) of the instances at time code ``frame``:
    the PointInstancer's local positions through its parent transform, composed in double precision."""
    from pxr import UsdGeom

    pi = UsdGeom.PointInstancer(stage.GetPrimAtPath("/World/Bed/Rocks"))
    local = np.asarray(pi.GetPositionsAttr().Get(frame), np.float64).reshape(-1, 3)
    ids = np.asarray(pi.GetIdsAttr().Get(frame), np.int64)
    vel = np.asarray(pi.GetVelocitiesAttr().Get(frame), np.float64).reshape(-1, 3)
    m = np.array(UsdGeom.Xformable(pi).ComputeLocalToWorldTransform(frame), np.float64)
    return ids, local @ m[:3, :3] + m[3, :3], vel, local


def test_usd_stage_metadata_and_time_samples(runs):
    from pxr import UsdGeom

    from taichi_rocks.output.instances import PROTOTYPES
    from taichi_rocks.output.looks import TINTS

    stage = _stage(runs / "all.usdc")
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == FPS
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, FRAMES - 1.0)
    assert stage.GetDefaultPrim().GetPath() == "/World"
    pi = UsdGeom.PointInstancer(stage.GetPrimAtPath("/World/Bed/Rocks"))
    for attr in (pi.GetPositionsAttr(), pi.GetIdsAttr(), pi.GetProtoIndicesAttr(), pi.GetOrientationsAttr(),
                 pi.GetScalesAttr(), pi.GetVelocitiesAttr()):
        assert attr.GetTimeSamples() == [float(f) for f in range(FRAMES)], attr.GetName()
    assert len(pi.GetPrototypesRel().GetTargets()) == PROTOTYPES * TINTS  # each rock shape in each tint
    car = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Vehicles/car"))
    assert len(car.GetOrderedXformOps()[0].GetTimeSamples()) == FRAMES
    cam = UsdGeom.Camera(stage.GetPrimAtPath("/World/Camera"))
    assert len(cam.GetPrim().GetAttribute("xformOp:transform").GetTimeSamples()) == FRAMES
    fov = 2 * math.degrees(math.atan(cam.GetVerticalApertureAttr().Get() / 2 / cam.GetFocalLengthAttr().Get()))
    assert fov == pytest.approx(50.0)  # the default [camera] fov


@pytest.mark.parametrize("name", ["all", "far"])
def test_usd_world_positions_equal_the_run(runs, name):
    """Bed transform x local position = the .npz's world position, within 1e-5 m, at the first, middle and
    last frame; near the world origin and 100 km from it (where float32 world coordinates would be off by
    millimetres)."""
    stage = _stage(runs / f"{name}.usdc")
    run = load_run(runs / ("run.npz" if name == "all" else "far.npz"))
    n = len(run["radii"])
    for f in (0, FRAMES // 2, FRAMES - 1):
        ids, world, vel, local = _rocks(stage, f)
        assert len(np.unique(ids)) == len(ids) == n  # every rock, each id once
        rock = ids % n
        np.testing.assert_array_equal(np.sort(rock), np.arange(n))
        err = np.max(np.abs(world - run["positions"][f][rock]))
        assert err <= 1e-5, f"frame {f}: {err:.3g} m"
        np.testing.assert_allclose(vel, run["velocities"][f][rock], rtol=0, atol=1e-6)
        assert np.max(np.abs(local)) < 1000.0  # float32 stays near the bed; the Xform carries the distance
    if name == "far":
        assert np.min(np.abs(run["positions"][..., :2])) > FAR - 100.0


def test_usd_origin_steps_without_sliding_the_rocks(runs):
    """Where the floating origin steps (the bed travelled 128 m), the frame is also written just before the
    step relative to the old origin: world positions are right at every frame and at the extra sample, and
    linearly interpolated samples give the interpolated world positions, not a 64 m slide."""
    from taichi_rocks.output.usd import STEP_HOLD

    stage = _stage(runs / "fast.usdc")
    run = load_run(runs / "fast.npz")
    n = len(run["radii"])
    translate = stage.GetPrimAtPath("/World/Bed").GetAttribute("xformOp:translate")
    origins = {t: np.array(translate.Get(t)) for t in translate.GetTimeSamples()}
    steps = [f for f in range(1, FRAMES) if not np.array_equal(origins[f], origins[f - 1])]
    assert len(steps) == 1 and np.linalg.norm(origins[steps[0]] - origins[steps[0] - 1]) >= 64.0
    f = steps[0]
    assert sorted(origins) == sorted([float(k) for k in range(FRAMES)] + [f - STEP_HOLD])
    for t in range(FRAMES):
        ids, world, _, _ = _rocks(stage, t)
        assert np.max(np.abs(world - run["positions"][t][ids % n])) <= 1e-5, t
    ids0, w0, _, _ = _rocks(stage, f - 1)
    ids1, w1, _, _ = _rocks(stage, f)
    ids_h, w_h, _, _ = _rocks(stage, f - STEP_HOLD)
    np.testing.assert_array_equal(ids_h, ids1)
    assert np.max(np.abs(w_h - w1)) <= 1e-5
    same = ids0 == ids1  # plain interpolation goes by array index: a recycled rock would move anyway
    for t in (f - 0.5, f - STEP_HOLD / 2):
        _, w, _, _ = _rocks(stage, t)
        a = min(1.0, (t - (f - 1)) / (1.0 - STEP_HOLD))
        expect = w0 + a * (w1 - w0) if t < f - STEP_HOLD else w1
        assert np.max(np.abs(w - expect)[same]) <= 1e-3, t


def test_usd_ids_unique_per_frame_and_new_after_a_recycle(runs):
    """No id continues across a jump its speed cannot explain (a recycle across the bed), and recycled rocks
    do get new ids (index + N x generation)."""
    stage = _stage(runs / "all.usdc")
    n = len(load_run(runs / "run.npz")["radii"])
    g = 9.81
    prev = None
    renamed = 0
    for f in range(FRAMES):
        ids, world, vel, _ = _rocks(stage, f)
        assert len(np.unique(ids)) == len(ids)
        order = np.argsort(ids % n)
        ids, world, vel = ids[order], world[order], vel[order]
        if prev is not None:
            p_ids, p_world, p_vel = prev
            same = ids == p_ids
            jump = np.linalg.norm(world - p_world, axis=1)
            speed = np.maximum(np.linalg.norm(vel, axis=1), np.linalg.norm(p_vel, axis=1))
            bound = (speed + g / FPS) / FPS + 1e-3
            assert np.all(jump[same] <= bound[same]), f"frame {f}: an id jumped {np.max(jump[same] - bound[same])} m"
            new = ~same
            assert np.all(ids[new] // n == p_ids[new] // n + 1)  # the next generation of that rock
            assert np.all(jump[new] > bound[new])
            renamed += int(new.sum())
        prev = ids, world, vel
    assert renamed > 0  # the scene recycles rocks: the check above was exercised


def test_only_flying_is_far_smaller_and_keeps_what_moves(runs):
    stage_all, stage_fly = _stage(runs / "all.usdc"), _stage(runs / "flying.usdc")
    size_all, size_fly = (runs / "all.usdc").stat().st_size, (runs / "flying.usdc").stat().st_size
    assert size_fly < 0.2 * size_all, (size_fly, size_all)
    run = load_run(runs / "run.npz")
    n = len(run["radii"])
    kept = 0
    for f in range(1, FRAMES):
        ids, world, _, _ = _rocks(stage_fly, f)
        moved = (run["positions"][f] != run["positions"][f - 1]).any(axis=1)
        moving = (run["velocities"][f] != 0).any(axis=1)
        np.testing.assert_array_equal(np.sort(ids % n), np.flatnonzero(moved | moving))
        a_ids, a_world, _, _ = _rocks(stage_all, f)
        where = {i: k for k, i in enumerate(a_ids)}
        np.testing.assert_array_equal(world, a_world[[where[i] for i in ids]])  # the same instances
        kept += len(ids)
    assert kept > 0


def _within(run, f, radius):
    """The rocks of frame f within ``radius`` of the car, horizontally (compared as squares, as the export does)."""
    d = run["positions"][f][:, :2] - run["vehicle_positions"][f][0][:2]
    return d[:, 0] ** 2 + d[:, 1] ** 2 <= radius ** 2


def _read_ply(path):
    data = path.read_bytes()
    header, _, body = data.partition(b"end_header\n")
    lines = header.decode("ascii").splitlines()
    assert lines[:2] == ["ply", "format binary_little_endian 1.0"]
    count = int(next(x for x in lines if x.startswith("element vertex")).split()[2])
    types = {"double": "<f8", "float": "<f4", "uint": "<u4"}
    props = [x.split()[1:] for x in lines if x.startswith("property")]
    dtype = np.dtype([(name, types[t]) for t, name in props])
    assert [name for _, name in props] == ["x", "y", "z", "radius", "vx", "vy", "vz", "id"]
    assert len(body) == count * dtype.itemsize
    return np.frombuffer(body, dtype=dtype)


def test_ply_frames_read_back_with_numpy(runs):
    """One binary PLY per frame: world positions (double) and velocities as in the run, radii, unique ids,
    and --crop 5 keeps exactly the rocks within 5 m of the followed car."""
    files = sorted((runs / "ply").iterdir())
    assert [p.name for p in files] == [f"frame_{f:05d}.ply" for f in range(FRAMES)]
    run = load_run(runs / "run.npz")
    n = len(run["radii"])
    for f, path in enumerate(files):
        rows = _read_ply(path)
        rock = rows["id"].astype(np.int64) % n
        assert len(np.unique(rows["id"])) == len(rows)
        world = np.stack([rows["x"], rows["y"], rows["z"]], axis=1)
        np.testing.assert_array_equal(world, run["positions"][f][rock])
        np.testing.assert_array_equal(rows["radius"], run["radii"][rock].astype(np.float32))
        np.testing.assert_array_equal(np.stack([rows["vx"], rows["vy"], rows["vz"]], axis=1),
                                      run["velocities"][f][rock])
        np.testing.assert_array_equal(np.sort(rock), np.flatnonzero(_within(run, f, 5.0)))


def test_export_refuses_to_overwrite_and_bad_input(taichi_cpu, capsys, tmp_path):
    """In this process (export's exit statuses from a process of its own: the two tests below)."""
    def cli(*args):
        return cli_here(capsys, *args)

    out = tmp_path / "x.usdc"
    out.write_bytes(b"mine")
    refused(cli("export", MINIMAL, "--out", out, "--frames", 2), "--overwrite")
    assert out.read_bytes() == b"mine"
    refused(cli("export", MINIMAL, "--out", tmp_path / "x.obj", "--frames", 2), ".usdc")
    folder = tmp_path / "frames"
    folder.mkdir()
    (folder / "frame_00000.ply").write_bytes(b"old")
    refused(cli("export", MINIMAL, "--format", "ply", "--out", folder, "--frames", 2), "--overwrite")
    (folder / "notes.txt").write_bytes(b"keep")
    refused(cli("export", MINIMAL, "--format", "ply", "--out", folder, "--frames", 2, "--overwrite"),
            "notes.txt")
    r = cli("export", MINIMAL, "--out", tmp_path / "y.usdc", "--crop", "-1")  # argparse: usage, then the error
    assert r.returncode == 2 and "Traceback" not in r.stderr and "--crop" in r.stderr.strip().splitlines()[-1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames", "x.usdc"]
    assert sorted(p.name for p in folder.iterdir()) == ["frame_00000.ply", "notes.txt"]
    (folder / "notes.txt").unlink()
    _ok(cli("export", MINIMAL, "--format", "ply", "--out", folder, "--frames", 2, "--overwrite"))
    assert sorted(p.name for p in folder.iterdir()) == ["frame_00000.ply", "frame_00001.ply"]
    assert _read_ply(folder / "frame_00000.ply").size == 2000
    _ok(cli("export", MINIMAL, "--out", out, "--frames", 2, "--overwrite"))
    assert _stage(out).GetEndTimeCode() == 1.0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames", "x.usdc"]  # no temporaries left


def test_export_usd_without_pxr_is_one_line(tmp_path):
    """Without usd-core: exit 2, one line naming the package, nothing written."""
    hide = tmp_path / "hide"
    (hide / "pxr").mkdir(parents=True)
    (hide / "pxr" / "__init__.py").write_text("raise ImportError('No module named pxr')\n")
    env = _env()
    env["PYTHONPATH"] = f"{hide}{os.pathsep}{ROOT}"
    r = subprocess.run([sys.executable, "-m", "taichi_rocks", "export", MINIMAL, "--out", tmp_path / "o" / "x.usdc"],
                       env=env, capture_output=True, text=True, timeout=300)
    refused(r, "usd-core")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hide"]


def test_export_streams_to_disk_and_ctrl_c_leaves_nothing(tmp_path):
    """The .usdc grows while simulating (each frame is saved as it is made), under a temporary name; Ctrl-C
    removes it and the folder the export made."""
    out = tmp_path / "out" / "x.usdc"
    p = start_cli("export", MINIMAL, "--out", out, "--frames", 100000, "--fps", 240)
    grown = lambda: any(q.name.startswith(".x.usdc.") and q.stat().st_size > 3_000_000
                        for q in (out.parent.iterdir() if out.parent.is_dir() else ()))
    wait_for(grown, p, poll=0.05)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130 and "interrupted" in err and "Traceback" not in err, err
    assert list(tmp_path.iterdir()) == []


def _face_normals(points, counts, indices):
    """Newell normals of the faces, and their centres."""
    normals, centres, k = [], [], 0
    for c in counts:
        p = points[indices[k:k + c]].astype(np.float64)
        q = np.roll(p, -1, axis=0)
        normals.append(np.stack([np.sum((p[:, 1] - q[:, 1]) * (p[:, 2] + q[:, 2])),
                                 np.sum((p[:, 2] - q[:, 2]) * (p[:, 0] + q[:, 0])),
                                 np.sum((p[:, 0] - q[:, 0]) * (p[:, 1] + q[:, 1]))]))
        centres.append(p.mean(axis=0))
        k += c
    return np.array(normals), np.array(centres)


def test_meshes_are_closed_outward_and_reproducible():
    """Rock prototypes (deterministic, distinct, mean radius 1), the box and the wheel cylinder: faces
    counter-clockwise seen from outside, every edge shared by exactly two faces."""
    from taichi_rocks.output.shapes import box_mesh, cylinder_mesh, rock_prototype

    rocks = [rock_prototype(k) for k in range(3)]
    for a, b in zip(rocks, [rock_prototype(k) for k in range(3)]):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)
    assert not np.array_equal(rocks[0][0], rocks[1][0])
    for mesh in rocks + [box_mesh((0.0, 0.0, 1.0), (4.0, 2.0, 1.5)), cylinder_mesh(0.3, 0.2)]:
        points, counts, indices = mesh
        normals, centres = _face_normals(*mesh)
        inner = points.mean(axis=0)
        assert np.all(np.sum(normals * (centres - inner), axis=1) > 0)
        edges, k = {}, 0
        for c in counts:
            f = indices[k:k + c]
            for a, b in zip(f, np.roll(f, -1)):
                edges[(min(a, b), max(a, b))] = edges.get((min(a, b), max(a, b)), 0) + 1
            k += c
        assert set(edges.values()) == {2}
    for points, _, _ in rocks:
        assert np.mean(np.linalg.norm(points, axis=1)) == pytest.approx(1.0, rel=1e-6)


def test_camera_matrix_looks_from_the_eye_at_the_target():
    """The exported camera is the renderer's rig (motion/camera.py camera_of); its USD transform is a rotation
    without roll that looks from the eye at the target."""
    from taichi_rocks.motion.camera import CameraRig
    from taichi_rocks.output.shapes import camera_matrix

    rig = CameraRig((-9.0, 0.5, 3.5), 6.0, 0.3)
    rng = np.random.default_rng(1)
    for k in range(40):
        p, h, t = rng.normal(size=3) * 100.0, float(rng.uniform(-np.pi, np.pi)), k / 12.0
        eye, target, _ = rig.update(p, h, t)
        m = camera_matrix(eye, target)
        np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-12)  # a rotation, no roll:
        assert abs(m[0, 2]) < 1e-12  # the camera's right axis stays horizontal
        look = -m[2, :3]
        np.testing.assert_allclose(look, (target - eye) / np.linalg.norm(target - eye), atol=1e-12)
        np.testing.assert_allclose(m[3, :3], eye, atol=1e-12)


def test_instances_carry_the_engines_orientations_and_new_ids_after_a_recycle():
    """The tracker hands on the engine's orientations and angular velocities as they are (a recycled rock keeps
    its orientation under its new id) and refuses a state without them."""
    from taichi_rocks.output.instances import RockTracker

    n = 50
    rng = np.random.default_rng(0)
    pos = np.zeros((n, 3))
    pos[:, 0] = np.arange(n)
    vel = np.zeros((n, 3), np.float32)
    q = rng.normal(size=(n, 4)).astype(np.float32)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    omega = np.zeros((n, 3), np.float32)
    tracker = RockTracker(n, 9.81, 10.0)
    st = {"positions": pos, "velocities": vel, "recycles_total": 0, "orientations": q, "angular_velocities": omega}
    first = tracker.update(st)
    vel2 = vel.copy()
    vel2[:10, 0] = 2.0  # rocks 0-9 fly
    pos2 = pos.copy()
    pos2[:10, 0] += 0.2
    pos2[10, 0] += 30.0  # rock 10 recycled across the bed
    q2, omega2 = q[::-1].copy(), rng.normal(size=(n, 3)).astype(np.float32)
    second = tracker.update({"positions": pos2, "velocities": vel2, "recycles_total": 1, "orientations": q2,
                             "angular_velocities": omega2})
    assert np.array_equal(first["orientations"], q) and np.array_equal(second["orientations"], q2)
    assert np.array_equal(second["angular_velocities"], omega2)
    assert np.flatnonzero(second["recycled"]).tolist() == [10]
    assert second["ids"][10] == 10 + n and np.array_equal(np.delete(second["ids"], 10), np.delete(first["ids"], 10))
    with pytest.raises(ValueError, match="tumble=True"):
        RockTracker(n, 9.81, 10.0).update({"positions": pos, "velocities": vel, "recycles_total": 0})


def test_usd_orientations_and_angular_velocities_are_the_engines(runs, taichi_cpu):
    """Read back from the stage at every frame: each instance's orientation (quath) and angular velocity
    (deg/s) are those of its rock (id mod N) in the engine's state at that frame, simulated here."""
    from pxr import UsdGeom

    from taichi_rocks.app.frames import frame_states
    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.engine.simulation import Simulation

    stage = _stage(runs / "all.usdc")
    pi = UsdGeom.PointInstancer(stage.GetPrimAtPath("/World/Bed/Rocks"))
    sim = Simulation(load_scene(MINIMAL), tumble=True)
    spinning = turned = 0
    first = None
    for f, st in frame_states(sim, FRAMES, FPS, True, None):
        ids = np.asarray(pi.GetIdsAttr().Get(f), np.int64)
        rock = ids % sim.n_rocks
        q = np.array([[x.GetImaginary()[0], x.GetImaginary()[1], x.GetImaginary()[2], x.GetReal()]
                      for x in pi.GetOrientationsAttr().Get(f)], np.float64)
        omega = np.asarray(pi.GetAngularVelocitiesAttr().Get(f), np.float64).reshape(-1, 3)
        want_q = st["orientations"][rock].astype(np.float64)
        np.testing.assert_allclose(q, want_q, atol=5e-4)  # half precision: 2^-12 of a unit
        np.testing.assert_allclose(omega, np.degrees(st["angular_velocities"][rock].astype(np.float64)),
                                   rtol=1e-6, atol=1e-4)
        spinning += int(np.any(omega != 0.0, axis=1).sum())
        first = want_q if first is None else first
        turned = int(np.sum(np.abs(np.sum(want_q * first, axis=1)) < 0.999))
    assert spinning > 20 and turned > 5  # stones were thrown, spun and turned


def test_every_registered_format_is_a_writer_named_as_its_key(capsys):
    """The registry (output/formats.py FORMATS) is what `export --format` lists; each entry names its writer."""
    from taichi_rocks.output.formats import FORMATS, ExportWriter, writer_class

    assert list(FORMATS) == ["usd", "ply"]
    for name in FORMATS:
        cls = writer_class(name)
        assert issubclass(cls, ExportWriter) and cls.name == name and cls.default_name
    with pytest.raises(ValueError, match="format must be one of usd, ply"):
        writer_class("obj")
    r = cli_here(capsys, "export", "--help")
    assert r.returncode == 0 and "{usd,ply}" in r.stdout


class _Landings:
    """A format of one module, as a new one is written (output/formats.py): one CSV row per rock that came to
    rest in a frame, from the whole state every frame carries."""

    @staticmethod
    def make(fail_at=None):
        from taichi_rocks.output.formats import FileWriter

        class LandingsWriter(FileWriter):
            name, default_name, suffixes = "landings", "{scene}_landings.csv", (".csv",)
            calls = []

            def __init__(self, out, run):
                super().__init__(out, run)
                self.f, self.prev = open(self.tmp, "x"), None
                self.f.write("frame,rock\n")

            def write(self, frame):
                if frame["frame"] == fail_at:
                    raise RuntimeError("disk full")
                phase = frame["state"]["phase"]
                if self.prev is not None:
                    for i in np.flatnonzero((self.prev != 0) & (phase == 0)):
                        self.f.write(f"{frame['frame']},{i}\n")
                self.prev = phase.copy()
                self.calls.append(frame["frame"])

            def close(self):
                self.f.close()
                self.calls.append("close")
                return super().close()

            def abort(self):
                self.f.close()
                self.calls.append("abort")
                super().abort()

        return LandingsWriter


def test_a_new_format_is_one_module_and_one_registry_line(taichi_cpu, tmp_path, monkeypatch):
    """A writer registered in FORMATS gets every frame in order, then close (the file appears under its
    name, complete); a writer that fails is aborted: nothing is left, not even the folder the export made."""
    import types

    from taichi_rocks.app.export import export_run
    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.output import formats

    for fail_at, out in ((None, tmp_path / "a" / "x.csv"), (3, tmp_path / "b" / "x.csv")):
        cls = _Landings.make(fail_at)
        module = types.ModuleType("taichi_rocks.output.landings")
        module.LandingsWriter = cls
        monkeypatch.setitem(sys.modules, module.__name__, module)
        monkeypatch.setitem(formats.FORMATS, "landings", ("landings", "LandingsWriter"))
        sim = Simulation(load_scene(MINIMAL), tumble=True)
        if fail_at is None:
            info = export_run(sim, out, 40, 30.0, fmt="landings")
            rows = out.read_text().splitlines()
            assert cls.calls == list(range(40)) + ["close"] and info["bytes"] == out.stat().st_size
            assert rows[0] == "frame,rock" and len(rows) > 1  # rocks thrown in 1.3 s have landed
            assert sorted(p.name for p in out.parent.iterdir()) == ["x.csv"]
        else:
            with pytest.raises(RuntimeError, match="disk full"):
                export_run(sim, out, 10, 30.0, fmt="landings")
            assert cls.calls == [0, 1, 2, "abort"] and not out.parent.exists()
        del sim  # one simulation at a time


# ---------------------------------------------------------------------------------------------- colours
def test_the_exports_colours_are_the_renderers():
    """output/looks.py computes the renderer's colours itself (output/ does not import render/): its numbers
    are render/looks.py's and render/rocklook.py's, its rock tints the renderer's resting-rock colour on random
    and edge-case ids, its wheel side the area-weighted mean of the side of render/meshes.py's wheel."""
    from taichi_rocks.output import looks as out
    from taichi_rocks.render import looks, rocklook
    from taichi_rocks.render.meshes import wheel

    assert (out.ROCK_GREY, out.ROCK_BROWN, out.ROCK_DARK) == (rocklook._GREY, rocklook._BROWN, rocklook._DARK)
    assert (out.TIRE_COLOR, out.TREAD_COLOR) == (looks.TIRE_COLOR, looks.TREAD_COLOR)
    np.testing.assert_allclose(out.GROUND_COLOR, (np.array(looks.GROUND_A) + looks.GROUND_B) / 2, atol=1e-15)
    rng = np.random.default_rng(5)
    ids = np.concatenate([rng.integers(0, 2 ** 31 - 1, 3000), [0, 1, 2 ** 31 - 1, 2 ** 32 - 1, 2 ** 32, 10 ** 12]])
    want = np.array([rocklook.rock_color(int(i)) for i in ids])
    np.testing.assert_allclose(out.rock_tints(ids), want, rtol=0, atol=1e-12)
    v, n, c, i = wheel(0.33, 0.22)
    tri = v[i.reshape(-1, 3)]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    side = np.abs(n[i[0::3], 1]) > 0.99
    mean = (c[i[0::3]][side] * area[side, None]).sum(axis=0) / area[side].sum()
    np.testing.assert_allclose(out.WHEEL_SIDE_COLOR, mean, atol=1e-12)
    palette = out.tint_palette()
    assert palette.shape == (out.TINTS, 3) and np.array_equal(palette, out.tint_palette())  # the same every time
    tints = out.rock_tints(np.arange(20000))
    near = palette[out.nearest_tint(tints, palette)]
    assert np.abs(near - tints).max() < 0.12 and np.sqrt(((near - tints) ** 2).sum(axis=1)).mean() < 0.05
    np.testing.assert_allclose(out.linear([0.0, 0.04045, 0.5, 1.0]), [0.0, 0.04045 / 12.92, 0.214041, 1.0],
                               atol=1e-6)


def test_usd_colours_are_the_renderers(runs):
    """Every mesh of the stage carries displayColor (linear: output/looks.py) and is bound to the one material,
    a UsdPreviewSurface whose diffuse colour reads it: the rocks' instances their renderer's colour, each
    prototype its tint, each rock the prototype of its shape in the tint nearest its own; the car its scene
    colour, its tires the renderer's tread blocks and rims, the ground the renderer's checker."""
    from pxr import Usd, UsdGeom, UsdShade

    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.output.instances import PROTOTYPES
    from taichi_rocks.output.looks import TINTS, linear, nearest_tint, tint_palette
    from taichi_rocks.output.usd import MATERIAL
    from taichi_rocks.render import looks
    from taichi_rocks.render.rocklook import rock_color

    stage = _stage(runs / "all.usdc")
    surface = UsdShade.Material.Get(stage, MATERIAL).ComputeSurfaceSource()[0]
    assert surface.GetIdAttr().Get() == "UsdPreviewSurface"
    reader = surface.GetInput("diffuseColor").GetConnectedSources()[0][0].source
    assert UsdShade.Shader(reader.GetPrim()).GetIdAttr().Get() == "UsdPrimvarReader_float3"
    assert UsdShade.Shader(reader.GetPrim()).GetInput("varname").Get() == "displayColor"
    meshes = [p for p in Usd.PrimRange(stage.GetPseudoRoot()) if p.IsA(UsdGeom.Mesh)]
    assert len(meshes) == 3 + 4 + PROTOTYPES * TINTS  # the ground, the car's body, glass and tires, the rocks
    for p in meshes:
        bound = UsdShade.MaterialBindingAPI(p).ComputeBoundMaterial()[0].GetPath()
        assert bound == ("/World/Looks/Glass" if p.GetName() == "Glass" else MATERIAL), p.GetPath()
        assert UsdGeom.Mesh(p).GetDisplayColorPrimvar().HasValue(), p.GetPath()

    def color(path):
        return np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath(path)).GetDisplayColorAttr().Get(), np.float64)

    palette = tint_palette()
    for k in range(PROTOTYPES):
        for j in range(TINTS):
            np.testing.assert_allclose(color(f"/World/Bed/Rocks/Prototypes/rock_{k}_{j}"), [linear(palette[j])],
                                       atol=1e-6)
    pi = UsdGeom.PointInstancer(stage.GetPrimAtPath("/World/Bed/Rocks"))
    pv = UsdGeom.PrimvarsAPI(pi).GetPrimvar("displayColor")
    assert pv.GetInterpolation() == UsdGeom.Tokens.vertex
    n = load_scene(MINIMAL).bed.rocks
    for f in (0, FRAMES // 2, FRAMES - 1):
        index = np.asarray(pi.GetIdsAttr().Get(f), np.int64) % n
        want = np.array([rock_color(int(i)) for i in index])
        np.testing.assert_allclose(np.asarray(pv.Get(f), np.float64), linear(want), atol=1e-6)
        proto = np.asarray(pi.GetProtoIndicesAttr().Get(f))
        assert np.array_equal(proto % TINTS, nearest_tint(want, palette)) and proto.max() < PROTOTYPES * TINTS
    scene = load_scene(MINIMAL)
    body = color("/World/Vehicles/car/Body")
    assert np.isclose(body, linear(scene.vehicles[0].color), atol=1e-6).all(axis=1).sum() >= 6  # its lower body
    np.testing.assert_allclose(color("/World/Vehicles/car/Glass"), linear([looks.GLASS_COLOR] * 4), atol=1e-6)
    assert UsdShade.MaterialBindingAPI(stage.GetPrimAtPath("/World/Vehicles/car/Glass")).ComputeBoundMaterial()[0] \
        .GetPath() == "/World/Looks/Glass"
    tire = color("/World/Vehicles/car/Wheel_RL/Tire")
    tread = [looks.TREAD_COLOR if k % 2 else looks.TIRE_COLOR for k in range(len(tire) - 2)]
    np.testing.assert_allclose(tire[:-2], linear(tread), atol=1e-6)
    np.testing.assert_allclose(color("/World/Ground/Plane"),
                               [linear((np.array(looks.GROUND_A) + looks.GROUND_B) / 2)], atol=1e-6)


@pytest.mark.parametrize("kind", ["car", "van", "truck"])
def test_usd_bodies_are_the_renderers(kind):
    """A vehicle's USD body is its parts (motion/bodies.py) with the faces the renderer draws in its colours:
    every face of the stage's Body and Glass meshes is a face of render/bodies.py's mesh, corner for corner,
    in the same colour (the lower body, which the renderer cuts round the wheels, in the scene's colour), and
    wound to face outwards; the glass faces are the renderer's glass."""
    from scenes_util import scene

    from taichi_rocks.output.usd import _body_meshes
    from taichi_rocks.render.bodies import vehicle_mesh
    from taichi_rocks.render.looks import GLASS_COLOR

    spec = scene(vehicles=[{"name": "v", "kind": kind, "length": 6.0, "width": 2.2, "height": 2.2, "wheelbase": 3.6,
                            "track": 1.9, "tire_radius": 0.4, "color": [0.2, 0.5, 0.8]}]).vehicles[0]
    m = vehicle_mesh(spec)
    body = m.wheel < 0
    quads = m.verts[body].reshape(-1, 4, 3)
    cols = m.cols[body].reshape(-1, 4, 3)[:, 0]
    norms = m.norms[body].reshape(-1, 4, 3)[:, 0]
    keys = {tuple(sorted(map(tuple, np.round(q, 9)))): (c, n) for q, c, n in zip(quads, cols, norms)}
    meshes = _body_meshes(spec)
    assert set(meshes) == {"Body", "Glass"}
    matched = 0
    for name, ((points, counts, idx), colors) in meshes.items():
        assert (counts == 4).all() and len(colors) == len(counts)
        for f, face in enumerate(points[idx].reshape(-1, 4, 3).astype(np.float64)):
            n = np.cross(face[1] - face[0], face[2] - face[0])  # the winding's normal (counter-clockwise)
            key = tuple(sorted(map(tuple, np.round(face, 5))))
            near = [k for k in keys if np.allclose(np.array(k), np.array(key), atol=1e-5)]
            if near:
                color, normal = keys[near[0]]
                np.testing.assert_allclose(colors[f], color, atol=1e-12)
                assert n @ normal > 0  # outwards, as the renderer's face
                matched += 1
            else:  # the lower body's faces: the renderer's are cut round the wheel wells
                np.testing.assert_allclose(colors[f], spec.color, atol=1e-12)
            if name == "Glass":
                np.testing.assert_allclose(colors[f], GLASS_COLOR, atol=1e-12)
    faces = sum(len(c) for _, c in meshes.values())
    assert matched == faces - (4 if kind != "truck" else 0)  # all but the lower body's sides, top and bottom
