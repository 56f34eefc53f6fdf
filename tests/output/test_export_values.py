"""Exported values, not only their counts: the vehicles' and the camera's USD transforms against the simulation's
poses and the camera rig, ``--crop`` around the camera's followed vehicle (USD, and the same rocks as a cropped
run file), PLY ``--only flying``, and the light run layout across a step of the floating origin, in f32 and f64.

Commands run in this process (``taichi_rocks.cli.main``); every scene has the minimal scene's 2,000-rock bed, so
they share its compiled World (the f64 one compiles once more)."""

import math

import numpy as np
import pytest

from cli_util import ROOT
from taichi_rocks import load_run

MINIMAL = ROOT / "scenes" / "minimal.toml"
FRAMES, FPS = 20, 10.0  # 2 s
CROP = 5.0  # m

# A car on a circle (its heading passes 180 deg at t = pi/2 s: the exported headings must not jump) followed
# by the bed and the chase camera, which looks at a van driving straight 18 m away (its tires throw nothing).
PAIR = """name = "pair"
duration = 2.0
[bed]
radius = 8.0
rocks = 2000
rock_radius = [0.02, 0.05]
[sim]
detection = "patch"
dt = 0.004
[[vehicle]]
name = "car"
path = { kind = "circle", center = [0.0, 0.0], radius = 12.0, speed = 12.0 }
[[vehicle]]
name = "van"
splash = false
length = 5.0
height = 2.0
path = { points = [[30.0, 0.0], [60.0, 0.0]], speed = 5.0 }
[camera]
target = "van"
"""
CAR_SPEED, VAN_SPEED, TIRE_R, SLIP = 12.0, 5.0, 0.33, 0.15  # the scene's speeds, the default tire and slip


def _cli(*args):
    from taichi_rocks.cli import main

    assert main([str(a) for a in args]) == 0


@pytest.fixture(scope="module")
def pair(taichi_cpu, tmp_path_factory):
    """The pair scene: USD (every rock; --crop), PLY --only flying, the full run and a cropped light run."""
    d = tmp_path_factory.mktemp("pair")
    scene = d / "pair.toml"
    scene.write_text(PAIR)
    common = ("--frames", FRAMES, "--fps", FPS)
    _cli("export", scene, "--out", d / "all.usdc", *common)
    _cli("export", scene, "--out", d / "crop.usdc", "--crop", CROP, *common)
    _cli("export", scene, "--format", "ply", "--out", d / "flying", "--only", "flying", *common)
    _cli("simulate", scene, "--out", d / "full.npz", "--layout", "full", *common)
    _cli("simulate", scene, "--out", d / "crop.npz", "--crop", CROP, *common)
    return d


def _stage(path):
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    assert stage, path
    return stage


def _world(stage, prim, t) -> np.ndarray:
    """The prim's local-to-world matrix at time code ``t`` (row vectors, as USD composes them)."""
    from pxr import UsdGeom

    return np.array(UsdGeom.Xformable(stage.GetPrimAtPath(prim)).ComputeLocalToWorldTransform(t), np.float64)


def _ids(stage, t) -> np.ndarray:
    from pxr import UsdGeom

    return np.asarray(UsdGeom.PointInstancer(stage.GetPrimAtPath("/World/Bed/Rocks")).GetIdsAttr().Get(t), np.int64)


# ---------------------------------------------------------------------------------------------- vehicles
def test_usd_vehicle_transforms_are_the_simulated_poses(pair):
    stage, run = _stage(pair / "all.usdc"), load_run(pair / "full.npz")
    np.testing.assert_allclose(run["time"], np.arange(FRAMES) / FPS, rtol=0, atol=1e-12)
    assert list(run["vehicle_names"]) == ["car", "van"]
    rotate = {name: stage.GetPrimAtPath(f"/World/Vehicles/{name}").GetAttribute("xformOp:rotateZ")
              for name in ("car", "van")}
    previous = None
    for f in range(FRAMES):
        for i, name in enumerate(("car", "van")):
            m = _world(stage, f"/World/Vehicles/{name}", f)
            h = float(run["vehicle_headings"][f][i])
            np.testing.assert_array_equal(m[3, :3], run["vehicle_positions"][f][i])  # double: the same metres
            np.testing.assert_allclose(m[0, :3], [math.cos(h), math.sin(h), 0.0], atol=1e-12)  # body x: forward
            np.testing.assert_allclose(m[2, :3], [0.0, 0.0, 1.0], atol=1e-12)  # upright
        car_deg = rotate["car"].Get(f)
        assert math.remainder(car_deg - math.degrees(run["vehicle_headings"][f][0]), 360.0) == pytest.approx(0.0,
                                                                                                           abs=1e-9)
        if previous is not None:  # unwrapped: never the long way round between two frames
            assert 0.0 < car_deg - previous < 10.0, (f, previous, car_deg)  # ccw, 5.7 deg per frame
        previous = car_deg
    # the car went past 180 deg (heading 90 + 57.3 t deg) without a jump back to -180
    assert rotate["car"].Get(FRAMES - 1) == pytest.approx(90.0 + math.degrees((FRAMES - 1) / FPS), abs=1e-6)
    assert rotate["van"].Get(FRAMES - 1) == pytest.approx(0.0, abs=1e-9)


def test_usd_wheels_turn_by_the_distance_driven(pair):
    """Front wheels: distance / tire radius; rear wheels (1 + slip) faster: the tread speed."""
    stage = _stage(pair / "all.usdc")
    for f in (1, FRAMES // 2, FRAMES - 1):
        t = f / FPS
        for name, speed, tol in (("car", CAR_SPEED, 2e-3), ("van", VAN_SPEED, 1e-6)):  # car: chords of a circle
            ops = {w: stage.GetPrimAtPath(f"/World/Vehicles/{name}/Wheel_{w}").GetAttribute("xformOp:rotateY")
                   for w in ("FL", "FR", "RL", "RR")}
            front = math.degrees(speed * t / TIRE_R)
            assert ops["FL"].Get(f) == ops["FR"].Get(f) == pytest.approx(front, rel=tol), (name, f)
            assert ops["RL"].Get(f) == ops["RR"].Get(f) == pytest.approx(front * (1 + SLIP), rel=tol), (name, f)


# ---------------------------------------------------------------------------------------------- camera
def test_usd_camera_is_the_rig_looking_at_the_target(pair):
    """The camera's transform is the scene's rig (motion/camera.py camera_of: the renderer's) fed the simulated
    poses frame by frame; at frame 0 (the rig snaps) it is also the chase preset in closed form: the eye 9 m
    behind and 3.5 m above the car, looking 6 m ahead of the van."""
    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.motion.camera import CHASE_OFFSET, camera_of

    stage, run = _stage(pair / "all.usdc"), load_run(pair / "full.npz")
    scene = load_scene(pair / "pair.toml")
    rig, rides, target = camera_of(scene)
    assert (rides, target) == (0, 1)  # rides with the car, looks at the van
    for f in range(FRAMES):
        pos, head = run["vehicle_positions"][f], run["vehicle_headings"][f]
        eye, look_at, _ = rig.update(pos[0], float(head[0]), float(run["time"][f]), (pos[1], float(head[1])))
        m = _world(stage, "/World/Camera", f)
        np.testing.assert_allclose(m[3, :3], eye, rtol=0, atol=1e-9)
        forward = (look_at - eye) / np.linalg.norm(look_at - eye)
        np.testing.assert_allclose(-m[2, :3], forward, atol=1e-9)  # a USD camera looks down its -Z
        assert abs(m[0, 2]) < 1e-12 and m[1, 2] > 0  # no roll: right horizontal, up upwards
        if f == 0:
            h = float(head[0])
            rot = np.array([[math.cos(h), -math.sin(h), 0.0], [math.sin(h), math.cos(h), 0.0], [0.0, 0.0, 1.0]])
            np.testing.assert_allclose(m[3, :3], pos[0] + rot @ np.array(CHASE_OFFSET), atol=1e-9)
            aim = pos[1] + np.array([scene.camera.look_ahead, 0.0, 0.0])  # the van heads along +x
            np.testing.assert_allclose(-m[2, :3], (aim - m[3, :3]) / np.linalg.norm(aim - m[3, :3]), atol=1e-9)


# ---------------------------------------------------------------------------------------------- selection
def _within(run, f, vehicle, radius):
    d = run["positions"][f][:, :2] - run["vehicle_positions"][f][vehicle][:2]
    return d[:, 0] ** 2 + d[:, 1] ** 2 <= radius ** 2


def test_usd_crop_keeps_the_rocks_around_the_followed_vehicle(pair):
    """--crop R around camera.follow (the car), as the cropped run file does, also though the camera looks at
    the van (the export once cropped around the van: no rocks at all)."""
    stage, run, light = _stage(pair / "crop.usdc"), load_run(pair / "full.npz"), load_run(pair / "crop.npz")
    n = len(run["radii"])
    assert stage.GetRootLayer().customLayerData["crop"] == CROP
    kept = 0
    for f in range(FRAMES):
        rock = np.sort(_ids(stage, f) % n)
        near_car = np.flatnonzero(_within(run, f, 0, CROP))
        np.testing.assert_array_equal(rock, near_car)
        np.testing.assert_array_equal(rock, np.flatnonzero(~np.isnan(light["positions"][f][:, 0])))
        assert not _within(run, f, 1, CROP).any()  # nothing near the van: cropping there would keep nothing
        kept += len(rock)
    assert kept > FRAMES * 0.2 * n  # (5/8)^2 of the bed


def _read_ply(path):
    header, _, body = path.read_bytes().partition(b"end_header\n")
    lines = header.decode("ascii").splitlines()
    count = int(next(x for x in lines if x.startswith("element vertex")).split()[2])
    from taichi_rocks.output.ply import VERTEX

    assert len(body) == count * VERTEX.itemsize
    return np.frombuffer(body, dtype=VERTEX)


def test_ply_only_flying_keeps_what_moves(pair):
    """--only flying: the rocks in the air or sliding and those that moved since the previous frame (frame 0:
    only the moving ones), at the run's world positions and velocities."""
    run = load_run(pair / "full.npz")
    n = len(run["radii"])
    files = sorted((pair / "flying").iterdir())
    assert [p.name for p in files] == [f"frame_{f:05d}.ply" for f in range(FRAMES)]
    written = 0
    for f, path in enumerate(files):
        rows = _read_ply(path)
        rock = rows["id"].astype(np.int64) % n
        moving = (run["velocities"][f] != 0).any(axis=1)
        moved = (run["positions"][f] != run["positions"][f - 1]).any(axis=1) if f else np.zeros(n, bool)
        np.testing.assert_array_equal(np.sort(rock), np.flatnonzero(moving | moved))
        world = np.stack([rows["x"], rows["y"], rows["z"]], axis=1)
        np.testing.assert_array_equal(world, run["positions"][f][rock])
        np.testing.assert_array_equal(np.stack([rows["vx"], rows["vy"], rows["vz"]], axis=1),
                                      run["velocities"][f][rock])
        written += len(rows)
    assert 0 < written < 0.2 * FRAMES * n  # far fewer than every rock; some did move


# ---------------------------------------------------------------------------------------------- light layout
@pytest.fixture(scope="module")
def fast(taichi_cpu, tmp_path_factory):
    """The minimal scene at 80 m/s (the bed drives 152 m in 1.9 s: the floating origin steps), in f32 and f64,
    each as a light (the default) and a full run."""
    d = tmp_path_factory.mktemp("fast")
    text = MINIMAL.read_text().replace("points = [[0.0, 0.0], [40.0, 0.0]], speed = 10.0",
                                       "points = [[0.0, 0.0], [400.0, 0.0]], speed = 80.0")
    assert "speed = 80.0" in text
    for real in ("f32", "f64"):
        scene = d / f"{real}.toml"
        scene.write_text(text.replace('dt = 0.004', f'dt = 0.004\nprecision = "{real}"'))
        common = ("--frames", FRAMES, "--fps", FPS)
        _cli("simulate", scene, "--out", d / f"{real}_light.npz", *common)
        _cli("simulate", scene, "--out", d / f"{real}_full.npz", "--layout", "full", *common)
    return d


@pytest.mark.parametrize("real", ["f32", "f64"])
def test_light_layout_across_an_origin_step_gives_the_full_run(fast, real):
    """The rows are relative to the origin of their frame: across the step the positions load_run gives are
    the full layout's (f32: bit for bit; f64: the rows keep f64, within a float64 rounding of the world
    position, 1e-13 m here, where f32 rows would be off by micrometres)."""
    with np.load(fast / f"{real}_light.npz") as z:
        origin, local = z["origin"], z["row_local"]
    steps = np.flatnonzero(np.any(np.diff(origin, axis=0) != 0, axis=1))
    assert len(steps) == 1, origin[:, 0]  # one step, in the middle of the run
    jump = origin[steps[0] + 1] - origin[steps[0]]
    assert jump[0] >= 64.0 and jump[0] % 64.0 == 0 and not jump[1:].any()
    assert local.dtype == np.dtype(np.float32 if real == "f32" else np.float64)
    light, full = load_run(fast / f"{real}_light.npz"), load_run(fast / f"{real}_full.npz")
    assert set(light) == set(full)
    for k in full:
        if k == "positions" and real == "f64":
            err = np.max(np.abs(light[k] - full[k]))
            assert err <= 1e-12, err
        else:
            np.testing.assert_array_equal(light[k], full[k], err_msg=k)
    moved = full["positions"][-1, :, 0] - full["positions"][0, :, 0]
    assert full["bed_center"][-1, 0] - full["bed_center"][0, 0] == pytest.approx(80.0 * (FRAMES - 1) / FPS)
    assert (moved > 100.0).any()  # rocks recycled ahead of the bed: their rows are relative to the new origin


# ---------------------------------------------------------------------------------------------- shots
def test_usd_camera_follows_the_shots_and_holds_at_the_cuts(taichi_cpu, tmp_path):
    """The shots scene exported at 10 frames/s: the camera of every frame is the shot's rig at that time
    (tests/shots_util.py: chase until 0.75 s, the car's driver's seat, then beside the van), and at each cut
    (frames 8 and 14) the frame before is written again STEP_HOLD before it, so that a tool interpolating between
    the samples cuts instead of flying the camera from one shot to the next; nowhere else an extra sample."""
    from shots_util import CUTS, expected_eyes, write_shots_scene
    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.output.usd import STEP_HOLD

    path = write_shots_scene(tmp_path)
    _cli("export", path, "--out", tmp_path / "shots.usdc", "--frames", FRAMES, "--fps", FPS)
    stage = _stage(tmp_path / "shots.usdc")
    want, _ = expected_eyes(load_scene(path), [f / FPS for f in range(FRAMES)])
    for f in range(FRAMES):
        np.testing.assert_allclose(_world(stage, "/World/Camera", f)[3, :3], want[f], rtol=0, atol=1e-9)
    cuts = [int(np.ceil(c * FPS - 1e-9)) for c in CUTS]
    assert cuts == [8, 14]
    samples = stage.GetPrimAtPath("/World/Camera").GetAttribute("xformOp:transform").GetTimeSamples()
    assert samples == sorted([float(f) for f in range(FRAMES)] + [c - STEP_HOLD for c in cuts])
    for c in cuts:
        held = _world(stage, "/World/Camera", c - STEP_HOLD)
        np.testing.assert_array_equal(held, _world(stage, "/World/Camera", c - 1))
        assert np.linalg.norm(want[c] - want[c - 1]) > 1.0  # a cut: the eye jumps
