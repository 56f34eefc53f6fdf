"""Flying rocks drawn as tumbling rock meshes (render/tumbling.py): every drawn rock's vertices and normals are
its prototype (motion/rockshapes.py, chosen by its id) scaled by its radius and turned by the engine's
quaternion (NumPy reference, on the engine's own flying rocks and on adversarial orientations), at the level of
detail its projected size asks for; the mesh is drawn where the rock projects; without tumbling the meshes are
compiled out; and only the commands that draw or export orientations (render, view, export) ask the engine
for them: ``simulate``'s Plan has no spin and its world no spin or orientation fields. The coarse level of
detail (motion/rockshapes.py) keeps the fine rock's volume, against closed forms."""

import gc

import numpy as np
import pytest

from taichi_rocks.config.scene import load_scene
from taichi_rocks.config.streams import LOOK_PROTOTYPE
from taichi_rocks.engine import drawing
from taichi_rocks.engine.rockfields import FLYING
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.engine.world import IPar
from taichi_rocks.motion.rockshapes import flat_triangles
from taichi_rocks.render import tumbling
from taichi_rocks.render.camera import NEAR
from taichi_rocks.render.renderer import Renderer
from taichi_rocks.render.rocklook import _unit_np

pytestmark = pytest.mark.usefixtures("taichi_cpu")

W, H = 320, 180


def np_rotate(q, p):
    """R(q) p for unit quaternions q = (x, y, z, w) (rows), points p (rows): q p q*."""
    v, w = q[..., :3], q[..., 3:]
    t = 2.0 * np.cross(v, p)
    return p + w * t + np.cross(v, t)


def np_prototype(rid):
    return np.minimum((_unit_np(rid, LOOK_PROTOTYPE.first) * tumbling.PROTOTYPES).astype(np.int64),
                      tumbling.PROTOTYPES - 1)


@pytest.fixture(scope="module")
def tumbling_sim(scenes_dir):
    sim = Simulation(load_scene(scenes_dir / "minimal.toml"), arch="cpu", tumble=True)
    r = Renderer(sim, resolution=(W, H), window_every=0)
    sim.advance_to(0.6)
    yield sim, r
    r.close()


def _rocks(sim):
    """The listed rocks (engine/drawing.py: with active stepping the active list; flying rocks are in it)."""
    w = sim.world
    n = int(w.ipar[IPar.N_ROCKS])
    return tuple(f.to_numpy()[:n] for f in (w.pos, w.radius, w.phase, w.rock_id, w.orient))


def _check_drawn(r, sim, eye, fwd):
    """Every rock in the mesh bucket against the NumPy reference; returns the drawn rocks' indices per level."""
    pos, rad, phase, rid, orient = _rocks(sim)
    _, _, meshes, counts = r.rock_layer.drawn
    m_pos, m_rad = meshes.pos.to_numpy(), meshes.rad.to_numpy()
    drawn = []
    for lod, n in enumerate(counts):
        protos = [flat_triangles(k, coarse=lod == tumbling.COARSE) for k in range(tumbling.PROTOTYPES)]
        nv = tumbling.VERTICES[lod]
        vbo = meshes.vertices(lod, n).reshape(n, nv, tumbling.VBO_STRIDE)
        got = []
        for j in range(n):
            c = m_pos[lod * meshes.cap + j]
            i = int(np.argmin(np.linalg.norm(pos.astype(np.float32) - c, axis=1)))
            assert np.array_equal(pos[i].astype(np.float32), c) and phase[i] == FLYING
            assert m_rad[lod * meshes.cap + j] == np.float32(rad[i])
            z = max(float((pos[i] - eye) @ fwd), NEAR)
            pr = rad[i] * r.px_per_rad / z
            if abs(pr - tumbling.FINE_PX) > 1e-3:  # f32 against f64 at the threshold
                assert (pr >= tumbling.FINE_PX) == (lod == tumbling.FINE), (pr, lod)
            q = orient[i] / np.linalg.norm(orient[i])
            pts, nrm = protos[int(np_prototype(rid[i]))]
            want = pos[i] + rad[i] * np_rotate(q[None], pts.astype(np.float64))
            np.testing.assert_allclose(vbo[j, :, 0:3], want, atol=2e-5 + 2e-6 * np.abs(want).max())
            np.testing.assert_allclose(vbo[j, :, 3:6], np_rotate(q[None], nrm.astype(np.float64)), atol=2e-5)
            assert np.all(vbo[j, :, 11] == 1.0)
            got.append(i)
        assert len(set(got)) == len(got)  # no rock twice
        drawn.append(got)
    return drawn


def _cull(r, eye, fwd, right, up):
    return r.cull(eye, fwd, right, up, r.sun_direction(0.0))


def test_flying_rocks_are_their_prototype_turned_by_the_engines_orientation(tumbling_sim):
    """The engine's own flying rocks (launched by the tread, turned by their integrated spin), seen from close
    by: both levels of detail are drawn, each rock once, as its prototype turned by its quaternion."""
    sim, r = tumbling_sim
    pos, rad, phase, _, orient = _rocks(sim)
    flying = phase == FLYING
    assert flying.sum() > 5
    assert np.abs(orient[flying][:, 3]).min() < 0.999  # they have turned
    view = r.view()
    fwd = view.fwd
    c = pos[flying].mean(axis=0)
    k = np.nonzero(flying)[0][np.argmin(np.linalg.norm(pos[flying] - c, axis=1))]
    right, up = view.right, view.up
    levels = set()
    for eye in (pos[k] - 0.4 * fwd, c - 1.2 * fwd):  # one rock close by (fine), then all a little further
        eye = eye.astype(np.float32)
        _cull(r, eye, fwd, right, up)
        drawn = _check_drawn(r, sim, eye, fwd)
        levels |= {lod for lod, d in enumerate(drawn) if d}
    assert levels == {tumbling.FINE, tumbling.COARSE}
    # and every flying rock in view of at least MESH_PX pixels is among them
    d = pos - eye
    z = d @ fwd
    inside = (z > NEAR + rad) & (np.abs(d @ right) < z * r.tan_x - rad) & (np.abs(d @ up) < z * r.tan_y - rad)
    big = flying & inside & (rad * r.px_per_rad / np.maximum(z, NEAR) > tumbling.MESH_PX + 1e-3)
    assert set(np.nonzero(big)[0]) <= set(drawn[0]) | set(drawn[1])


@pytest.mark.parametrize("q", [(1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 1e-7), (0.3, -0.5, 0.1, -0.8),
                               (2.0, 0.0, 0.0, 2.0)], ids=["half-turn-x", "w~0", "w<0", "not-unit"])
def test_a_placed_rock_is_turned_and_drawn_where_it_projects(tumbling_sim, q):
    """Adversarial orientations (a half turn, w ~ 0, w < 0, a quaternion of norm 2.8: drawn normalised) on a
    big flying rock in front of the camera: its vertices are the reference's, and the frame shows it there."""
    sim, r = tumbling_sim
    view = r.view()
    target = view.eye + 3.0 * view.fwd + 0.4 * view.right
    w = sim.world
    i = 0
    old = (w.pos[i], w.radius[i], w.phase[i], w.orient[i])
    try:
        w.radius[i] = 0.15
        w.phase[i] = FLYING
        w.pos[i] = (view.eye - 5.0 * view.fwd).tolist()  # behind the camera
        before = r.render_frame().copy()
        w.pos[i] = target.tolist()
        w.orient[i] = list(q)
        after = r.render_frame().copy()
        _cull(r, view.eye, view.fwd, view.right, view.up)
        drawn = _check_drawn(r, sim, view.eye, view.fwd)
    finally:
        w.pos[i], w.radius[i], w.phase[i], w.orient[i] = old
    assert i in drawn[tumbling.FINE]
    diff = np.abs(after.astype(int) - before.astype(int)).sum(axis=2) > 30
    z = float((target - view.eye) @ view.fwd)
    px = ((target - view.eye) @ view.right / (z * r.tan_x) + 1) / 2 * W
    py = (1 - ((target - view.eye) @ view.up / (z * r.tan_y) + 1) / 2) * H
    rad = 0.15 * r.px_per_rad / z
    ys, xs = np.nonzero(diff)
    near = (xs - px) ** 2 + (ys - py) ** 2 < (1.6 * rad + 2) ** 2
    assert near.sum() > 0.4 * np.pi * rad ** 2, (near.sum(), rad)
    assert abs(xs[near].mean() - px) < 0.4 * rad + 1 and abs(ys[near].mean() - py) < 0.4 * rad + 1


def test_without_orientations_flying_rocks_stay_particles(scenes_dir):
    """A simulation that does not tumble (no orientations) draws no mesh: the rock pass compiles them out. The
    renderer gives every SNode tree it made back when it closes (engine/trees.py: Taichi allows 512 a process):
    its buffers and its vehicles' fields to the pool, free for the next renderer of their sizes; the next
    renderer makes no new buffer and no new vehicle field."""
    from taichi_rocks.render.buffers import POOL

    gc.collect()  # the renderers of earlier tests are given back now, not during this one
    sim = Simulation(load_scene(scenes_dir / "minimal.toml"), arch="cpu")
    assert not drawing.has_orientations(sim.world)
    with Renderer(sim, resolution=(W, H), window_every=0) as r:
        sim.advance_to(0.6)
        view = r.view()
        pos, phase = sim.world.pos.to_numpy(), sim.world.phase.to_numpy()
        eye = (pos[phase == FLYING].mean(axis=0) - 1.2 * view.fwd).astype(np.float32)
        n = _cull(r, eye, view.fwd, view.right, view.up)
        _, count, meshes, counts = r.rock_layer.drawn
        assert not meshes.on and counts == (0, 0) and count == n > 0
        assert r.rock_layer.protos is None
        fields = r.fields
        made = fields.trees.count
        assert made >= 4  # buffers, buckets: each a tree of its own
        assert not POOL.is_free(fields)
    # kept for the next renderer (destroyed when the process runs short of trees)
    assert POOL.is_free(fields)
    with Renderer(sim, resolution=(W, H), window_every=0) as again:
        assert again.fields is fields and not POOL.is_free(fields)
        r.close()  # a second close of the first renderer leaves the buffers with the second
        assert not POOL.is_free(fields)
        assert _cull(again, eye, view.fwd, view.right, view.up) == n
        assert fields.trees.count == made  # no new buffer
    assert POOL.is_free(fields)


class _Stop(Exception):
    pass


def _asked(monkeypatch, module, call):
    """The keyword arguments ``call`` builds its Simulation with (stopped there)."""
    seen = {}

    def fake(scene, **kw):
        seen.update(kw)
        raise _Stop

    monkeypatch.setattr(module, "Simulation", fake)
    with pytest.raises(_Stop):
        call()
    return seen


def test_only_render_view_and_export_ask_for_orientations(monkeypatch, scenes_dir, tmp_path):
    """render, view and export build their Simulation with tumbling; simulate does not, and the Simulation it
    builds has no spin in its Plan and no spin or orientation field (nothing allocated, nothing compiled)."""
    from taichi_rocks.app import export, render, simulate, view

    scene = load_scene(scenes_dir / "minimal.toml")
    asks = {
        "simulate": _asked(monkeypatch, simulate, lambda: simulate.simulate_scene(scene, out=tmp_path / "s.npz",
                                                                                   frames=1, progress=False)),
        "render": _asked(monkeypatch, render, lambda: render.render_scene(scene, out_dir=tmp_path / "r", frames=1,
                                                                          resolution=(W, H), fmt="png",
                                                                          progress=False)),
        "view": _asked(monkeypatch, view, lambda: view.Viewer(scene)),
        "export": _asked(monkeypatch, export, lambda: export.export_scene(scene, out=tmp_path / "e.usd",
                                                                          frames=1)),
    }
    assert {k: bool(v.get("tumble")) for k, v in asks.items()} == {"simulate": False, "render": True,
                                                                    "view": True, "export": True}
    monkeypatch.undo()
    plain = Simulation(scene, **asks["simulate"])
    assert not plain.plan.spin
    assert not any(f.name in ("spin", "orient") for f in plain.world.rocks)
    assert not hasattr(plain.world, "spin") and not hasattr(plain.world, "orient")
    assert not drawing.has_orientations(plain.world)


def test_the_coarse_prototype_is_the_fine_one_on_the_icosahedron_at_the_same_volume():
    """The level of detail for small rocks: the fine rock's first 12 points (the icosahedron's), scaled to its
    volume, faces outward; ``volume`` against closed forms (a unit cube's 12 triangles, a turned-in one)."""
    from taichi_rocks.motion.rockshapes import rock_prototype, volume

    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                      [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    assert volume(cube * 2.0 + 5.0, faces) == pytest.approx(8.0)
    assert volume(cube, faces[:, ::-1]) == pytest.approx(-1.0)
    for k in range(tumbling.PROTOTYPES):
        fp, _, fi = rock_prototype(k)
        cp, counts, ci = rock_prototype(k, coarse=True)
        assert len(cp) == 12 and len(counts) == 20 and np.all(counts == 3)
        v_fine, v_coarse = volume(fp, fi.reshape(-1, 3)), volume(cp, ci.reshape(-1, 3))
        assert v_coarse == pytest.approx(v_fine, rel=1e-5) and v_fine > 0
        s = np.linalg.norm(cp, axis=1) / np.linalg.norm(fp[:12], axis=1)
        assert np.allclose(s, s[0], rtol=1e-5) and s[0] > 1.0  # the same points, pushed out to hold the volume
        tri = cp.astype(np.float64)[ci.reshape(-1, 3)]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        assert np.all(np.einsum("ij,ij->i", n, tri.mean(axis=1)) > 0)  # every face outward
