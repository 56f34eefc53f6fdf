"""Hits you can see, host side (render/marks.py, glassmarks.py, paintchips.py, markstore.py, flashes.py), on
synthetic events: the state keeps each hit once, forgets what lies after a time gone back to, counts by class;
a windscreen mark lies where the stone hit, on the glass, shaped by its class, and nowhere else; flashes ride
with the vehicle and keep a size in pixels."""

import math

import numpy as np
import pytest

from scenes_util import scene as make_scene


def _events(n, **cols):
    from taichi_rocks.engine.events import EVENT_DTYPE

    ev = np.zeros(n, EVENT_DTYPE)
    ev["normal"] = (1.0, 0.0, 0.0)
    ev["thrower"] = -1
    for k, v in cols.items():
        ev[k] = v
    return ev


def _car():
    return make_scene(vehicles=[{"name": "car", "kind": "car", "length": 4.5, "width": 1.8, "height": 1.45,
                                 "path": {"points": [[0.0, 0.0], [99.0, 0.0]]}}]).vehicles[0]


def _segments(hits, spec, vehicle=0):
    """The windscreen marks' segments of ``vehicle`` shown by ``hits`` (body frame on the glass, (K, 2, 3)),
    made by a store of ``spec``'s marks (render/markstore.py)."""
    from taichi_rocks.render.glassmarks import glass_point
    from taichi_rocks.render.markstore import MarkStore

    store = MarkStore([spec, spec])
    store.sync(hits)
    return glass_point(store.cabins[vehicle], store.segments(vehicle, hits.t))


def _windscreen_hit(cab, u=0.5, y=0.1, damage=1, **kw):
    """An event on the windscreen of ``cab``, ``u`` of the way up from the belt, at ``y``."""
    z = cab.belt + u * (cab.roof - cab.belt)
    n = np.array([cab.roof - cab.belt, 0.0, cab.base_x - cab.top_x])
    return _events(1, point=(cab.windscreen_x(z), y, z), normal=n / np.linalg.norm(n), part=2, damage=damage,
                   normal_momentum=kw.pop("momentum", 0.02), normal_speed=kw.pop("speed", 20.0), **kw)


def test_each_hit_is_kept_once_and_only_those_up_to_the_time_shown_count():
    from taichi_rocks.render.marks import Hits

    hits = Hits()
    ev = _events(4, time=[0.1, 0.2, 0.3, 0.4], step=[6, 12, 18, 24], rock=[1, 2, 3, 4], damage=[0, 1, 2, 1])
    assert hits.update(ev[:2], 0.2) == 2
    assert hits.update(ev[:3], 0.3) == 1  # the first two again (a restore stepping the same steps): kept once
    assert list(hits.events["rock"]) == [1, 2, 3]
    hits.update(ev[3:], 0.45)
    assert hits.counts(0) == {"mark": 1, "chip": 2, "crack": 1}
    hits.update(ev[:0], 0.25)  # a scrub back to 0.25 s: the hits after it do not count
    assert list(hits.shown()["rock"]) == [1, 2] and hits.counts(0) == {"mark": 1, "chip": 1, "crack": 0}
    assert hits.update(ev[2:], 0.45) == 0  # played again: the same hits, shown again
    assert list(hits.shown()["rock"]) == [1, 2, 3, 4]
    hits.update(ev[:0], 0.0)  # round to frame 0: none shown
    assert len(hits.shown()) == 0 and hits.counts(0) == {"mark": 0, "chip": 0, "crack": 0}
    hits.update(ev[:0], 0.45)  # a jump forward past a saved state (its steps not stepped again): shown again
    assert len(hits.shown()) == 4
    hits.clear_after(0.2)  # the future changed (a rebuild at 0.2 s): forgotten
    assert list(hits.events["rock"]) == [1, 2]
    assert hits.update(ev[2:], 0.45) == 2


def test_counts_are_per_vehicle_and_flashes_last_their_time():
    from taichi_rocks.render.marks import FLASH_S, Hits

    hits = Hits()
    hits.update(_events(3, time=[1.0, 1.0, 1.05], rock=[1, 2, 3], vehicle=[0, 1, 0], damage=[2, 2, 0]), 1.05)
    assert hits.counts(0) == {"mark": 1, "chip": 0, "crack": 1}
    assert hits.counts(1)["crack"] == 1
    ev, age = hits.flashing(1.05)
    assert list(ev["rock"]) == [1, 2, 3]
    np.testing.assert_allclose(age, [0.05, 0.05, 0.0], atol=1e-12)
    ev, _ = hits.flashing(1.0 + FLASH_S + 0.01)
    assert list(ev["rock"]) == [3]
    assert len(hits.flashing(2.0)[0]) == 0


@pytest.mark.parametrize("damage", [1, 2], ids=("chip", "crack"))
def test_a_windscreen_mark_lies_where_the_stone_hit_on_the_glass(damage):
    """The mark's segments lie in the windscreen's plane, inside the glass, around the hit point: a chip within
    CHIP_R of it, a crack reaching further (up to CRACK_L / 2 per arm, its branches a little more)."""
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.glassmarks import CHIP_R, CRACK_L
    from taichi_rocks.render.marks import Hits

    spec = _car()
    cab = cabin_of(spec)
    hits = Hits()
    ev = _windscreen_hit(cab, u=0.45, y=-0.2, damage=damage, rock=7, step=30, time=1.0)
    hits.update(ev, 1.0)
    seg = _segments(hits, spec)
    assert len(seg) >= 8
    p = seg.reshape(-1, 3)
    np.testing.assert_allclose(p[:, 0], cab.windscreen_x(p[:, 2]), atol=1e-12)  # on the glass's plane
    assert np.linalg.norm(p - ev["point"][0], axis=1).min() < 1e-12  # from the hit
    assert np.all(p[:, 2] >= cab.belt) and np.all(p[:, 2] <= cab.roof)
    u = (p[:, 2] - cab.belt) / (cab.roof - cab.belt)
    assert np.all(np.abs(p[:, 1]) <= cab.base_half + u * (cab.top_half - cab.base_half))
    reach = np.linalg.norm(p - ev["point"][0], axis=1).max()
    if damage == 1:
        assert reach <= CHIP_R[1] + 1e-9
    else:
        assert 0.5 * CRACK_L[0] * 0.7 <= reach <= CRACK_L[1]
    assert _segments(hits, spec, 1).shape == (0, 2, 3)  # another vehicle's windscreen: nothing


def test_no_mark_from_a_light_hit_or_off_the_glass_and_none_after_a_scrub_back():
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.marks import Hits

    spec = _car()
    cab = cabin_of(spec)
    hits = Hits()
    light = _windscreen_hit(cab, damage=0, rock=1, step=6, time=0.5)  # a "mark" class hit: no mark left
    bonnet = _windscreen_hit(cab, damage=2, rock=2, step=7, time=0.6)
    bonnet["part"] = 1
    hits.update(np.concatenate([light, bonnet]), 0.7)
    assert _segments(hits, spec).shape == (0, 2, 3)
    chip = _windscreen_hit(cab, damage=1, rock=3, step=60, time=1.0)
    hits.update(chip, 1.0)
    assert len(_segments(hits, spec))
    hits.update(chip[:0], 0.9)  # the viewer goes back before the chip
    assert _segments(hits, spec).shape == (0, 2, 3)
    hits.update(chip[:0], 1.0)  # and forward again
    assert len(_segments(hits, spec))


def test_a_mark_is_the_same_every_time_and_grows_with_the_hit():
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.glassmarks import glass_point, mark_segments
    from taichi_rocks.render.marks import severity

    cab = cabin_of(_car())
    e = _windscreen_hit(cab, damage=2, rock=5, step=9)[0]
    np.testing.assert_array_equal(mark_segments(e, 0.3, cab), mark_segments(e, 0.3, cab))
    small, big = (np.linalg.norm(glass_point(cab, mark_segments(e, s, cab)).reshape(-1, 3) - e["point"], axis=1).max()
                  for s in (0, 1))
    assert big > 1.5 * small
    th = (0.0055, 0.14)
    lo = _windscreen_hit(cab, damage=1, momentum=2 * 0.006 / 10.0, speed=10.0)[0]  # 1/2 p u = 0.006 J
    hi = _windscreen_hit(cab, damage=1, momentum=2 * 0.1 / 10.0, speed=10.0)[0]  # 0.1 J
    assert 0.0 < severity(lo, th, "energy") < severity(hi, th, "energy") < 1.0
    assert severity(hi, (0.0011, 0.0055), "momentum") == 1.0  # 0.02 N s: above the chip range, clipped


def test_a_mark_near_the_edge_is_clipped_to_the_glass():
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.glassmarks import GLASS_MARGIN
    from taichi_rocks.render.marks import Hits

    spec = _car()
    cab = cabin_of(spec)
    hits = Hits()
    hits.update(_windscreen_hit(cab, u=0.1, y=cab.base_half - 0.02, damage=2, rock=4, step=3), 0.1)
    p = _segments(hits, spec).reshape(-1, 3)
    u = (p[:, 2] - cab.belt) / (cab.roof - cab.belt)
    assert np.all(np.abs(p[:, 1]) <= cab.base_half + u * (cab.top_half - cab.base_half) - GLASS_MARGIN + 1e-6)
    assert np.all(p[:, 2] >= cab.belt + GLASS_MARGIN - 1e-6)


def test_body_frame_and_pose_transforms():
    from taichi_rocks.render.marks import body_to_local, to_body_frame

    ev = _events(2, point=[(1.0, 0.5, 1.2), (-2.0, 0.0, 0.3)])
    out = to_body_frame(ev, ground_local=0.25)
    np.testing.assert_allclose(out["point"][:, 2], [0.95, 0.05])
    np.testing.assert_allclose(ev["point"][:, 2], [1.2, 0.3])  # a copy
    h = np.array([math.pi / 2, math.pi])
    got = body_to_local(out["point"], [(10.0, 20.0, 1.0), (0.0, 0.0, 0.0)], h)
    np.testing.assert_allclose(got, [(10.0 - 0.5, 21.0, 1.95), (2.0, 0.0, 0.05)], atol=1e-12)


def test_a_flash_rides_with_the_vehicle_and_keeps_its_size_in_pixels():
    from taichi_rocks.render.flashes import FLASH_M, FLASH_PX, HOT, RAYS, flash_geometry
    from taichi_rocks.render.marks import FLASH_S

    ev = _events(2, point=[(2.0, 0.0, 1.0), (2.0, 0.0, 1.0)], rock=[1, 2])
    pos = np.array([(0.0, 0.0, 0.0), (100.0, 0.0, 0.0)])
    c, r, col, seg, seg_col = flash_geometry(ev, [0.0, 0.0], pos, [0.0, 0.0], eye=(0.0, 0.0, 1.0),
                                             px_per_rad=1000.0)
    np.testing.assert_allclose(c[:, 1:], [[0.0, 1.0], [0.0, 1.0]], atol=1e-6)
    assert c[0, 0] > 2.0 and c[1, 0] > 102.0  # at the contact, just off the surface (normal +x)
    assert r[0] == pytest.approx(FLASH_M)  # near: its size in metres
    assert r[1] == pytest.approx(FLASH_PX * np.linalg.norm(c[1] - (0, 0, 1)) / 1000.0, rel=0.02)  # far: in pixels
    assert seg.shape == (2 * RAYS, 2, 3) and seg_col.shape == (2 * RAYS, 3)
    assert np.all(col <= HOT) and np.all(col > 0.4)
    _, r_old, col_old, _, _ = flash_geometry(ev[:1], [0.9 * FLASH_S], pos[:1], [0.0], (0.0, 0.0, 1.0), 1000.0)
    assert r_old[0] < r[0] and np.all(col_old[0] < col[0])  # it fades and shrinks


def test_the_hud_counts_the_players_hits_by_class():
    from types import SimpleNamespace

    from taichi_rocks.render.hits import HitLayer
    from taichi_rocks.render.panel import hud_lines

    scene = make_scene(vehicles=[{"name": n, "path": {"points": [[x, 0.0], [x + 99.0, 0.0]]}}
                                 for n, x in (("player", 0.0), ("lead", 8.0))], bed={"follow": "player"})
    layer = HitLayer(scene)
    tl = SimpleNamespace(time=1.0, frame=30, frames=60, playing=True, speed=1.0)
    v = SimpleNamespace(timeline=tl, fps=30.0, in_air=0, sim=SimpleNamespace(launches_total=0), camera_name="chase",
                        renderer=SimpleNamespace(hits=layer), switches={"effects.impacts": False}, notice="")
    assert not any("hits" in line for line in hud_lines(v))  # impacts off, nothing seen: no line
    v.switches["effects.impacts"] = True
    assert "hits on the player  mark 0   chip 0   crack 0" in hud_lines(v)
    layer.hits.update(_events(4, time=[0.2, 0.3, 0.4, 0.5], rock=[1, 2, 3, 4], vehicle=[0, 0, 1, 0],
                              damage=[0, 2, 2, 2]), 1.0)
    assert "hits on the player  mark 1   chip 0   crack 2" in hud_lines(v)


@pytest.mark.parametrize("side", [False, True])
def test_glass_ribbons_stay_on_the_glass(side):
    """Ribbons of cracks that reach the glass's edges, a few pixels wide seen from near and from far: every
    corner lies on the windscreen's plane (GLASS_GAP off it, on the camera's side), GLASS_EDGE inside its edges,
    and each ribbon is about ``width_px`` pixels wide where it is not clipped."""
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.glassmarks import GLASS_EDGE, GLASS_GAP, glass_normal, glass_ribbons
    from taichi_rocks.render.marks import Hits
    from taichi_rocks.render.markstore import MarkStore

    spec = _car()
    cab = cabin_of(spec)
    hits = Hits()
    ev = np.concatenate([_windscreen_hit(cab, u=u, y=y, damage=2, rock=k, step=k, momentum=1.0)
                         for k, (u, y) in enumerate(((0.5, 0.0), (0.1, cab.base_half - 0.03), (0.9, -0.5)))])
    hits.update(ev, 1.0)
    store = MarkStore([spec])
    store.sync(hits)
    seg = store.segments(0, hits.t)
    for eye, px_per_rad in (((cab.eye[0], cab.eye[1], cab.eye[2]), 700.0), ((30.0, 0.0, 2.0), 200.0)):
        t = glass_ribbons(seg, cab, side, eye, px_per_rad, 2.0)
        assert t.shape[1:] == (3, 3) and len(t) >= 2 * len(seg) - 10
        p = t.reshape(-1, 3) - (-GLASS_GAP if side else GLASS_GAP) * glass_normal(cab)
        np.testing.assert_allclose(p[:, 0], cab.windscreen_x(p[:, 2]), atol=1e-9)  # on the glass's plane
        u = (p[:, 2] - cab.belt) / (cab.roof - cab.belt)
        assert u.min() > 0.0 and u.max() < 1.0
        assert np.all(np.abs(p[:, 1]) <= cab.base_half + u * (cab.top_half - cab.base_half) - GLASS_EDGE + 1e-9)
        side_len = np.linalg.norm(t[:, 1] - t[:, 0], axis=1)  # the first triangle's a-, a+: across the ribbon
        dist = np.linalg.norm(t[:, 0] - np.asarray(eye), axis=1)
        assert np.median(side_len / (dist / px_per_rad)) == pytest.approx(2.0, rel=0.2)


@pytest.mark.parametrize("damage", [1, 2])
def test_a_paint_chip_lies_on_the_face_hit_and_inside_it(damage):
    """A hit on the bonnet or the front chips the paint: a flake round the hit, on the face it hit (PAINT_GAP off
    it), inside that face's edges (a hit near an edge is clipped; one off it leaves none), the same every time,
    larger for a crack than for a chip; Hits.marks counts it, and the windscreen's segments do not."""
    from taichi_rocks.motion.bodies import body_parts
    from taichi_rocks.render.marks import Hits
    from taichi_rocks.render.markstore import MarkStore
    from taichi_rocks.render.paintchips import PAINT_GAP, PAINT_MARGIN, PAINT_R, body_faces, paint_chip

    spec = _car()
    faces = body_faces(spec)
    x0, x1, half, z0, z1 = body_parts(spec).part("lower").bounds
    top = _events(1, point=(x1 - 0.4, 0.3, z1), normal=(0.0, 0.0, 1.0), part=1, damage=damage, rock=3, step=4,
                  normal_momentum=1.0, normal_speed=30.0)[0]
    tris, n = paint_chip(top, 1.0, faces)
    np.testing.assert_allclose(n, (0.0, 0.0, 1.0), atol=1e-12)
    p = tris.reshape(-1, 3)
    np.testing.assert_allclose(p[:, 2], z1 + PAINT_GAP, atol=1e-9)
    reach = np.linalg.norm(p[:, :2] - (x1 - 0.4, 0.3), axis=1).max()
    assert PAINT_R[damage - 1][1] * 0.5 < reach <= PAINT_R[damage - 1][1] + 1e-9
    np.testing.assert_array_equal(paint_chip(top, 1.0, faces)[0], tris)
    edge = top.copy()
    edge["point"] = (x1 - 0.4, half - 0.005, z1)  # 5 mm from the side: clipped to the face's margin
    tris, _ = paint_chip(edge, 1.0, faces)
    assert len(tris) and np.all(tris.reshape(-1, 3)[:, 1] <= half - PAINT_MARGIN + 1e-9)
    off = top.copy()
    off["point"] = (x1 - 0.4, half - 0.001, z1)  # inside the margin: no chip
    assert len(paint_chip(off, 1.0, faces)[0]) == 0
    front = _events(1, point=(x1, -0.2, 0.5 * (z0 + z1)), normal=(1.0, 0.0, 0.0), part=0, damage=damage, rock=5,
                    step=6, normal_momentum=1.0, normal_speed=30.0)
    hits = Hits()
    hits.update(np.concatenate([top[None], front]), 1.0)
    store = MarkStore([spec])
    store.sync(hits)
    assert len(hits.marks()) == 2 and store.segments(0, hits.t).shape == (0, 2, 2)
    tris, nrm = store.paint_chips(0, hits.t)
    assert len(tris) == len(nrm) and {tuple(np.round(v, 9)) for v in nrm} == {(0.0, 0.0, 1.0), (1.0, 0.0, 0.0)}
