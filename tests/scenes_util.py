"""Small scenes built in code for tests."""

import numpy as np

from taichi_rocks.scene import parse_scene


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
        from taichi_rocks.paths import Pose

        x, y, heading, speed = self.fn(t)
        return Pose(np.array([x, y], float), heading, speed, 0.0,
                    np.array([speed * np.cos(heading), speed * np.sin(heading)]))


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
