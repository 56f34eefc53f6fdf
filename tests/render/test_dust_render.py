"""Dust's drawing (render/dust.py): the translucency's colour and radius laws against NumPy, nothing made
without dust, and a frame of a run with dust that differs from the same frame without it only by the dust."""

import numpy as np

from scenes_util import scene
from taichi_rocks.config.effects.dust import Dust
from taichi_rocks.engine.simulation import Simulation
from taichi_rocks.render.dust import MIN_ALPHA, draw_dust, dust_looks
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
