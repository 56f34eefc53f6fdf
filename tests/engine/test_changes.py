"""``Simulation.changes()`` (engine/changes.py): its rows, applied to a mirror of the bed, reproduce ``state()``
bit for bit after every frame, in both stepping modes, with tumbling, across origin shifts in both axes, a
restore, ``set_rocks`` and coasting; the rows are exactly the rocks whose state differs from the previous
frame's (an independent NumPy diff of two ``state()`` reads); the origin shift's listing matches a NumPy
reference of f32 rounding on adversarial values."""

import numpy as np
import pytest

from scenes_util import scene
from taichi_rocks.engine import changes, origin
from taichi_rocks.engine.simulation import Simulation

pytestmark = pytest.mark.usefixtures("taichi_cpu")

CAR = {"length": 4.0, "width": 1.8, "wheelbase": 2.6, "track": 1.5, "tire_radius": 0.33}


def _pair(points, speed):
    """A splashing car 6 m ahead of the player the bed follows, both on the line through ``points``."""
    (x0, y0), (x1, y1) = points
    d = np.array([x1 - x0, y1 - y0]) / np.hypot(x1 - x0, y1 - y0)
    lead = [[x0 + 6 * d[0], y0 + 6 * d[1]], [x1 + 6 * d[0], y1 + 6 * d[1]]]
    return [{"name": "lead", **CAR, "path": {"points": lead, "speed": speed}},
            {"name": "player", **CAR, "splash": False, "path": {"points": [[x0, y0], [x1, y1]], "speed": speed}}]


def _scene(stepping, speed=100.0, points=((3.3, -1.7), (2003.3, 1998.3)), **kw):
    """Diagonal and fast: the floating origin (shifts of 64 m once the bed is 128 m away) moves in x and y
    within the run, so rocks near a zero coordinate round when shifted."""
    return scene(rocks=3000, radius=6.0, vehicles=_pair(points, speed), bed={"follow": "player"},
                 sim={"detection": "patch", "dt": 0.004, "stepping": stepping}, duration=6.0, **kw)


class Mirror:
    """A game's copy of the bed, kept by changes() alone."""

    def __init__(self, n, spin):
        self.pos = np.full((n, 3), np.nan)
        self.phase = np.full(n, -9, np.int8)
        self.orient = np.full((n, 4), np.nan, np.float32) if spin else None

    def apply(self, rows):
        ids = rows["ids"]
        assert ids.dtype == np.int32 and rows["positions"].dtype == np.float64 and rows["phase"].dtype == np.int8
        assert len(np.unique(ids)) == len(ids)  # one row per rock
        self.pos[ids] = rows["positions"]
        self.phase[ids] = rows["phase"]
        if self.orient is not None:
            self.orient = self.orient.astype(rows["orientations"].dtype)
            self.orient[ids] = rows["orientations"]

    def check(self, st):
        assert np.array_equal(self.pos, st["positions"])
        assert np.array_equal(self.phase, st["phase"])
        if self.orient is not None:
            assert np.array_equal(self.orient, st["orientations"])


def _diff(prev, st, spin):
    """Ids whose drawn state differs between two state() reads (independent of the engine's bookkeeping)."""
    d = (prev["positions"] != st["positions"]).any(1) | (prev["phase"] != st["phase"])
    if spin:
        d |= (prev["orientations"] != st["orientations"]).any(1)
    return np.flatnonzero(d)


@pytest.mark.parametrize("stepping,tumble", [("active", False), ("full", False), ("active", True)])
def test_rows_reproduce_state_every_frame(stepping, tumble):
    sim = Simulation(_scene(stepping), tumble=tumble)
    mirror, prev, shifts, moved = Mirror(sim.n_rocks, tumble), None, 0, 0
    origin = sim.origin.copy()
    for f in range(150):
        sim.advance_to(f / 30)
        rows = sim.changes(velocities=f % 2 == 1)
        st = sim.state()
        mirror.apply(rows)
        mirror.check(st)
        if f % 2:  # the rows' velocities are state()'s
            assert np.array_equal(rows["velocities"], st["velocities"][rows["ids"]])
            assert rows["velocities"].dtype == st["velocities"].dtype
        if prev is None:
            assert len(rows["ids"]) == sim.n_rocks  # the first read gives every rock
        else:
            assert np.array_equal(np.sort(rows["ids"]), _diff(prev, st, tumble))  # exactly the rocks that changed
            moved += len(rows["ids"])
        shifts += int(not np.array_equal(origin, sim.origin))
        origin, prev = sim.origin.copy(), st
    assert shifts >= 2 and sim.origin[0] != 0 and sim.origin[1] != 0  # the origin moved in both axes
    assert 0 < moved < 0.5 * 149 * sim.n_rocks  # rows are the few that changed, not the bed
    assert len(sim.changes()["ids"]) == 0  # nothing changed since the last read


def test_restore_set_rocks_and_coasting():
    sim = Simulation(_scene("active", speed=[30.0, 0.0], points=((0.0, 0.0), (40.0, 0.0))))
    mirror = Mirror(sim.n_rocks, False)
    mirror.apply(sim.changes())
    sim.advance_to(0.5)
    saved = sim.checkpoint()
    mirror.apply(sim.changes())
    mirror.check(sim.state())
    sim.set_rocks([5, 7], positions=[[1.0, 2.0, 3.0], [2.0, 1.0, 0.5]], phase=[1, 1], velocities=[0.0, 0.0, 1.0])
    rows = sim.changes()
    assert len(rows["ids"]) == sim.n_rocks  # loaded rocks: every row again
    mirror.apply(rows)
    mirror.check(sim.state())
    sim.restore(saved)
    mirror.apply(sim.changes())
    mirror.check(sim.state())
    for f in range(1, 200):  # the vehicles stop at 40 m: steps then coast
        sim.advance_to(0.5 + f * 0.05)
        mirror.apply(sim.changes())
    assert sim.steps_coasted > 0
    mirror.check(sim.state())


def test_without_tracking():
    sim = Simulation(_scene("active"), track_changes=False)
    assert not sim.plan.drawn and not sim.world.drawn
    sim.step(3)
    with pytest.raises(RuntimeError, match="track_changes"):
        sim.changes()


def test_shift_listing_matches_float32_rounding():
    """The origin's move (engine/origin.py) lists exactly the rocks whose world position float64(p) + origin
    changes when the origin moves (NumPy: the f32 move and the float64 sums), on adversarial values: zeros, signed zeros, tiny and huge
    coordinates, exact multiples of the shift, values that cross a power of two; an anchor with a fraction."""
    sim = Simulation(_scene("full"))
    w, n = sim.world, sim.n_rocks
    rng = np.random.default_rng(4)
    special = np.array([0.0, -0.0, 1e-30, -1e-30, 0.3, -0.3, 63.99, 64.0, 64.01, 127.99, 128.0, -64.0, 1e7, -1e7,
                        2.0 ** 24, 1.5, 96.0, 32.000004, 1e-7], np.float32)
    p = rng.normal(0.0, 50.0, (n, 3)).astype(np.float32)
    p[: len(special), 0] = special
    p[len(special): 2 * len(special), 1] = special
    d = np.array([128.0, -64.0])
    for anchor in (np.array([0.0, 0.0]), np.array([3.3, -1.7])):
        w.drawn_pos.from_numpy(p)
        w.drawn_flag.fill(0)
        w.drawn_count[None] = 0
        before, after = anchor + np.array([64.0, 0.0]), anchor + np.array([64.0, 0.0]) + d
        origin.put_move(w, d, before, after)
        origin.move_origin(w, True)
        k = int(changes.listed_count(w))
        listed = np.sort(w.drawn_list.to_numpy()[:k])
        moved = p[:, :2] - d.astype(np.float32)
        same = moved.astype(np.float64) + after == p[:, :2].astype(np.float64) + before
        assert np.array_equal(w.drawn_pos.to_numpy()[:, :2], moved)  # the mirror moves as the rocks do
        assert np.array_equal(listed, np.flatnonzero(~same.all(1)))
        assert 0 < k < n
