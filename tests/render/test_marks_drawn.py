"""Marks as drawn (render/hits.py through the Renderer, GGUI offscreen): hits on the windscreen change the pixels
of the glass and nothing else, seen from the driver's seat (the cabin's frame and the dashboard hide what lies
behind them) and from outside; hits on the bonnet and the front leave a paint chip on the face they hit, and
nothing elsewhere. Synthetic hits (no flash: they are a second old) on scenes/minimal.toml's car, 320x180."""

import math

import numpy as np
import pytest

from events_util import event_rows

W, H = 320, 180
T = 1.0  # s: the frame's time; the hits are a second older, long past their flash


@pytest.fixture(scope="module")
def drawn(taichi_cpu, scenes_dir):
    from taichi_rocks.config.scene import load_scene
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.render.renderer import Renderer

    sim = Simulation(load_scene(scenes_dir / "minimal.toml"), arch="cpu")
    r = Renderer(sim, resolution=(W, H), window_every=0)
    sim.advance_to(T)
    yield sim, r
    r.close()


def _events(rows):
    n = len(rows)
    return event_rows(rows, thrower=-1, time=T - 1.0, step=np.arange(n) + 10, rock=np.arange(n) + 100,
                      normal_speed=30.0)


def _glass_hits(cab):
    """Cracks all over the windscreen, the largest the measure allows, some at its edges (they run off it)."""
    n = np.array([cab.roof - cab.belt, 0.0, cab.base_x - cab.top_x])
    n /= np.linalg.norm(n)
    rows = []
    for u, y in ((0.5, 0.0), (0.1, 0.3), (0.85, -0.4), (0.3, cab.base_half - 0.03), (0.6, -cab.base_half + 0.05),
                 (0.05, -0.2), (0.95, 0.1)):
        z = cab.belt + u * (cab.roof - cab.belt)
        rows.append({"point": (cab.windscreen_x(z) - 0.006, y, z), "normal": n, "part": 2, "damage": 2,
                     "normal_momentum": 1.0})
    return _events(rows)


def _draw(r, view=None, events=None):
    """A frame with ``events`` as the only hits (None: none)."""
    r.hits.hits.clear()
    if events is not None:
        r.hits.hits.update(events, T)
    return r.render_frame(view).copy()


def _outside_view(sim, r, offset, look):
    """A view from ``offset`` in the car's frame towards ``look`` (m, car frame)."""
    from taichi_rocks.render.camera import frame_of

    pose = sim.vehicle_poses()[0]
    c, s = math.cos(pose.heading), math.sin(pose.heading)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    base = np.asarray(pose.position, np.float64) - np.asarray(sim.origin, np.float64)
    return frame_of((base + rot @ offset).astype(np.float32), (base + rot @ look).astype(np.float32), pose.heading)


def _rays(r, view, ys, xs):
    u = ((xs + 0.5) / W * 2.0 - 1.0) * r.tan_x
    v = ((H - ys - 0.5) / H * 2.0 - 1.0) * r.tan_y
    return view.fwd.astype(np.float64)[None] + u[:, None] * view.right[None] + v[:, None] * view.up[None]


def _to_body(sim, view, d):
    """The eye and the rays ``d`` in the car's body frame."""
    pose = sim.vehicle_poses()[0]
    c, s = math.cos(pose.heading), math.sin(pose.heading)
    inv = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    base = np.asarray(pose.position, np.float64) - np.asarray(sim.origin, np.float64)
    return inv @ (view.eye.astype(np.float64) - base), d @ inv.T


def _on_the_glass(sim, view, r, ys, xs, cab):
    """Per pixel: does its ray meet the windscreen's plane inside the glass?"""
    o, d = _to_body(sim, view, _rays(r, view, ys, xs))
    n = np.array([cab.roof - cab.belt, 0.0, cab.base_x - cab.top_x])
    t = ((np.array([cab.base_x, 0.0, cab.belt]) - o) @ n) / (d @ n)
    p = o + t[:, None] * d
    u = (p[:, 2] - cab.belt) / (cab.roof - cab.belt)
    return (t > 0) & (u >= 0) & (u <= 1) & (np.abs(p[:, 1]) <= cab.base_half + u * (cab.top_half - cab.base_half))


def _nearest_surface(o, d, tri):
    """Per ray from ``o`` along rows of ``d``: the nearest t (in units of d) at which it meets a triangle."""
    best = np.full(len(d), np.inf)
    for k in range(0, len(tri), 256):
        t = tri[k:k + 256]
        e1, e2 = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]
        p = np.cross(d[:, None], e2[None])
        det = np.einsum("ntk,tk->nt", p, e1)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = o - t[:, 0]
        a = np.einsum("ntk,tk->nt", p, s) * inv
        q = np.cross(s, e1)
        b = np.einsum("nk,tk->nt", d, q) * inv
        tt = np.einsum("tk,tk->t", e2, q)[None] * inv
        hit = ok & (a >= 0) & (b >= 0) & (a + b <= 1) & (tt > 1e-4)
        best = np.minimum(best, np.where(hit, tt, np.inf).min(axis=1))
    return best


@pytest.mark.parametrize("where", ["driver", "front", "front_left"])
def test_cracks_change_the_glass_and_nothing_else(drawn, where):
    """With cracks all over the windscreen, some reaching past its edges: pixels change, and every one that does
    lies on the glass's projection and on no surface nearer than the glass (the cabin's frame, the dashboard:
    from the driver's seat); every pixel off the glass is the same as without hits."""
    from taichi_rocks.motion.cabin import cabin_of

    sim, r = drawn
    cab = cabin_of(sim.scene.vehicles[0])
    view = None
    if where == "driver":
        r.set_view("driver")
        r.view()
    else:
        r.set_view("chase")
        r.view()
        y = 0.0 if where == "front" else 2.5
        view = _outside_view(sim, r, np.array([6.0, y, 2.4]), np.array([cab.base_x, 0.0, cab.belt + 0.3]))
    bare = _draw(r, view)
    marked = _draw(r, view, _glass_hits(cab))
    if view is None:
        view = r.view()
    changed = np.any(marked != bare, axis=2)
    ys, xs = np.nonzero(changed)
    assert changed.sum() > 150, changed.sum()
    on = _on_the_glass(sim, view, r, ys, xs, cab)
    assert on.all(), list(zip(xs[~on], ys[~on]))[:10]
    o, d = _to_body(sim, view, _rays(r, view, ys, xs))
    vs = r.vehicles  # the frame's vertices (local) and the triangles drawn from where the camera is
    pose = sim.vehicle_poses()[0]
    c, s = math.cos(pose.heading), math.sin(pose.heading)
    inv = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    base = np.asarray(pose.position, np.float64) - np.asarray(sim.origin, np.float64)
    tri = (vs.frame[vs.layouts[r.inside].reshape(-1, 3)].astype(np.float64) - base) @ inv.T
    n = np.array([cab.roof - cab.belt, 0.0, cab.base_x - cab.top_x])
    t_glass = ((np.array([cab.base_x, 0.0, cab.belt]) - o) @ n) / (d @ n)
    t_mesh = _nearest_surface(o, d, tri)
    near = t_mesh < t_glass - 0.004 / np.linalg.norm(d, axis=1)  # a surface 4 mm or more in front of the glass
    assert not near.any(), list(zip(xs[near], ys[near]))[:10]


def _paint_hits(sim):
    """Hits on the bonnet's top and on the front's face, of the chip and the crack class."""
    from taichi_rocks.motion.bodies import body_parts
    from taichi_rocks.motion.cabin import cabin_of

    spec = sim.scene.vehicles[0]
    x0, x1, half, z0, z1 = body_parts(spec).part("lower").bounds
    cab = cabin_of(spec)
    rows = []
    for k, y in enumerate((-0.5, 0.0, 0.45)):
        rows.append({"point": (0.5 * (cab.base_x + x1), y, z1), "normal": (0.0, 0.0, 1.0), "part": 1,
                     "damage": 1 + k % 2, "normal_momentum": 0.5})
        rows.append({"point": (x1, y, 0.5 * (z0 + z1)), "normal": (1.0, 0.0, 0.0), "part": 0, "damage": 2 - k % 2,
                     "normal_momentum": 0.5})
    return _events(rows), (cab.base_x, x1, half, z0, z1)


def test_hits_on_the_bonnet_and_the_front_leave_paint_chips_there(drawn):
    """Bonnet and front hits (chip and crack class) leave marks: pixels change, only where the rays meet the
    bonnet's top or the body's front face (ahead of the windscreen; the bumper's box proud of it included)."""
    from taichi_rocks.render.paintchips import PAINT_R

    sim, r = drawn
    r.set_view("chase")
    r.view()
    events, (xb, x1, half, z0, z1) = _paint_hits(sim)
    view = _outside_view(sim, r, np.array([x1 + 1.3, 0.8, z1 + 0.9]), np.array([x1 - 0.3, 0.0, z1 - 0.15]))
    bare = _draw(r, view)
    marked = _draw(r, view, events)
    changed = np.any(marked != bare, axis=2)
    ys, xs = np.nonzero(changed)
    assert changed.sum() > 6 * 3, changed.sum()
    o, d = _to_body(sim, view, _rays(r, view, ys, xs))
    reach = PAINT_R[1][1] + 0.01
    hits = events["point"]
    # every changed pixel's ray passes within a chip's reach of a hit
    gap = np.linalg.norm(np.cross(hits[None] - o, d[:, None]), axis=2) / np.linalg.norm(d, axis=1)[:, None]
    assert np.all(gap.min(axis=1) < reach)
    # and each hit left pixels: the chips of the bonnet and of the front all show
    near = gap < 0.5 * PAINT_R[0][0] + 0.004
    assert near.any(axis=0).sum() >= 4
