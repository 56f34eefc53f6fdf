"""Dust's drawing (render/dust.py): the window's particles' colour and radius laws against NumPy; the offscreen
puffs: their projection, radius law and vehicle occlusion against known answers, their compositing against a
NumPy reference (soft depth test, the 3D layer's pixels, order independence); nothing made without dust, and a
frame of a run with dust that differs from the same frame without it only by the dust."""

import numpy as np

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


def _numpy_dust(rows, alpha, reach, hidden, near, key, out, color):
    """The compositing of render/dust.py in NumPy: optical depths summed per pixel of a half-resolution image
    (background: the soft fraction in front of ``near`` at the middle of the pixel's 2 x 2; the 3D layer (``key``
    False): unless hidden), T = exp(-sum) interpolated bilinearly to each pixel, then c T + c_dust (1 - T)."""
    W2, H2 = (W + 1) // 2, (H + 1) // 2
    tau = np.zeros((2, W2, H2))
    ii, jj = np.meshgrid(np.arange(W2), np.arange(H2), indexing="ij")
    z = near[np.minimum(2 * ii + 1, W - 1), np.minimum(2 * jj + 1, H - 1)]
    for (x, y, pr, depth), a0, r, hid in zip(rows * [0.5, 0.5, 0.5, 1.0], alpha, reach, hidden):
        s2 = ((ii + 0.5 - x) ** 2 + (jj + 0.5 - y) ** 2) / pr ** 2
        a = np.where(s2 < 1, np.minimum(a0 * (1 - s2) ** 2, 0.99), 0.0)
        front = np.clip((z - depth + r) / (2 * r), 0.0, 1.0)
        tau[0] += -np.log(1 - a * front)
        tau[1] += 0.0 if hid else -np.log(1 - a)
    trans = np.exp(-np.round(tau * D.TAU_ONE) / D.TAU_ONE)
    X, Y = np.meshgrid((np.arange(W) + 0.5) * 0.5 - 0.5, (np.arange(H) + 0.5) * 0.5 - 0.5, indexing="ij")
    i0, j0 = np.floor(X).astype(int), np.floor(Y).astype(int)
    fx, fy = X - i0, Y - j0
    T = np.zeros((2, W, H))
    for di in (0, 1):
        for dj in (0, 1):
            w = (fx if di else 1 - fx) * (fy if dj else 1 - fy)
            T += w * trans[:, np.clip(i0 + di, 0, W2 - 1), np.clip(j0 + dj, 0, H2 - 1)]
    t = np.where(key, T[0], T[1]).T[::-1][..., None]  # (H, W, 1), row 0 at the top
    return np.where(t < 0.999, out * t + np.asarray(color) * 255.0 * (1 - t), out)


def test_compositing_matches_numpy_and_ignores_the_order_of_the_puffs():
    from taichi_rocks.engine.trees import FieldTrees

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
    half_rows = rows * np.array([0.5, 0.5, 0.5, 1.0], np.float32)  # what SoftDust.splat hands the kernel
    images = []
    for order in (np.arange(k), rng.permutation(k)):
        out = out0.copy()
        for half, idx in D._by_square(half_rows[order]):
            sel = order[idx]
            D._splat(layer.tau, half_rows[sel], alpha[sel], reach[sel], hidden[sel], Buf.zbuf, True, half)
        D._blend(layer.tau, out, raw, ti.math.vec3(*color))
        images.append(out)
    assert np.array_equal(images[0], images[1])  # integer sums: the same frame in any order
    want = _numpy_dust(rows, alpha, reach, hidden, near, key, out0.astype(np.float64), color)
    assert np.abs(images[0].astype(np.float64) - want).max() <= 1.0  # one step of rounding
    assert np.count_nonzero(images[0] != out0) > 0.1 * out0.size
    assert not layer.tau.to_numpy().any()  # cleared for the next frame
