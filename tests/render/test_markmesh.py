"""Marks made once and posed each frame (render/markstore.py, render/markmesh.py), no window: the kernel that
places the marks shown gives the triangles of the NumPy reference (render/glassmarks.py ``glass_ribbons`` posed
with render/marks.py ``body_to_local``; the paint chips posed likewise), for several vehicles turned every way,
eyes near and far (ribbons wider than the glass: fans of up to six triangles), from inside a cabin and out, the
same buffer every run; vehicles out of view, windscreens and chips seen from behind give nothing; each mark is
made once and each of its rows uploaded once, whatever the scrubbing; a change of the past makes again only
what it changed."""

import math
import numpy as np
import pytest

from events_util import event_rows
from scenes_util import scene as make_scene


def _vehicles():
    return make_scene(vehicles=[
        {"name": "car", "kind": "car", "path": {"points": [[0.0, 0.0], [99.0, 0.0]]}},
        {"name": "van", "kind": "van", "length": 5.0, "width": 2.0, "height": 2.0, "wheelbase": 3.2,
         "path": {"points": [[10.0, 0.0], [99.0, 0.0]]}}]).vehicles


def _events(rows):
    return event_rows(rows, thrower=-1, normal_speed=30.0)


def _hits(specs, seed=0, n=24):
    """Random chips and cracks on the windscreens (some at their edges) and paint chips on the bonnets and
    fronts of ``specs``, one every 0.05 s from 0.05 s, alternating vehicles."""
    from taichi_rocks.motion.bodies import body_parts
    from taichi_rocks.motion.cabin import cabin_of

    rng = np.random.default_rng(seed)
    rows = []
    for k in range(n):
        i = k % len(specs)
        cab = cabin_of(specs[i])
        x0, x1, half, z0, z1 = body_parts(specs[i]).part("lower").bounds
        kind = k % 3
        if kind == 0:  # the glass, anywhere on it, its edges included
            u = rng.uniform(0.02, 0.98)
            z = cab.belt + u * (cab.roof - cab.belt)
            w = cab.base_half + u * (cab.top_half - cab.base_half)
            n = np.array([cab.roof - cab.belt, 0.0, cab.base_x - cab.top_x])
            row = {"point": (cab.windscreen_x(z), rng.uniform(-w, w), z), "normal": n / np.linalg.norm(n), "part": 2}
        elif kind == 1:
            row = {"point": (0.5 * (cab.base_x + x1), rng.uniform(-half, half), z1), "normal": (0.0, 0.0, 1.0),
                   "part": 1}
        else:
            row = {"point": (x1, rng.uniform(-half, half), rng.uniform(z0, z1)), "normal": (1.0, 0.0, 0.0),
                   "part": 0}
        rows.append({**row, "vehicle": i, "damage": 1 + int(rng.integers(0, 2)), "time": 0.05 * (k + 1),
                     "step": 10 * (k + 1), "rock": 100 + k, "normal_momentum": float(rng.uniform(0.01, 2.0))})
    return _events(rows)


class _Scene:
    """A GGUI scene that keeps the vertex buffers handed over (render/vbo.py declare_mesh)."""

    def __init__(self):
        self.drawn = []


@pytest.fixture(autouse=True)
def _keep_buffers(monkeypatch):
    import taichi_rocks.render.markmesh as mm

    monkeypatch.setattr(mm, "declare_mesh", lambda scene, vbo, identity: scene.drawn.append(vbo.copy()))


def _frame(specs, seed):
    rng = np.random.default_rng(seed)
    pos = np.stack([rng.uniform(-30, 30, len(specs)), rng.uniform(-30, 30, len(specs)), rng.uniform(-0.5, 0.5,
                                                                                                    len(specs))], 1)
    head = rng.uniform(-math.pi, math.pi, len(specs))
    return pos, head


def _sight(eye, target, inside=None, px_per_rad=600.0, see_through=False):
    from taichi_rocks.render.markmesh import Sight

    eye = np.asarray(eye, np.float64)
    fwd = np.asarray(target, np.float64) - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    return Sight(eye, fwd, right, np.cross(right, fwd), 0.6, 0.35, px_per_rad, inside, (0.3, -0.2, 0.93),
                 see_through)


def _reference(store, specs, t, pos, head, sight, in_view):
    """Every triangle the frame should draw (local frame, (T, 3, 3)), by the NumPy reference: of the vehicles
    ``in_view``, the windscreen marks facing the eye (or all of them see-through, or from inside the cabin) and
    the paint chips facing it (or all of them see-through)."""
    from taichi_rocks.render.glassmarks import glass_normal, glass_ribbons
    from taichi_rocks.render.markmesh import MARK_PX
    from taichi_rocks.render.marks import body_to_local

    out = [np.empty((0, 3, 3))]
    for i in np.flatnonzero(in_view):
        c, s = math.cos(head[i]), math.sin(head[i])
        e = np.asarray(sight.eye) - pos[i]
        eye = np.array([c * e[0] + s * e[1], -s * e[0] + c * e[1], e[2]])
        cab = store.cabins[i]
        place = lambda p: body_to_local(p.reshape(-1, 3), np.repeat(pos[i][None], p.size // 3, 0),
                                        np.full(p.size // 3, head[i])).reshape(-1, 3, 3)
        inside = sight.inside == i
        if sight.see_through or inside or (eye - (cab.base_x, 0.0, cab.belt)) @ glass_normal(cab) > 0:
            out.append(place(glass_ribbons(store.segments(i, t), cab, inside, eye, sight.px_per_rad, MARK_PX)))
        tris, nrm = store.paint_chips(i, t)
        facing = (np.einsum("kj,kj->k", nrm, eye[None] - tris[:, 0]) > 0) | sight.see_through
        out.append(place(tris[facing]))
    return _solid(np.concatenate(out))


def _solid(tris):
    """The triangles of ``tris`` with an area (an empty slot, or a fan's sliver of no width, draws nothing)."""
    area = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    return tris[area > 1e-9]


def _same_triangles(got, want, tol=2e-4):
    """Each triangle of ``want`` has one in ``got`` with the same corners in the same order, and the counts agree."""
    assert len(got) == len(want), (len(got), len(want))
    used = np.zeros(len(got), bool)
    for w in want:
        d = np.abs(got - w[None]).max(axis=(1, 2))
        d[used] = np.inf
        k = int(np.argmin(d))
        assert d[k] < tol, (w, got[k], d[k])
        used[k] = True


def _drawn(mesh, store, t, pos, head, sight):
    scene = _Scene()
    n = mesh.draw(scene, store.shown(t), pos, head, sight)
    vbo = scene.drawn[0] if scene.drawn else np.empty((0, 12), np.float32)
    return n, vbo


@pytest.fixture(scope="module")
def made(taichi_cpu):
    from taichi_rocks.render.markmesh import MarkMesh, body_bounds
    from taichi_rocks.render.marks import Hits
    from taichi_rocks.render.markstore import MarkStore

    specs = _vehicles()
    hits = Hits()
    hits.update(_hits(specs), 2.0)
    store = MarkStore(specs)
    store.sync(hits)
    mesh = MarkMesh(store.cabins, body_bounds(specs))
    mesh.upload(store)
    return specs, hits, store, mesh


@pytest.mark.parametrize("case", ["near", "far", "inside", "wide"])
def test_the_kernel_draws_the_reference_triangles(made, case):
    """The marks posed by the kernel are the reference's triangles, in the local frame; with wide ribbons
    (a far eye and few pixels per radian) the fans clipped at the glass's corners have up to six triangles,
    and the buffer is the same however the threads ran."""
    specs, hits, store, mesh = made
    for seed in range(4):
        pos, head = _frame(specs, seed)
        i = seed % len(specs)
        c, s = math.cos(head[i]), math.sin(head[i])
        ahead = pos[i] + np.array([c, s, 0.0]) * 3.0 + (0.0, 0.0, 1.2)
        if case == "inside":  # from the driver's seat of vehicle i
            cab = store.cabins[i]
            eye = pos[i] + np.array([c * cab.eye[0] - s * cab.eye[1], s * cab.eye[0] + c * cab.eye[1], cab.eye[2]])
            sight = _sight(eye, eye + np.array([c, s, 0.0]), inside=i)
        else:  # ahead of vehicle i, looking back at it: its marks face the eye, the other's may not
            dist = {"near": 4.0, "far": 40.0, "wide": 15.0}[case]
            eye = ahead + np.array([c, s, 0.0]) * dist + (0.0, 0.0, 1.0)
            sight = _sight(eye, pos[i], px_per_rad=30.0 if case == "wide" else 600.0, see_through=seed % 2 == 1)
        n, vbo = _drawn(mesh, store, hits.t, pos, head, sight)
        got = _solid(vbo[:, :3].astype(np.float64).reshape(-1, 3, 3))
        c_, s_ = np.cos(head), np.sin(head)
        in_view = mesh._in_view(pos, c_, s_, sight) | sight.see_through
        assert in_view[i]
        want = _reference(store, specs, hits.t, pos, head, sight, in_view)
        assert len(want) > 20
        _same_triangles(got, want)
        again = _drawn(mesh, store, hits.t, pos, head, sight)[1]
        np.testing.assert_array_equal(again, vbo)
        if case == "wide":  # fans of more than two triangles (the third and further ones after the others)
            assert int(mesh._blocks[(store.shown(hits.t).glass + 63) // 64]) > 0


def test_marks_out_of_view_or_seen_from_behind_are_left_out(made):
    """A camera looking away from every vehicle draws no mark; low behind the vehicles (every windscreen, bonnet
    top and front turned away), none; see-through (wireframes) the same camera draws them again."""
    specs, hits, store, mesh = made
    pos = np.array([(0.0, 0.0, 0.0), (12.0, 0.0, 0.0)])
    head = np.zeros(2)
    assert mesh.draw(_Scene(), store.shown(hits.t), pos, head, _sight((-20.0, 0.0, 2.0), (-40.0, 0.0, 2.0))) == 0
    behind = _sight((-10.0, 0.0, 0.5), (0.0, 0.0, 1.0))  # behind the car, low (its bonnet's top turned away)
    n, vbo = _drawn(mesh, store, hits.t, pos, head, behind)
    assert len(_solid(vbo[:, :3].astype(np.float64).reshape(-1, 3, 3))) == 0
    see = behind._replace(see_through=True)
    n, vbo = _drawn(mesh, store, hits.t, pos, head, see)
    assert len(_solid(vbo[:, :3].astype(np.float64).reshape(-1, 3, 3))) > 0


def test_a_buffer_too_small_for_the_fans_grows_and_draws_the_same(made, monkeypatch):
    """Buffers of the exact size asked for, with no room kept for the fans' further triangles: the first draw
    overflows, the buffer grows and the frame is drawn again, the same."""
    import taichi_rocks.render.markmesh as mm

    specs, hits, store, mesh = made
    pos, head = _frame(specs, 7)
    sight = _sight(pos[0] + (20.0, 5.0, 3.0), pos[0], px_per_rad=25.0, see_through=True)
    n, vbo = _drawn(mesh, store, hits.t, pos, head, sight)
    vbo = vbo.copy()
    shown = store.shown(hits.t)
    more = n - 3 * int(shown.chips) - 6 * int(shown.glass)
    assert more > 0
    monkeypatch.setattr(mm, "_capacity", lambda k: max(k, 1))
    mesh._spill = 0
    n2, vbo2 = _drawn(mesh, store, hits.t, pos, head, sight)
    assert n2 == n and mesh._spill >= more
    np.testing.assert_array_equal(vbo2, vbo)


def test_each_mark_is_made_once_and_each_row_uploaded_once(taichi_cpu, monkeypatch):
    """Frame by frame, scrubbing back and forth: every mark is made once, when its hit first shows; only the
    rows made since the last frame go to the device; the rows drawn are those of the marks shown."""
    import taichi_rocks.render.markmesh as mm
    from taichi_rocks.render.markmesh import MarkMesh, body_bounds
    from taichi_rocks.render.marks import Hits
    from taichi_rocks.render.markstore import MarkStore

    uploads = []
    real = mm._put_rows
    monkeypatch.setattr(mm, "_put_rows", lambda dst, src, start: (
        uploads.append((dst.shape[1], start, src.shape[0], isinstance(src, np.ndarray))), real(dst, src, start)))
    specs = _vehicles()
    events = _hits(specs, seed=3, n=30)
    hits, store = Hits(), MarkStore(specs)
    mesh = MarkMesh(store.cabins, body_bounds(specs))
    latest = 0.0
    for t in list(np.arange(0.0, 1.0, 0.1)) + [0.4, 0.2, 0.9, 1.6]:  # forward, back, forward
        latest = max(latest, t)
        hits.update(events[events["time"] <= t], t)
        store.sync(hits)
        mesh.upload(store)
        assert store.made == int((events["time"] <= latest).sum())  # each hit's mark made once, never again
        shown = store.shown(t)
        glass, chips = _rows_of(hits.marks(), specs, store.cabins)
        assert (shown.glass, shown.chips) == (int(glass.sum()), int(chips.sum()))
        np.testing.assert_array_equal(shown.glass_of, glass)
        np.testing.assert_array_equal(shown.chips_of, chips)
    for width, rows in ((6, store.glass.n), (14, store.chips.n)):
        mine = [(start, n) for w, start, n, host in uploads if w == width and host]  # from the host
        assert sum(n for _, n in mine) == rows  # each row once
        assert [s for s, _ in mine] == list(np.cumsum([0] + [n for _, n in mine])[:-1])


def _rows_of(marks, specs, cabins):
    """Per vehicle, the glass and chip rows the shapes of ``marks`` have (made here again, independently)."""
    from taichi_rocks.render.glassmarks import mark_segments
    from taichi_rocks.render.marks import severity
    from taichi_rocks.render.paintchips import body_faces, paint_chip

    glass, chips = np.zeros(len(specs), int), np.zeros(len(specs), int)
    for e in marks:
        i, s = int(e["vehicle"]), severity(e, (0.0055, 0.14), "energy")
        if e["part"] == 2:
            seg = mark_segments(e, s, cabins[i])
            glass[i] += int((np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) > 1e-9).sum())
        else:
            chips[i] += len(paint_chip(e, s, body_faces(specs[i]))[0])
    return glass, chips


def test_a_changed_past_makes_again_only_the_marks_it_changed(taichi_cpu):
    """Forgetting the future (a changed setting) drops the marks after the time; a hit older than the newest
    sorted in makes again the marks after it, not those before; a clear drops every mark."""
    from taichi_rocks.render.marks import Hits
    from taichi_rocks.render.markstore import MarkStore

    specs = _vehicles()
    events = _hits(specs, seed=5, n=18)
    hits, store = Hits(), MarkStore(specs)
    hits.update(events, 1.0)
    store.sync(hits)
    before = (store.glass.rows.copy(), store.chips.rows.copy())
    made = store.made
    store.changed_from()
    hits.clear_after(0.5)
    store.sync(hits)
    assert len(store) == len(hits.marks()) and store.made == made
    kept = store.shown(0.5)
    np.testing.assert_array_equal(store.glass.rows, before[0][:kept.glass])
    late = events[events["time"] > 0.5]
    early = late[:1].copy()
    early["time"], early["step"] = 0.22, 3  # a hit at 0.22 s reported now
    hits.update(np.concatenate([late[1:], early]), 1.0)
    store.sync(hits)
    n_before = int((hits.marked["time"] < 0.22).sum())
    assert store.made == made + len(hits.marked) - n_before
    np.testing.assert_array_equal(store.glass.rows[:store.shown(0.2).glass], before[0][:store.shown(0.2).glass])
    assert store.changed_from() == (store.shown(0.22 - 1e-9).glass, store.shown(0.22 - 1e-9).chips)
    hits.clear()
    hits.update(events[:2], 0.1)
    store.sync(hits)
    assert len(store) == len(hits.marks())
