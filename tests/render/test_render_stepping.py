"""Rendering under active stepping: the rock pass draws the active list and the tile store's tiles in view, and
the frames are those of full stepping, pixel for pixel."""

import numpy as np
import pytest

from scenes_util import scene

W, H = 160, 96
TIMES = (0.5, 2.5)  # rocks in the air; then after a floating-origin shift (60 m/s: 150 m driven)


@pytest.fixture(scope="module")
def fast_scene():
    # a bed wider than the view (part of it behind the camera) and a car fast enough to pass ORIGIN_RANGE
    return scene(rocks=4000, radius=14.0, sim={"detection": "patch"},
                 vehicles=[{"name": "car", "path": {"points": [[0.0, 0.0], [1000.0, 0.0]], "speed": 60.0}}])


@pytest.fixture(scope="module")
def frames(taichi_cpu, fast_scene):
    """Per stepping mode and rock drawing mode, the frames at TIMES (and, for active stepping, what the tile
    culling saw at each)."""
    from taichi_rocks.config.scene import scene_with
    from taichi_rocks.engine.simulation import Simulation
    from taichi_rocks.render.renderer import Renderer

    out, seen = {}, []
    for stepping in ("full", "active"):
        sim = Simulation(scene_with(fast_scene, {"sim.stepping": stepping}), arch="cpu")
        assert sim.world.stored == (stepping == "active")
        rs = {rocks: Renderer(sim, resolution=(W, H), window_every=0, rocks=rocks) for rocks in ("splat", "particles")}
        try:
            for t in TIMES:
                sim.advance_to(t)
                for rocks, r in rs.items():
                    out[stepping, rocks, t] = r.render_frame().copy()
                if stepping == "active":
                    seen.append(_culling(sim, rs["splat"]))
        finally:
            for r in rs.values():
                r.close()
    return out, seen


def _culling(sim, r):
    """What the last rock pass of ``r`` saw: the state, the view, the slots it visited, the occupied slots."""
    w = sim.world
    vis = r.fields.visible
    return {"state": sim.state(), "active": sim.active_count, "shift": sim.origin[:2] - sim.anchor[:2],
            "view": r.view(), "visited": set(vis.slots.to_numpy()[:r.tiles_in_view].tolist()),
            "occupied": int((w.ts_count.to_numpy() > 0).sum()), "keys": w.ts_key.to_numpy(),
            "tile": w.store_tile, "grid": w.store_grid, "tiles": sim.tile_shift(), "origin": sim.origin.copy()}


@pytest.mark.parametrize("rocks", ["splat", "particles"])
@pytest.mark.parametrize("t", TIMES, ids=["in_the_air", "after_origin_shift"])
def test_active_stepping_renders_the_frames_of_full_stepping(frames, rocks, t):
    out, _ = frames
    full, act = out["full", rocks, t], out["active", rocks, t]
    assert full.astype(float).std() > 10.0  # a real frame
    assert np.array_equal(full, act), (np.abs(full.astype(int) - act.astype(int)).max(),
                                       int((full != act).any(axis=2).sum()))


def test_the_moments_compared_have_rocks_in_the_air_and_stored_and_a_shifted_origin(frames):
    _, seen = frames
    for k, s in enumerate(seen):
        n = len(s["state"]["phase"])
        assert (s["state"]["phase"] == 1).sum() > 10
        assert 0 < s["active"] < n // 10  # most rocks are in the tiles: drawing the active list alone would miss them
    assert np.all(seen[0]["shift"] == 0.0) and np.abs(seen[1]["shift"]).max() >= 128.0


def _passes_view_test(p, r, view, tan_x, tan_y, near, far):
    """The rock pass's per-rock view test (render/splat.py _draw_rock), in NumPy (float64)."""
    d = p - view.eye
    z, x, y = d @ view.fwd, d @ view.right, d @ view.up
    sec_x, sec_y = np.sqrt(1 + tan_x ** 2), np.sqrt(1 + tan_y ** 2)
    return (z > near - r) & ((d ** 2).sum(1) < far ** 2) & (np.abs(x) < z * tan_x + r * sec_x) & \
        (np.abs(y) < z * tan_y + r * sec_y)


def test_tile_culling_keeps_every_tile_with_a_rock_in_view_and_skips_others(frames, fast_scene):
    """Reference: every stored rock (in NumPy, from the state) that passes the per-rock view test lies in a tile
    the pass visited; and the pass skipped tiles (the bed reaches behind the camera)."""
    from taichi_rocks.render.camera import NEAR, Lens

    _, seen = frames
    tan_x, tan_y, _ = Lens.of(float(fast_scene.camera.fov), W, H)
    for s in seen:
        st = s["state"]
        resting = st["phase"] == 0
        p = st["positions"][resting] - s["origin"]
        r = st["radii"][resting]
        inview = _passes_view_test(p, r, s["view"], tan_x, tan_y, NEAR, float(fast_scene.render.draw_distance))
        keys = np.floor(p[inview, :2] / s["tile"]).astype(np.int64) + s["tiles"].astype(np.int64)
        g = s["grid"]
        slots = (keys[:, 0] % g) * g + keys[:, 1] % g
        assert inview.sum() > 100
        # a resting rock in view is either in a visited tile or in the active list (a rock whose tile was full)
        stored_slots = {int(sl) for sl, k in zip(slots, keys) if np.array_equal(s["keys"][sl], k)}
        assert stored_slots <= s["visited"], sorted(stored_slots - s["visited"])[:5]
        assert len(stored_slots) > 5
        assert len(s["visited"]) < s["occupied"], (len(s["visited"]), s["occupied"])
