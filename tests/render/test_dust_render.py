"""Dust's drawing (render/dust.py): the window's particles' colour and radius laws against NumPy; the offscreen
puffs: their projection, radius law and vehicle occlusion against known answers, their compositing against a
NumPy reference (soft depth test, the 3D layer's pixels, order independence); nothing made without dust, and a
frame of a run with dust that differs from the same frame without it only by the dust."""

import numpy as np
import pytest

from scenes_util import scene
from taichi_rocks.config.effects.dust import Dust
from taichi_rocks.engine.simulation import Simulation
import taichi as ti

from taichi_rocks.render import dust as D
from taichi_rocks.render.camera import Lens
from taichi_rocks.render.dust import MIN_ALPHA, draw_dust, dust_looks
from taichi_rocks.render.looks import KEY
from taichi_rocks.render.looks import GROUND_A, GROUND_B
from taichi_rocks.render.renderer import Renderer
from taichi_rocks.engine.trees import FieldTrees

W, H = 160, 96


def test_colour_blends_towards_what_lies_behind_and_radius_shrinks():
    t = Dust(color=(0.5, 0.4, 0.3), size=0.1)
    haze = (0.9, 0.9, 1.0)
    alpha = np.array([0.0, 0.25, 1.0], np.float32)
    col, rad = dust_looks(alpha, t, haze)
    behind = (np.array(haze) + (np.array(GROUND_A) + np.array(GROUND_B)) / 2) / 2
    np.testing.assert_allclose(col, alpha[:, None] * np.array([0.5, 0.4, 0.3]) + (1 - alpha[:, None]) * behind,
                               atol=1e-6)
    np.testing.assert_allclose(rad, 0.1 * (0.4 + 0.6 * alpha), rtol=1e-6)
    assert 0 < MIN_ALPHA < 0.1


def test_without_dust_nothing_is_made():
    sim = Simulation(scene(rocks=50))
    assert draw_dust(None, None, sim, np.zeros(3), (1.0, 1.0, 1.0)) is None


def _frame(dust: bool):
    sc = scene(rocks=300, duration=3.0, effects={"dust": dust}, dust={"rate": 5.0, "size": 0.05},
               render={"shadows": False}, camera={"view": "chase"})
    sim = Simulation(sc, tumble=True)
    r = Renderer(sim, resolution=(W, H), fps=10, window_every=0)
    for f in range(9):
        sim.advance_to(f / 10)
        img = r.render_frame().copy()
    n = len(sim.effect_arrays().get("dust", {"positions": []})["positions"])
    r.close()
    return img, n


def test_a_frame_with_dust_shows_it():
    off, n_off = _frame(False)
    on, n_on = _frame(True)
    assert n_off == 0 and n_on > 100  # 5 (10 - 3)^2 particles/s for 0.8 s: 196
    changed = np.any(off != on, axis=2)
    assert changed.mean() > 0.01  # the dust covers some of the frame
    assert changed[: H // 4].mean() < changed[H // 4:].mean()  # low, behind the car: not the sky at the top


LENS = Lens.of(60.0, W, H)
FWD, RIGHT, UP = np.array([1.0, 0, 0]), np.array([0, -1.0, 0]), np.array([0, 0, 1.0])  # looking along +x


def test_a_puff_projects_where_the_camera_sees_it_and_grows_with_its_age():
    t = Dust(size=0.1, diffusion=0.5, fade=2.0, opacity=0.8)
    eye = np.zeros(3)
    ages = np.array([0.0, 1.0, 3.0])
    alpha = 0.8 * np.exp(-ages / 2.0)
    np.testing.assert_allclose(D.puff_radius(alpha, t), 0.1 + np.sqrt(2 * 0.5 * ages), rtol=1e-6)
    local = np.array([[10.0, 0.0, 0.0], [20.0, -2.0, 1.0], [-5.0, 0.0, 0.0]])  # ahead, ahead right-up, behind
    rows, a, reach, hidden = D.puffs(local, alpha, t, eye, FWD, RIGHT, UP, LENS, (W, H))
    assert len(rows) == 2 and not hidden.any()  # the one behind the eye is not drawn
    np.testing.assert_allclose(rows[0, :2], [W / 2, H / 2], atol=1e-4)
    np.testing.assert_allclose(rows[0, 2:], [0.1 * LENS.px_per_rad / 10.0, 10.0], rtol=1e-5)
    np.testing.assert_allclose(rows[1, :2], [W / 2 + 2 * LENS.px_per_rad / 20, H / 2 + LENS.px_per_rad / 20],
                               rtol=1e-5)
    np.testing.assert_allclose(a, D.PUFF * alpha[:2], rtol=1e-6)
    np.testing.assert_allclose(reach, D.puff_radius(alpha[:2], t), rtol=1e-6)


def test_a_vehicle_between_the_eye_and_a_puff_hides_it():
    eye = np.array([0.0, 0.0, 1.0])
    box = (5.0, 0.0, 0.3, 2.0, 1.0, 0.0, 1.5)  # centre x, y, heading, half length, half width, bottom, top
    d = np.array([[1.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0]])
    hidden = D._hidden_by_boxes(eye, d, np.array([10.0, 2.0, 10.0]), [box])
    assert hidden.tolist() == [True, False, False]  # behind the box; in front of it; beside it
    inside = (0.0, 0.0, 0.0, 2.0, 1.0, 0.0, 1.5)  # the cabin the eye sits in hides nothing
    assert not D._hidden_by_boxes(eye, d, np.array([10.0, 2.0, 10.0]), [inside]).any()


def _numpy_dust(rows, alpha, reach, hidden, near, key, out, color, own=None, frame=None):
    """The compositing of render/dust.py in NumPy: optical depths summed per pixel of a half-resolution image
    (background: the soft fraction in front of ``near`` at the middle of the pixel's 2 x 2; the 3D layer (``key``
    False): unless hidden, the soft fraction in front of ``own``, the half-resolution depth of the vehicle the eye
    rides in), T = exp(-sum) interpolated bilinearly to each pixel, then c T + c_dust (1 - T), but not over the
    3D layer's pixels of its windscreen's ``frame`` (full resolution)."""
    W2, H2 = (W + 1) // 2, (H + 1) // 2
    tau = np.zeros((2, W2, H2))
    ii, jj = np.meshgrid(np.arange(W2), np.arange(H2), indexing="ij")
    z = near[np.minimum(2 * ii + 1, W - 1), np.minimum(2 * jj + 1, H - 1)]
    own = np.full((W2, H2), D.FAR) if own is None else own
    for (x, y, pr, depth), a0, r, hid in zip(rows * [0.5, 0.5, 0.5, 1.0], alpha, reach, hidden):
        s2 = ((ii + 0.5 - x) ** 2 + (jj + 0.5 - y) ** 2) / pr ** 2
        a = np.where(s2 < 1, np.minimum(a0 * (1 - s2) ** 2, 0.99), 0.0)
        front = np.clip((z - depth + r) / (2 * r), 0.0, 1.0)
        tau[0] += -np.log(1 - a * front)
        mine = np.clip((own - depth + r) / (2 * r), 0.0, 1.0)
        tau[1] += 0.0 if hid else -np.log(1 - a * mine)
    trans = np.exp(-np.round(tau * D.TAU_ONE) / D.TAU_ONE)
    X, Y = np.meshgrid((np.arange(W) + 0.5) * 0.5 - 0.5, (np.arange(H) + 0.5) * 0.5 - 0.5, indexing="ij")
    i0, j0 = np.floor(X).astype(int), np.floor(Y).astype(int)
    fx, fy = X - i0, Y - j0
    T = np.zeros((2, W, H))
    for di in (0, 1):
        for dj in (0, 1):
            w = (fx if di else 1 - fx) * (fy if dj else 1 - fy)
            T += w * trans[:, np.clip(i0 + di, 0, W2 - 1), np.clip(j0 + dj, 0, H2 - 1)]
    t = np.where(key, T[0], np.where(frame if frame is not None else False, 1.0, T[1])).T[::-1][..., None]
    return np.where(t < 0.999, out * t + np.asarray(color) * 255.0 * (1 - t), out)


def _solids(rng, n=3):
    """Random parallelepipeds (corner and three edges) 1.5 to 6 m ahead of an eye at 0 looking along +x, filling
    about a fifth of the view."""
    out = []
    for _ in range(n):
        corner = np.array([rng.uniform(1.5, 4.0), rng.uniform(-2.0, 0.5), rng.uniform(-1.2, 0.2)])
        edges = np.diag(rng.uniform(0.8, 2.0, 3)) + rng.uniform(-0.3, 0.3, (3, 3))
        out.append(np.vstack([corner, edges]))
    return np.array(out)


def _march(solids, w, h, step=1e-3, far=12.0):
    """The depth (along +x) at which the ray of each pixel (x, y up; the camera of LENS at 0 looking along +x)
    first lies inside one of ``solids``, found by walking along it in steps of ``step`` and testing the six
    face planes of each solid (inf: none): a reference that shares nothing with the kernels' slabs."""
    px, py = np.meshgrid((np.arange(w) + 0.5) * 2 / w - 1, (np.arange(h) + 0.5) * 2 / h - 1, indexing="ij")
    d = FWD + (px * LENS.tan_x)[..., None] * RIGHT + (py * LENS.tan_y)[..., None] * UP  # (w, h, 3)
    depth = np.full((w, h), np.inf)
    ts = np.arange(0.0, far, step)
    for corner, *edges in solids:
        inside = np.ones((w, h, len(ts)), bool)
        for k in range(3):  # between the two faces spanned by the other two edges
            a, b = edges[(k + 1) % 3], edges[(k + 2) % 3]
            n = np.cross(a, b)
            n = n if n @ edges[k] > 0 else -n
            lo, hi = n @ corner, n @ (corner + edges[k])
            proj = (d @ n)[..., None] * ts
            inside &= (proj >= lo) & (proj <= hi)
        first = np.where(inside.any(axis=2), ts[np.argmax(inside, axis=2)], np.inf)
        depth = np.minimum(depth, first)
    return depth


def test_rays_enter_the_solids_where_a_walk_along_them_does(taichi_cpu):
    """_own_depth: each half-resolution pixel's depth of the nearest solid its ray enters (FAR: none), against
    a walk along the ray (within its step, where the walk's step does not skip a grazed corner)."""
    rng = np.random.default_rng(5)
    w, h = 40, 24
    solids = _solids(rng)
    own = FieldTrees(owner=D).image(w, h, (1, ti.f32))
    rows = D.solid_rows(solids, np.zeros(3), FWD, RIGHT, UP)
    D._own_depth(own, rows, len(rows), Lens.of(60.0, W, H).tan_x, Lens.of(60.0, W, H).tan_y)
    got = own.to_numpy()
    want = _march(solids, w, h)
    hit = np.isfinite(want)
    assert 0.1 < hit.mean() < 0.9
    agree = np.where(hit, np.abs(got - want) <= 2e-3, got >= D.FAR)
    assert agree.mean() > 0.99, np.argwhere(~agree)


def test_compositing_matches_numpy_and_ignores_the_order_of_the_puffs(taichi_cpu):
    rng = np.random.default_rng(3)
    k = 40
    rows = np.stack([rng.uniform(-5, W + 5, k), rng.uniform(-5, H + 5, k), rng.uniform(1, 30, k),
                     rng.uniform(2, 20, k)], axis=1).astype(np.float32)
    alpha, reach = rng.uniform(0, 0.4, k).astype(np.float32), rng.uniform(0.2, 2, k).astype(np.float32)
    hidden = (rng.uniform(size=k) < 0.3).astype(np.int32)
    near = rng.uniform(1, 25, (W, H)).astype(np.float32)  # a rock's depth at each pixel
    near[: W // 3] = np.inf  # no rock: the sky
    key = rng.uniform(size=(W, H)) < 0.8  # where GGUI drew nothing
    raw = np.where(key[..., None], np.array([*KEY, 255]) / 255.0, 0.2).astype(np.float32)
    out0 = rng.integers(0, 256, (H, W, 3)).astype(np.uint8)
    color = (0.55, 0.48, 0.38)

    class Buf:
        splat = True
    trees = FieldTrees(owner=Buf)
    Buf.zbuf = trees.image(W, H, (1, ti.i64))
    bits = near.astype(np.float32).view(np.int32).astype(np.int64) << 24
    Buf.zbuf.from_numpy(np.where(np.isinf(near), np.int64(0x7FFFFFFF) << 32, bits))
    layer = D.SoftDust(W, H)
    own = np.where(rng.uniform(size=((W + 1) // 2, (H + 1) // 2)) < 0.5, rng.uniform(1, 25), D.FAR)
    layer.own.from_numpy(own.astype(np.float32))  # the depth of the vehicle the eye rides in, where it is
    solids = _solids(rng)
    frame_rows = D.solid_rows(solids, np.zeros(3), FWD, RIGHT, UP)
    images = []
    half_rows = rows * np.array([0.5, 0.5, 0.5, 1.0], np.float32)  # what SoftDust.splat hands the kernel
    for order in (np.arange(k), rng.permutation(k)):
        out = out0.copy()
        for half, idx in D._by_square(half_rows[order]):
            sel = order[idx]
            D._splat(layer.tau, half_rows[sel], alpha[sel], reach[sel], hidden[sel], Buf.zbuf, True, half, layer.own)
        D._blend(layer.tau, out, raw, ti.math.vec3(*color), frame_rows, len(frame_rows), LENS.tan_x, LENS.tan_y)
        images.append(out)
    assert np.array_equal(images[0], images[1])  # integer sums: the same frame in any order
    frame = np.isfinite(_march(solids, W, H, step=0.01))
    assert 0.05 < frame.mean() < 0.5
    want = _numpy_dust(rows, alpha, reach, hidden, near, key, out0.astype(np.float64), color, own.astype(np.float32),
                       frame)
    off = np.abs(images[0].astype(np.float64) - want).max(axis=2) > 1.0  # one step of rounding
    assert off.mean() < 0.002, off.sum()  # and a few pixels whose centre a ray grazes a solid's edge at
    assert np.count_nonzero(images[0] != out0) > 0.1 * out0.size
    assert not layer.tau.to_numpy().any()  # cleared for the next frame


CONVOY_DUST = {
    "name": "dusty", "duration": 3.0, "seed": 5,
    "effects": {"dust": True}, "dust": {"rate": 12.0, "size": 0.12, "lift_speed": 2.0},
    "bed": {"radius": 6.0, "rocks": 400, "rock_radius": [0.02, 0.05], "follow": "player"},
    "camera": {"view": "driver", "follow": "player"}, "render": {"shadows": False},
    "vehicle": [{"name": "player", "splash": False, "path": {"points": [[0.0, 0.0], [200.0, 0.0]], "speed": 14.0}},
                {"name": "truck", "kind": "truck", "path": {"points": [[14.0, 0.0], [214.0, 0.0]], "speed": 14.0}}],
}


def test_a_resumed_render_with_dust_gives_the_uninterrupted_frames(taichi_cpu, tmp_path):
    """A truck's dust seen from the driver's seat behind it: interrupted after frame 6 with states saved after
    frames 2 and 5, the render resumes from the state after frame 5, whose dust it restores, and draws frames
    7 to 9 byte for byte as the render that was not interrupted."""
    import imageio.v3 as iio

    from taichi_rocks.app.render import render_scene
    from taichi_rocks.config.scene import parse_scene

    scene = parse_scene(CONVOY_DUST, source="<test>")
    kw = dict(frames=10, resolution=(W, H), fps=10.0, fmt="png", progress=False)
    render_scene(scene, out_dir=tmp_path / "ref", **kw)

    def stop(k, img):
        if k == 7:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render_scene(scene, out_dir=tmp_path / "cut", on_frame=stop, checkpoint_every=3, **kw)
    saved = sorted((tmp_path / "cut" / ".resume").glob("frame_*.npz"))
    assert [p.name for p in saved] == ["frame_00002.npz", "frame_00005.npz"]
    with np.load(saved[-1]) as z:
        assert np.count_nonzero((z["dust_age"] >= 0) & (z["dust_age"] < scene.dust.life)) > 50  # dust to carry
    res = render_scene(scene, out_dir=tmp_path / "cut", resume=True, checkpoint_every=3, **kw)
    assert res["resumed_from"] == 7 and res["replayed_from"] == 6
    for k in range(7, 10):
        want = iio.imread(tmp_path / "ref" / "frames" / f"frame_{k:05d}.png")
        got = iio.imread(tmp_path / "cut" / "frames" / f"frame_{k:05d}.png")
        assert np.array_equal(got, want), f"frame {k}: {np.count_nonzero(np.any(got != want, axis=2))} pixels differ"


def _cloud_frames(view: str, cloud: np.ndarray, size: float = 0.15):
    """The frame of a parked car seen from ``view`` with the dust particles at ``cloud`` (world, (K, 3): put in
    through a checkpoint, a tenth of a second old), and the same frame without them; and the car's pose."""
    car = {"name": "car", "path": {"points": [[0.0, 0.0], [50.0, 0.0]], "speed": 0.0}}
    sc = scene(rocks=300, radius=5.0, duration=3.0, vehicles=[car], effects={"dust": True},
               dust={"size": size, "diffusion": 0.0, "life": 10.0, "fade": 10.0, "opacity": 1.0},
               render={"shadows": False}, camera={"view": view})
    sim = Simulation(sc, tumble=True)
    sim.advance_to(0.2)
    cp = sim.checkpoint().as_dict()
    r = Renderer(sim, resolution=(2 * W, 2 * H), fps=10, window_every=0)
    frames = []
    for dusty in (True, False):
        age = np.full_like(cp["dust_age"], -1.0)
        pos = cp["dust_pos"].copy()
        if dusty:
            age[:len(cloud)] = 0.1
            pos[:len(cloud)] = cloud - cp["origin"]
        sim.restore({**cp, "dust_age": age, "dust_pos": pos})
        frames.append(r.render_frame().copy())
    r.close()
    return frames[0], frames[1], sim.vehicle_poses()[0]


def _grid(x, y, z, n=16) -> np.ndarray:
    """A block of dust particles, n per side, over the ranges x, y, z (world m)."""
    axes = [np.linspace(lo, hi, n) for lo, hi in (x, y, z)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _red(img: np.ndarray) -> np.ndarray:
    """The pixels of the car's paint (red, lit or in shade)."""
    img = img.astype(int)
    return (img[..., 0] > 100) & (img[..., 0] > 2 * img[..., 1]) & (img[..., 0] > 2 * img[..., 2])


def _shrunk(mask: np.ndarray, px: int) -> np.ndarray:
    """``mask`` without the pixels within ``px`` of its edge."""
    out = mask.copy()
    for _ in range(px):
        out[1:-1, 1:-1] &= out[:-2, 1:-1] & out[2:, 1:-1] & out[1:-1, :-2] & out[1:-1, 2:]
        out[[0, -1]] = False
        out[:, [0, -1]] = False
    return out


def test_from_the_drivers_seat_no_dust_is_drawn_over_the_own_cabin_and_bonnet():
    """A thick cloud ahead of a parked car seen from its driver's seat: it shows through the windscreen, but no
    pixel of the car's own dashboard, pillars, header and lining (dark) or its bonnet (red, the lower half of the
    frame) changes: the frame lies inside the glass, the bonnet in front of the cloud."""
    with_dust, without, pose = _cloud_frames("driver", _grid((6.0, 16.0), (-5.0, 5.0), (0.1, 3.5)))
    dark = without.astype(int).max(axis=2) < 50
    red = _red(without)
    red[: H] = False  # the upper half (of 2 H rows)
    own = _shrunk(dark, 1) | _shrunk(red, 2)
    changed = np.any(with_dust != without, axis=2)
    assert own.mean() > 0.2 and _shrunk(dark, 1).sum() > 200 and _shrunk(red, 2).sum() > 50
    assert changed.mean() > 0.15  # the cloud, through the glass
    assert not changed[own].any(), f"{int(changed[own].sum())} pixels of the own car changed"


def test_a_puff_behind_a_vehicle_is_hidden_where_the_vehicle_is_drawn():
    """The chase camera behind a parked car, a cloud beyond the car: it shows around the car, and not one pixel
    of the car (its red paint and its windows, away from its edges by more than a puff's radius) changes."""
    with_dust, without, pose = _cloud_frames("chase", _grid((2.5, 6.0), (-2.0, 2.0), (0.05, 1.5)))
    img = without.astype(int)
    glass = (img[..., 2] > img[..., 0] + 20) & (img[..., 2] < 130) & (img[..., 0] < 90)  # its windows, blue-grey
    car = _shrunk(_red(without) | glass, 4)
    changed = np.any(with_dust != without, axis=2)
    assert car.sum() > 300
    assert changed[~car].sum() > 1000  # the cloud, around the car
    assert not changed[car].any(), f"{int(changed[car].sum())} pixels of the car changed"
