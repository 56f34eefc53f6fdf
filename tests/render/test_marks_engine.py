"""Windscreen marks from the engine's impacts (render/hits.py HitLayer.update on a Simulation, no drawing): a
scripted stone the player drives into leaves one mark, where it hit its windscreen and nowhere else; going back
before the hit takes the mark away, and playing on brings it back in the same place."""

import numpy as np
import pytest

from taichi_rocks.config.scene import parse_scene

SCENE = {
    "name": "scripted_hit", "duration": 1.0, "seed": 3,
    "effects": {"impacts": True},
    "bed": {"radius": 10.0, "rocks": 8000, "rock_radius": [0.004, 0.015]},
    "sim": {"detection": "patch"},
    # the lead throws (impacts need a thrower) but is far outside the bed: nothing but the scripted stone flies
    "vehicle": [{"name": "player", "path": {"points": [[0.0, 0.0], [260.0, 0.0]], "speed": 20.0}},
                {"name": "lead", "path": {"points": [[60.0, 0.0], [320.0, 0.0]], "speed": 20.0}}],
}
ROCK = 17


def _segments(layer, vehicle=0):
    """The windscreen marks' segments of ``vehicle`` the layer shows (body frame on the glass, (K, 2, 3))."""
    from taichi_rocks.render.glassmarks import glass_point

    layer.store.sync(layer.hits)
    return glass_point(layer.store.cabins[vehicle], layer.store.segments(vehicle, layer.hits.t))


def _aim(sim, cab, lead_s=0.06):
    """A stone that the player's windscreen meets ``lead_s`` seconds from now at the glass's middle, left of
    centre: its start (world), velocity, and the body-frame point aimed at."""
    g = 9.81
    z = cab.belt + 0.5 * (cab.roof - cab.belt)
    target = np.array([cab.windscreen_x(z), 0.25, z])
    pose = sim.fleet.poses(sim.time)[0]
    v_stone = np.array([2.0, 0.0, 0.5 * g * lead_s])  # slow ahead of the car; rising what gravity will take
    rel = v_stone[0] - 20.0
    start = pose.position + target - np.array([rel * lead_s, 0.0, 0.0])  # the car drives along +x (heading 0)
    return start, v_stone, target


@pytest.fixture(scope="module")
def run(taichi_cpu):
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.motion.cabin import cabin_of
    from taichi_rocks.render.hits import HitLayer

    scene = parse_scene(SCENE, source="<test>")
    sim = Simulation(scene)
    layer = HitLayer(scene)
    cab = cabin_of(scene.vehicles[0])
    sim.advance_to(0.2)
    layer.update(sim)
    before = sim.checkpoint()
    t_before = sim.time
    start, v, target = _aim(sim, cab)
    sim.set_rocks([ROCK], positions=start[None], velocities=v[None], phase=np.array([1], np.int8))
    after_aim = sim.checkpoint()
    sim.advance_to(0.4)
    layer.update(sim)
    return dict(sim=sim, layer=layer, cab=cab, target=target, before=before, t_before=t_before,
                after_aim=after_aim)


def test_the_stone_leaves_one_mark_where_it_hit(run):
    layer, cab = run["layer"], run["cab"]
    marks = layer.hits.marks()
    assert len(marks) == 1 and marks["rock"][0] == ROCK and marks["vehicle"][0] == 0, marks
    hit = marks["point"][0]
    # its contact point: where the aimed line meets the glass, less the stone's radius along the normal
    assert np.linalg.norm(hit - run["target"]) < 0.03, (hit, run["target"])
    seg = _segments(layer).reshape(-1, 3)
    # the mark starts at the hit, on the glass's plane (the contact point was found a few mm inside the glass)
    on_glass = np.array([cab.windscreen_x(hit[2]), hit[1], hit[2]])
    assert abs(on_glass[0] - hit[0]) < 0.01
    assert len(seg) and np.linalg.norm(seg - on_glass, axis=1).min() < 1e-9
    centre = seg.mean(axis=0)
    assert abs(centre[1] - hit[1]) < 0.3 and abs(centre[2] - hit[2]) < 0.3
    assert _segments(layer, 1).shape == (0, 2, 3)  # none on the lead
    counts = layer.counts()
    assert sum(counts.values()) == 1 and counts[("mark", "chip", "crack")[marks["damage"][0]]] == 1


def test_going_back_before_the_hit_takes_the_mark_away_and_playing_brings_it_back(run):
    sim, layer = run["sim"], run["layer"]
    first = layer.hits.marks().copy()
    sim.restore(run["before"])  # the viewer's scrub back: a saved state before the hit, the clock then
    layer.update(sim)
    assert sim.time == run["t_before"] and len(layer.hits.marks()) == 0
    assert _segments(layer).shape == (0, 2, 3)
    sim.restore(run["after_aim"])  # the same stone again
    sim.advance_to(0.4)
    layer.update(sim)
    again = layer.hits.marks()
    assert len(again) == 1
    np.testing.assert_allclose(again["point"], first["point"], atol=1e-6)


UNDER_FIRE = {  # a car 6 m behind another: its windscreen is cracked at 0.51 s and 0.56 s (frames 16, 17)
    "name": "under_fire", "duration": 0.8, "seed": 3, "effects": {"impacts": True},
    "bed": {"radius": 10.0, "rocks": 8000, "rock_radius": [0.004, 0.015]}, "sim": {"detection": "patch"},
    "camera": {"view": "driver"},
    "vehicle": [{"name": "player", "path": {"points": [[0.0, 0.0], [260.0, 0.0]], "speed": 20.0}},
                {"name": "lead", "path": {"points": [[6.0, 0.0], [266.0, 0.0]], "speed": 20.0}}],
}


def test_a_resumed_render_keeps_the_marks_made_before_its_saved_state(taichi_cpu, tmp_path):
    """Interrupted at frame 20 with states saved after frames 14 and 19 (after the cracks): the resume replays
    from frame 0, so the frames it draws have the marks an uninterrupted render has."""
    import imageio.v3 as iio

    from taichi_rocks.app.render import render_scene

    scene = parse_scene(UNDER_FIRE, source="<test>")
    kw = dict(frames=24, resolution=(320, 192), fmt="png", progress=False)
    render_scene(scene, out_dir=tmp_path / "ref", **kw)

    def stop(k, img):
        if k == 20:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render_scene(scene, out_dir=tmp_path / "cut", on_frame=stop, checkpoint_every=5, **kw)
    assert len(list((tmp_path / "cut" / ".resume").glob("frame_*.npz"))) == 2
    res = render_scene(scene, out_dir=tmp_path / "cut", resume=True, checkpoint_every=5, **kw)
    assert res["resumed_from"] == 20 and res["replayed_from"] == 0
    ref = [iio.imread(tmp_path / "ref" / "frames" / f"frame_{k:05d}.png") for k in (15, 20, 23)]
    assert np.abs(ref[1].astype(int) - ref[0]).max() > 100  # the cracks show between frames 15 and 20
    for k in (20, 23):
        np.testing.assert_array_equal(iio.imread(tmp_path / "cut" / "frames" / f"frame_{k:05d}.png"),
                                      iio.imread(tmp_path / "ref" / "frames" / f"frame_{k:05d}.png"))


def test_the_views_scrub_hides_the_marks_and_brings_them_back(taichi_cpu):
    """The viewer's clock (app/timeline.py) on an offscreen Renderer of a car whose windscreen cracks at frames 16
    and 17, seen from its driver's seat: played to frame 22, scrubbed back to frame 12 (a saved state, then
    simulated forward) and forward to 22 again (simulated again from a saved state, the marks already made):
    each frame is the one first drawn at that time, the cracks gone at 12 and back at 22, made once."""
    from taichi_rocks.app.timeline import Timeline
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.render.renderer import Renderer

    scene = parse_scene(UNDER_FIRE, source="<test>")
    sim = Simulation(scene, tumble=True, track_changes=False)
    r = Renderer(sim, resolution=(320, 192), window_every=0)
    try:
        tl = Timeline(30.0, 24, every=5)
        r.view()
        tl.save(sim, r.rig)
        first = {0: r.render_frame().copy()}
        for k in range(1, 23):
            tl.advance(sim, r.view)
            tl.save(sim, r.rig)
            first[k] = r.render_frame().copy()
        made = r.hits.store.made
        assert len(r.hits.hits.marks()) == made
        assert np.abs(first[22].astype(int) - first[12]).max() > 100  # the cracks, and what moved
        on_glass = {}
        for k in (12, 22, 18, 3):
            tl.seek(k, sim, r.rig, r.view)
            np.testing.assert_array_equal(r.render_frame(), first[k])
            marks = r.hits.hits.marks()
            assert np.all(marks["time"] <= k / 30.0 + 1e-9)
            on_glass[k] = int((marks["part"] == 2).sum())
        assert on_glass[12] == on_glass[3] == 0 and on_glass[22] >= 2  # the windscreen's cracks: 16 and 17
        assert r.hits.store.made == made  # none made again
    finally:
        r.close()
