"""Small scenes built in code for tests."""

import numpy as np
import pytest

from taichi_rocks.config.scene import SceneError, parse_scene


def scene(rocks=2000, radius=8.0, vehicles=None, effects=None, sim=None, world=None, bed=None, launch=None,
          **top):
    vehicles = vehicles or [{"name": "car", "path": {"points": [[0.0, 0.0], [400.0, 0.0]], "speed": 10.0}}]
    data = {"duration": 2.0, "seed": 3, "bed": {"radius": radius, "rocks": rocks,
                                                "rock_radius": [0.02, 0.05], **(bed or {})},
            "vehicle": vehicles, "effects": effects or {}, "sim": {"dt": 0.004, **(sim or {})},
            "world": world or {}, "launch": launch or {}, **top}
    return parse_scene(data, source="<test>")


class FakePath:
    """A scripted pose function (for jumps that a real path cannot make)."""

    def __init__(self, fn):
        self.fn = fn
        self.duration = None

    def pose(self, t):
        from taichi_rocks.motion.paths import Pose

        x, y, heading, speed = self.fn(t)
        return Pose(np.array([x, y], float), heading, speed, 0.0,
                    np.array([speed * np.cos(heading), speed * np.sin(heading)]))



def problems(data, source="s.toml"):
    """The problems SceneError lists for the scene dict ``data`` (it must be refused)."""
    with pytest.raises(SceneError) as e:
        parse_scene(data, source=source)
    return e.value.problems


def equal_area_bins(xy, center, radius, rings=5, sectors=8):
    d = xy - center
    r2 = (d ** 2).sum(1) / radius ** 2
    ring = np.minimum((r2 * rings).astype(int), rings - 1)
    sector = ((np.arctan2(d[:, 1], d[:, 0]) + np.pi) / (2 * np.pi) * sectors).astype(int) % sectors
    return np.bincount(ring * sectors + sector, minlength=rings * sectors)


def uniformity_pvalue(xy, center, radius):
    from scipy.stats import chisquare

    counts = equal_area_bins(xy, center, radius)
    return chisquare(counts).pvalue


def reload_probe(probe, pos, radius, rays, cell=None):
    """Reuse a compiled ``harness.Probe`` (Taichi compiles per World) for other rocks, rays and cell size.

    The probe must have been built with at least as many rocks and rays, hash entries (aabb: larger radii,
    smaller cells) and ray cells (longer rays, smaller cells) as needed. Missing rocks and rays are padded
    with dummies far away (harness.padded_rocks, Probe.set_rays), which nothing can hit. Returns the probe;
    ``hits()`` then works as usual (indices < len(pos))."""
    from harness import padded_rocks, put_rocks
    from taichi_rocks.engine import hashgrid
    from taichi_rocks.engine.params import IPar, Par, dilation_cells

    w = probe.w
    cap = w.pos.shape[0]
    pos = np.asarray(pos, np.float64).reshape(-1, 3)
    radius = np.asarray(radius, np.float64).reshape(-1)
    rays = np.asarray(rays, np.float64).reshape(-1, 2, 3)
    n, m = len(pos), len(rays)
    assert n <= cap and m <= w.n_tires, (n, cap, m, w.n_tires)
    cell = float(probe.cell if cell is None else cell)
    pos, radius = padded_rocks(pos, radius, cap, cell)
    length = float(np.max(np.linalg.norm(rays[:, 1] - rays[:, 0], axis=1))) if m else 0.0
    assert hashgrid.ray_capacity(length, cell) <= w.ray_capacity, "probe built for shorter rays / larger cells"
    r_max = float(radius.max())
    par, ipar = w.par.to_numpy(), w.ipar.to_numpy()
    par[Par.CELL], par[Par.R_MAX] = cell, r_max
    ipar[IPar.DILATE] = dilation_cells(r_max, cell) if probe.center else 0
    w.set_params(par, ipar)
    put_rocks(w, pos=pos, radius=radius, hit_step=np.full(cap, -1))
    probe.n, probe.cell, probe.rays = n, cell, rays
    hashgrid.clear_counts(w)
    hashgrid.count_all(w, probe.center, 0.0, 0.0)
    probe.total = hashgrid.inclusive_scan(w)
    assert probe.total <= w.entry_capacity, "probe built for fewer hash entries"
    hashgrid.scatter(w, probe.center)
    return probe


# One World layout shared by the reference tests (tests/engine/test_reference_stepping.py, test_uniform_launch.py,
# test_ground_contact.py): 3,000 rocks in a 4.5 m bed, ray detection, the "uniform" launch model with wide ranges.
REFERENCE_ROCKS, REFERENCE_RADIUS = 3000, 4.5


def reference_scene(speed=15.0, world=None, effects=None, sim=None, launch=None, **top):
    """A car driving straight along +x from the origin at ``speed`` (0: parked), the bed following it."""
    car = {"name": "car", "path": {"points": [[0.0, 0.0], [400.0, 0.0]], "speed": speed}}
    return scene(rocks=REFERENCE_ROCKS, radius=REFERENCE_RADIUS, vehicles=[car], world=world, effects=effects,
                 sim={"detection": "ray", **(sim or {})},
                 launch={"model": "uniform", "release_angle": [10.0, 60.0], "spread": 20.0, **(launch or {})},
                 **top)
