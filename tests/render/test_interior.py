"""The driver's view (motion/cabin.py, render/interior.py): the cabin is the windscreen the body mesh draws, the
view from inside leaves out the greenhouse and draws the windscreen's frame, and the view frames the vehicle
ahead (its rear tires in the image every half second of the shipped scenes that use it and of test scenes, the
eye inside the player's body box, the frame hiding nothing of the vehicle ahead), in geometry and in pixels."""

import math

import numpy as np
import pytest

from scenes_util import scene as make_scene
from test_render import _first_hit, _framed_points, _in_frame, _ray_hits

W, H = 320, 192


def _kind_specs():
    from scenes_util import scene

    same = {"length": 6.0, "width": 2.2, "height": 2.2, "wheelbase": 3.6, "track": 1.9, "tire_radius": 0.4}
    return scene(vehicles=[{"name": k, "kind": k, **same, "path": {"points": [[0.0, 3.0 * i], [99.0, 3.0 * i]]}}
                           for i, k in enumerate(("car", "van", "truck"))]).vehicles


@pytest.mark.parametrize("k", range(3), ids=("car", "van", "truck"))
def test_the_cabin_is_the_windscreen_the_body_draws(k):
    """motion/cabin.py's windscreen is the glazed front face of render/bodies.py's mesh: its top corners are
    the face's, its foot the face's foot (which starts the 1 cm overlap below the belt line)."""
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.bodies import vehicle_mesh
    from taichi_rocks.render.looks import GLASS_COLOR

    spec = _kind_specs()[k]
    cab = cabin_of(spec)
    m = vehicle_mesh(spec)
    glass = np.all(np.isclose(m.cols, GLASS_COLOR), axis=1) & (m.wheel < 0) & (m.norms[:, 0] > 0.3)
    v = m.verts[glass]
    top, foot = v[v[:, 2] > cab.roof - 1e-9], v[v[:, 2] < cab.belt + 1e-9]
    assert len(top) and len(foot)
    np.testing.assert_allclose(np.unique(np.round(top[:, 0], 9)), [cab.top_x], atol=1e-9)
    np.testing.assert_allclose(np.unique(np.round(np.abs(top[:, 1]), 9)), [cab.top_half], atol=1e-9)
    np.testing.assert_allclose(np.abs(foot[:, 1]), cab.base_half, atol=1e-9)
    assert np.all(cab.belt - foot[:, 2] <= 0.0100001)
    x_at_foot = cab.windscreen_x(foot[:, 2])  # the face's foot lies on the cabin's windscreen plane
    np.testing.assert_allclose(foot[:, 0], x_at_foot, atol=2e-3 * spec.length)


@pytest.mark.parametrize("k", range(3), ids=("car", "van", "truck"))
def test_from_inside_the_greenhouse_is_left_out_and_the_bonnet_stays(k):
    """From the driver's eye, rays through the windscreen's opening (inside the pillars, below the header, above
    the dashboard and the bonnet) leave the vehicle in the view from inside, where they met the glass outside;
    the frame is drawn (the ray to a pillar's middle meets it) and the floor below the eye stays."""
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.bodies import vehicle_mesh
    from taichi_rocks.render.interior import PILLAR, interior_of

    spec = _kind_specs()[k]
    cab = cabin_of(spec)
    inter = interior_of(spec, vehicle_mesh(spec))
    m = inter.mesh
    eye = np.array(cab.eye)
    inside = m.verts[inter.triangles(True).reshape(-1, 3)]
    outside = m.verts[inter.triangles(False).reshape(-1, 3)]
    rng = np.random.default_rng(7)
    u_eye = (eye[2] - cab.belt) / (cab.roof - cab.belt)
    for _ in range(200):  # points on the glass above the eye, inside its frame, then 20 m on along the ray
        u, v = rng.uniform(u_eye + 0.02, 0.85), rng.uniform(-0.6, 0.6)
        z = cab.belt + u * (cab.roof - cab.belt)
        half = cab.base_half + u * (cab.top_half - cab.base_half)
        p = np.array([cab.windscreen_x(z), v * half, z])
        far = eye + (p - eye) * 20.0 / np.linalg.norm(p - eye)
        assert np.isinf(_ray_hits(eye, far, inside)).all(), p
        assert np.isfinite(_ray_hits(eye, far, outside)).any(), p  # outside, the glass is in the way
    for v in np.linspace(-0.5, 0.5, 11):  # down over the dashboard and the bonnet's front edge: nothing in the way
        edge = np.array([cab.front_x + 0.01, v * cab.base_half, cab.bonnet_z + 0.02])
        assert np.isinf(_ray_hits(eye, eye + 3.0 * (edge - eye), inside)).all(), v
    z = cab.belt + 0.5 * (cab.roof - cab.belt)
    half = cab.base_half + 0.5 * (cab.top_half - cab.base_half)
    pillar = np.array([cab.windscreen_x(z) - 0.01, half - 0.5 * PILLAR * cab.width, z])
    assert np.isfinite(_ray_hits(eye, eye + 1.5 * (pillar - eye), inside)).any()
    floor = eye + np.array([0.0, 0.0, -(eye[2] - cab.belt) * 1.5])  # straight down: the cabin's floor
    assert np.isfinite(_ray_hits(eye, floor, inside)).any()


def _ahead_scenes():
    """Test scenes the driver's view must frame: round a 40 m circle at 20 m/s (1/2 rad/s: the gaze lags the
    heading by ~9 degrees), the player 6 m behind the vehicle ahead (bumper to bumper, as in the convoy),
    as a car behind a van turning left, a van behind a truck turning
    right, a truck behind a car turning left."""
    bodies = {"car": {}, "van": {"length": 5.0, "width": 2.0, "height": 2.0, "wheelbase": 3.2, "track": 1.75,
                                 "tire_radius": 0.36},
              "truck": {"length": 8.0, "width": 2.5, "height": 3.2, "wheelbase": 5.0, "track": 2.1,
                        "tire_radius": 0.5, "tire_width": 0.3}}
    R = 40.0
    out = []
    for player, ahead, cw in (("car", "van", False), ("van", "truck", True), ("truck", "car", False)):
        gap = 6.0 + 0.5 * (bodies[ahead].get("length", 4.5) + bodies[player].get("length", 4.5))
        turn = math.degrees(gap / R) * (-1.0 if cw else 1.0)
        circle = {"kind": "circle", "radius": R, "speed": 20.0, "clockwise": cw}
        out.append(make_scene(rocks=0, duration=8.0, camera={"view": "driver"}, vehicles=[
            {"name": "player", "kind": player, **bodies[player], "path": circle},
            {"name": "ahead", "kind": ahead, **bodies[ahead], "path": {**circle, "start_angle": turn}}]))
    return out


def _shipped_driver_scenes(scenes_dir):
    from taichi_rocks.config.scene import load_scene

    found = []
    for path in sorted(scenes_dir.glob("*.toml")):
        s = load_scene(path)
        if "driver" in [x.view for x in s.camera.shots] + [s.camera.view]:
            found.append(s)
    return found


def _body_frame(pose, p):
    c, s = math.cos(pose.heading), math.sin(pose.heading)
    d = np.asarray(p, float) - pose.position
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]])


def test_the_drivers_view_frames_the_vehicle_ahead(scenes_dir):
    """Every half second of the driver's view in the shipped scenes that use it (the convoy from its cut) and
    in the test scenes: the eye is inside the player's body box, both rear tires of the vehicle ahead project
    inside the image, and (the shipped scenes) the windscreen's frame hides no point of the back of the vehicle
    ahead that the rest of the player's body does not hide already."""
    from taichi_rocks.motion.vehicles import Fleet
    from taichi_rocks.render.bodies import scene_meshes
    from taichi_rocks.render.camera import Lens, look_at_time, scene_camera
    from taichi_rocks.render.interior import interior_of
    from taichi_rocks.render.meshes import pose_mesh

    shipped = _shipped_driver_scenes(scenes_dir)
    assert [s.name for s in shipped] == ["convoy"]
    checked = 0
    for scene in shipped + _ahead_scenes():
        cam, fleet = scene_camera(scene), Fleet(scene)
        meshes = scene_meshes(scene)
        tan_x, tan_y, _ = Lens.of(scene.camera.fov, *scene.render.resolution)
        fps = scene.render.fps
        for k in range(int(scene.duration * fps) + 1):
            t = k / fps
            poses = fleet.poses(t)
            view = look_at_time(cam, poses, t, np.zeros(3))
            if k % int(fps / 2) or cam.shot.view != "driver":
                continue
            me = cam.shot.rides
            spec, pose = scene.vehicles[me], poses[me]
            x, y, z = _body_frame(pose, view.eye)
            z0 = 0.8 * spec.tire_radius
            assert abs(x) < spec.length / 2 and abs(y) < spec.width / 2 and z0 < z < z0 + spec.height, (t, x, y, z)
            ahead = min((i for i in range(len(poses)) if i != me and _body_frame(pose, poses[i].position)[0] > 0),
                        key=lambda i: _body_frame(pose, poses[i].position)[0])
            tires, _ = _framed_points(scene, ahead, poses[ahead], meshes[ahead], view.eye)
            for _, _, face in tires:
                assert _in_frame(view, tan_x, tan_y, face, margin=0.02), (scene.name, t, face)
            if scene in shipped:
                _frame_hides_nothing_ahead(scene, meshes, poses, me, ahead, view, interior_of, pose_mesh)
            checked += 1
    assert checked == 13 + 3 * 17  # 6 s of the convoy, 8 s of each test scene: 2 a second, both ends


def _frame_hides_nothing_ahead(scene, meshes, poses, me, ahead, view, interior_of, pose_mesh):
    """Rays from the eye to a grid over the back of the vehicle ahead meet the same first vehicle triangle with
    the windscreen's frame as without it."""
    inter = interior_of(scene.vehicles[me], meshes[me])
    n_body = len(meshes[me].idx) // 3
    keep = inter.inside.copy()
    keep[n_body:] = False  # the same view from inside, without the frame
    mine = pose_mesh(inter.mesh, poses[me].position, poses[me].heading)[0][inter.mesh.idx.reshape(-1, 3)]
    with_frame, without = mine[inter.inside], mine[keep]
    spec = scene.vehicles[ahead]
    c, s = math.cos(poses[ahead].heading), math.sin(poses[ahead].heading)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    others = [pose_mesh(m, p.position, p.heading) for i, (m, p) in enumerate(zip(meshes, poses)) if i != me]
    z0 = 0.8 * spec.tire_radius
    for y in np.linspace(-0.45, 0.45, 7) * spec.width:
        for z in np.linspace(0.05, z0 + spec.height - 0.05, 7):
            target = poses[ahead].position + rot @ np.array([-spec.length / 2 - 0.03, y, z])
            near = _first_hit(view.eye, target, others, [m for i, m in enumerate(meshes) if i != me])[2]
            a, b = _ray_hits(view.eye, target, with_frame).min(), _ray_hits(view.eye, target, without).min()
            assert (a < near) == (b < near), (y, z)  # the frame adds no occluder in front of the vehicle ahead


@pytest.fixture(scope="module")
def driver_frame(taichi_cpu, scenes_dir):
    """A frame of the convoy's driver's shot (5 s: a second after the cut), its renderer's view and poses."""
    from taichi_rocks.config.scene import load_scene, scene_with
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.render.renderer import Renderer

    scene = scene_with(load_scene(scenes_dir / "convoy.toml"), {"bed.rocks": 3000, "bed.radius": 12.0})
    sim = Simulation(scene, arch="cpu")
    r = Renderer(sim, resolution=(W, H), window_every=0)
    try:
        for k in range(0, 151, 5):  # the camera stepped on the way: the render's frames, a few of them
            sim.advance_to(k / 30.0)
            r.view()
        img = r.render_frame().copy()
        view = r.view()
        assert r.rig.shot.view == "driver"
        return img, view, sim.vehicle_poses(), np.asarray(sim.origin, np.float64), scene, r.inside
    finally:
        r.close()


def _pixel(view, tan_x, tan_y, p):
    d = p - view.eye
    z = d @ view.fwd
    return int((d @ view.right / (z * tan_x) + 1) / 2 * W), int((1 - (d @ view.up / (z * tan_y) + 1) / 2) * H)


def _lit(color, pad=3):
    """The range of 8-bit pixel values of ``color`` lit as GGUI lights it: ambient only to ambient + full sun."""
    from taichi_rocks.render.looks import AMBIENT, SUN_COLOR

    c = np.array(color)
    return c * np.array(AMBIENT) * 255 - pad, np.minimum(c * (np.array(AMBIENT) + np.array(SUN_COLOR)) * 255 + pad, 255)


def test_drawn_from_the_drivers_seat_the_truck_ahead_shows_through_the_frame(driver_frame):
    """Pixels: where the renderer's camera projects the truck's two tail lights and the middle of its back,
    the frame shows them (their colours, lit as GGUI lights them); where it projects the left A-pillar and the
    dashboard, it shows the interior's colours: the view is from inside (the player's own interior drawn)."""
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.camera import Lens
    from taichi_rocks.render.interior import PILLAR
    from taichi_rocks.render.looks import DASHBOARD_COLOR, PILLAR_COLOR, TAIL_LIGHT_COLOR

    img, view, poses, origin, scene, inside = driver_frame
    assert inside == 0  # the player's cabin
    tan_x, tan_y, _ = Lens.of(scene.camera.fov, W, H)
    truck = scene.vehicle_index("truck")
    spec, pose = scene.vehicles[truck], poses[truck]
    c, s = math.cos(pose.heading), math.sin(pose.heading)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    z0 = 0.8 * spec.tire_radius
    lz = z0 + min(0.18, 0.12 * spec.height) + 0.06 * spec.height  # render/bodies.py _trim: the lights' height
    lo, hi = _lit(TAIL_LIGHT_COLOR)
    for side in (1.0, -1.0):
        light = pose.position - origin + rot @ np.array([-spec.length / 2 - 0.036, side * 0.38 * spec.width, lz])
        px, py = _pixel(view, tan_x, tan_y, light)
        assert 0 <= px < W and 0 <= py < H
        patch = img[py - 1:py + 2, px - 1:px + 2].reshape(-1, 3).astype(float)
        assert (np.all((patch >= lo) & (patch <= hi), axis=1)).sum() >= 5, (side, patch)
    back = pose.position - origin + rot @ np.array([-spec.length / 2 - 0.01, 0.25 * spec.width, z0 + 0.6 * spec.height])
    px, py = _pixel(view, tan_x, tan_y, back)
    lo, hi = _lit(np.array(spec.color) * 0.8)  # the cargo box's back (render/bodies.py _truck)
    patch = img[py - 1:py + 2, px - 1:px + 2].reshape(-1, 3).astype(float)
    assert (np.all((patch >= lo) & (patch <= hi), axis=1)).sum() >= 5, patch
    cab = cabin_of(scene.vehicles[0])
    me = poses[0]
    c, s = math.cos(me.heading), math.sin(me.heading)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    z = cab.belt + 0.5 * (cab.roof - cab.belt)
    half = cab.base_half + 0.5 * (cab.top_half - cab.base_half)
    pillar = me.position - origin + rot @ np.array([cab.windscreen_x(z) - 0.01, half - 0.5 * PILLAR * cab.width, z])
    dash = me.position - origin + rot @ np.array([cab.base_x - 0.04 * cab.length, 0.0, cab.belt + 0.005])
    for point, color in ((pillar, PILLAR_COLOR), (dash, DASHBOARD_COLOR)):
        px, py = _pixel(view, tan_x, tan_y, point)
        assert 0 <= px < W and 0 <= py < H, point
        lo, hi = _lit(color)
        assert np.all((img[py, px] >= lo) & (img[py, px] <= hi)), (color, img[py, px])
