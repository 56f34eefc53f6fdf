"""The Panda3D game (examples/panda3d_game.py): its rocks' mirror and chunks against NumPy references, its marks on
the glass, and the game itself run offscreen twice over the same recorded drive, with the truck's tires throwing and
not: the frames differ where the stones fly, and the game counts the hits ``impacts()`` reports.

The game's runs take ~20-40 s on two shared cores (two processes, each starting Taichi and Panda3D and drawing 120
frames at 480x270): the comparison with the tires off needs both, and the test is the only one of a real game
engine drawing the rock system.
"""

import json
import math
import os
import subprocess
import sys
from types import SimpleNamespace

import imageio.v3 as iio
import numpy as np
import panda3d  # noqa: F401  (tools/setup.sh installs it: the game's test runs everywhere the suite does)
import pytest
from panda3d.core import NodePath
from scipy.spatial.transform import Rotation

from cli_util import ROOT

sys.path.insert(0, str(ROOT / "examples"))
from rockgame import rocks as R  # noqa: E402
from rockgame.controls import Replay  # noqa: E402
from rockgame.hits import CHIP, CRACK, GAP, Glass, windscreen_mark  # noqa: E402
from rockgame.scene import FOLLOW_DRIVE, PLAYER, game_scene  # noqa: E402

GAME = ROOT / "examples" / "panda3d_game.py"
FRAMES, W, H = 120, 480, 270
CHECKED = (60, 90, 120)  # frames whose pixels are compared


# ---------------------------------------------------------------------------------------------- the mirror's chunks
def _rows(ids, pos, phase, quat):
    return SimpleNamespace(ids=np.asarray(ids, np.int32), positions=np.asarray(pos, np.float64),
                           phase=np.asarray(phase, np.int8), orientations=np.asarray(quat, np.float32))


def _check_chunks(mesh: R.RockMesh, pos, phase, quat, origin):
    """Every rock in exactly one chunk, in the slot it is listed at, in the cell it lies in (the chunk of the
    stones in flight when in the air), and drawn where it is: its pebble's corners as a NumPy reference turns
    them."""
    n = len(pos)
    np.testing.assert_array_equal(mesh.positions, pos)
    np.testing.assert_array_equal(mesh.phase, phase)
    assert sum(c.count for c in mesh.chunks) == n
    seen = np.zeros(n, int)
    for c, chunk in enumerate(mesh.chunks):
        rocks = chunk.rock[:chunk.count]
        seen[rocks] += 1
        assert np.all(chunk.rock[chunk.count:] == -1)
        np.testing.assert_array_equal(mesh.chunk_of[rocks], c)
        np.testing.assert_array_equal(mesh.slot_of[rocks], np.arange(chunk.count))
        assert chunk.tris.getNumVertices() == 12 * chunk.count and chunk.dots.getNumVertices() == chunk.count
        if not chunk.count:
            continue
        cells = np.floor((pos[rocks, :2] - origin[:2]) / R.CELL).astype(np.int64)
        keys = (cells[:, 0] * (1 << 32) + cells[:, 1]) << 1
        keys[phase[rocks] == R.FLYING] = R.AIR  # the stones in flight: one chunk
        np.testing.assert_array_equal(keys, chunk.key)
        pebbles, points = chunk.views()
        turned = np.stack([Rotation.from_quat(quat[i].astype(np.float64)).apply(mesh._shape[i]) for i in rocks])
        np.testing.assert_allclose(pebbles["p"][:chunk.count], (pos[rocks] - origin)[:, None, :] + turned, atol=2e-4)
        np.testing.assert_allclose(points["p"][:chunk.count], pos[rocks] - origin, atol=2e-4)
    np.testing.assert_array_equal(seen, 1)


def test_the_mirror_files_every_changed_row_where_its_rock_is_drawn():
    rng = np.random.default_rng(53)
    n, origin = 3000, np.array([1000.0, -500.0, 0.0])
    radii = rng.uniform(0.015, 0.05, n)
    mesh = R.RockMesh(radii, origin, NodePath("test"))
    pos = origin + np.column_stack([rng.uniform(-20, 20, (n, 2)), radii])
    phase = np.zeros(n, np.int8)
    quat = Rotation.random(n, random_state=1).as_quat().astype(np.float32)
    mesh.apply(_rows(np.arange(n), pos, phase, quat))  # the first changes(): every rock
    _check_chunks(mesh, pos, phase, quat, origin)
    for frame in range(12):
        ids = rng.choice(n, int(rng.integers(0, 900)), replace=False)
        k = len(ids)
        kind = rng.integers(0, 4, k)  # 0: recycled far, 1: a nudge across cells, 2: launched or landed, 3: tumbles
        new = pos[ids].copy()
        new[kind == 0, :2] += rng.uniform(-60, 60, (np.sum(kind == 0), 2))
        new[kind == 1, :2] += rng.normal(scale=0.8, size=(np.sum(kind == 1), 2))
        new[kind == 2, 2] += rng.uniform(0, 2, np.sum(kind == 2))
        ph = phase[ids].copy()
        ph[kind == 2] = 1 - np.minimum(ph[kind == 2], 1)
        ph[kind == 1] = rng.integers(0, 3, np.sum(kind == 1))
        q = quat[ids].copy()
        q[kind == 3] = Rotation.random(np.sum(kind == 3), random_state=frame).as_quat()
        if frame == 5:  # every rock of one cell leaves it: its chunk is emptied, then used again for another cell
            cell = np.floor((pos[:, :2] - origin[:2]) / R.CELL)
            ids = np.flatnonzero((cell == cell[0]).all(axis=1) & (phase != 1))
            new, ph, q = pos[ids] + (200.0, 0.0, 0.0), phase[ids], quat[ids]
        pos[ids], phase[ids], quat[ids] = new, ph, q
        mesh.apply(_rows(ids, new, ph, q))
        _check_chunks(mesh, pos, phase, quat, origin)
        if frame == 5:
            assert mesh._free  # the emptied chunk waits for a cell
    assert not mesh.apply(_rows([], np.zeros((0, 3)), [], np.zeros((0, 4))))  # a frame where nothing changed
    _check_chunks(mesh, pos, phase, quat, origin)


# ---------------------------------------------------------------------------------------------- the marks
@pytest.mark.parametrize("damage", [CHIP, CRACK])
def test_windscreen_marks_stay_on_the_glass(damage):
    from taichi_rocks.engine.events import EVENT_DTYPE
    from taichi_rocks.motion.cabin import cabin_of

    scene = game_scene()
    cab = cabin_of(scene.vehicles[scene.vehicle_index(PLAYER)])
    glass = Glass(cab)
    foot = np.array([cab.base_x, 0.0, cab.belt])  # a point of the glass's plane
    rng = np.random.default_rng(damage)
    for _ in range(40):
        e = np.zeros((), EVENT_DTYPE)
        u = rng.uniform(0.1, 0.9)  # a hit well inside the glass (one at its very edge may leave no mark)
        z = cab.belt + u * (cab.roof - cab.belt)
        half = 0.9 * (cab.base_half + u * (cab.top_half - cab.base_half))
        e["point"] = (cab.windscreen_x(z), rng.uniform(-half, half), z)
        e["damage"], e["rock"], e["step"] = damage, rng.integers(0, 1 << 20), rng.integers(0, 1 << 20)
        segs = windscreen_mark(e, float(rng.uniform(0, 1)), glass).reshape(-1, 3)
        # on the glass's plane, GAP outside it, and inside its trapezoid
        assert len(segs) >= 2
        np.testing.assert_allclose((segs - foot) @ glass.normal, GAP, atol=1e-9)
        inside = (segs[:, 2] >= cab.belt - 1e-9) & (segs[:, 2] <= cab.roof + 1e-9)
        w = cab.base_half + (segs[:, 2] - cab.belt) / (cab.roof - cab.belt) * (cab.top_half - cab.base_half)
        assert inside.all() and np.all(np.abs(segs[:, 1]) <= w + 1e-9)


# ---------------------------------------------------------------------------------------------- the game
def _start(out, *extra):
    return subprocess.Popen([sys.executable, str(GAME), "--offscreen", "--frames", str(FRAMES), "--resolution",
                             f"{W}x{H}", "--out", str(out), *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))


@pytest.fixture(scope="module")
def games(tmp_path_factory):
    """The game offscreen over the shipped drive (follow.drive), the truck's tires on and off, side by side."""
    base = tmp_path_factory.mktemp("game")
    procs = {"on": _start(base / "on"), "off": _start(base / "off", "--truck-tires-off")}
    out = {}
    for name, p in procs.items():
        stdout, stderr = p.communicate(timeout=600)
        assert p.returncode == 0, stderr[-3000:]
        assert "Traceback" not in stderr, stderr[-3000:]
        summary = json.loads(stdout.strip().splitlines()[-1])
        out[name] = SimpleNamespace(dir=base / name, summary=summary, stdout=stdout,
                                    log=dict(np.load(base / name / "frames.npz")))
    return out


def _replay(truck_tires: bool):
    """The shipped drive through the rock system alone, as the game drives it: the hits per frame, and every rock's
    state at the checked frames (state() is the reference here; the game reads changes() only)."""
    from taichi_rocks import Simulation

    scene = game_scene(truck_splash=truck_tires)
    sim = Simulation(scene)
    wheelbase = scene.vehicles[scene.vehicle_index(PLAYER)].wheelbase
    drive = Replay(FOLLOW_DRIVE, wheelbase)
    hits, states = [], {}
    sim.changes()
    for f in range(1, FRAMES + 1):
        t = f / 60
        cmd = drive.command(t, 1 / 60)
        sim.drive(PLAYER, cmd.position, cmd.heading, speed=cmd.speed, yaw_rate=cmd.yaw_rate,
                  wheel_spin=cmd.wheel_spin)
        sim.advance_to(t)
        hits.append(len(sim.impacts()))
        sim.changes()
        if f in CHECKED:
            states[f] = sim.state()
    return SimpleNamespace(hits=np.array(hits), states=states)


@pytest.fixture(scope="module")
def replay(taichi_cpu):
    return _replay(True)


@pytest.fixture(scope="module")
def replay_off(taichi_cpu):
    return _replay(False)


def test_the_game_runs_offscreen_and_says_what_it_cost(games):
    for name, g in games.items():
        s = g.summary
        assert set(s) >= {"frames", "fps", "rocks_ms", "draw_ms", "rocks", "hits"}
        assert s["frames"] == FRAMES and s["rocks"] == 50_000
        assert s["fps"] > 0 and s["rocks_ms"] > 0 and s["draw_ms"] > 0
        frames = sorted(g.dir.glob("frame_*.png"))
        assert len(frames) == FRAMES and not list(g.dir.glob("*.part*"))
        assert iio.imread(frames[-1]).shape == (H, W, 3)
        for part in ("rocks", "mirror", "game", "draw", "png"):  # the budget's table, a line a part
            assert any(line.split()[:1] == [part] for line in g.stdout.splitlines()), part


def test_the_game_counts_the_hits_impacts_reported(games, replay):
    on, off = games["on"], games["off"]
    np.testing.assert_array_equal(on.log["hits"], replay.hits)
    assert on.summary["hits"] == int(replay.hits.sum()) > 0
    assert off.summary["hits"] == 0  # nothing thrown, nothing hits


def test_the_mirror_kept_from_changes_counts_the_stones_in_flight(games, replay):
    for f, st in replay.states.items():
        assert games["on"].log["flying"][f - 1] == np.count_nonzero(st.phase == 1) > 20
    assert not games["off"].log["flying"].any()


def _pixels(view, points, origin):
    """Pixel (x, y) of world ``points`` through a frame's view matrix (examples/rockgame/game.py view_matrix), and
    which of them lie in front of the camera inside the frame."""
    clip = np.column_stack([points - origin, np.ones(len(points))]) @ view
    ndc = clip[:, :3] / clip[:, 3:4]
    x, y = (ndc[:, 0] + 1) * W / 2, (1 - ndc[:, 1]) * H / 2
    ok = (clip[:, 3] > 0) & (np.abs(ndc[:, 2]) < 1) & (x >= 2) & (x < W - 2) & (y >= 0.12 * H) & (y < H - 2)
    return np.column_stack([x, y]), ok


def _hidden(eye, points, state, scene):
    """Which ``points`` a vehicle's body hides from ``eye`` (world m): the segment from the eye to each point meets
    one of the convex parts of motion/bodies.py (clipped against its six face planes, Cyrus-Beck)."""
    from taichi_rocks.motion.bodies import body_parts, hexahedron_planes

    d = points - eye
    out = np.zeros(len(points), bool)
    for spec, at, h in zip(scene.vehicles, state.vehicle_positions, state.vehicle_headings):
        c, s = math.cos(h), math.sin(h)
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        for part in body_parts(spec).parts:
            planes = hexahedron_planes(part.corners() @ turn.T + at)
            enter, leave = np.zeros(len(points)), np.full(len(points), 0.97)  # stop short of the stone itself
            for n, off in zip(planes[:, :3], planes[:, 3]):
                num, den = off - eye @ n, d @ n
                with np.errstate(divide="ignore", invalid="ignore"):
                    t = num / den
                enter = np.where(den < 0, np.maximum(enter, t), enter)
                leave = np.where(den > 0, np.minimum(leave, t), leave)
                leave = np.where((den == 0) & (num < 0), -1.0, leave)
            out |= enter < leave
    return out


def test_the_frames_show_the_stones_in_flight(games, replay, replay_off):
    on, off = games["on"], games["off"]
    found = []
    for f in CHECKED:
        a = iio.imread(on.dir / f"frame_{f:04d}.png").astype(int)
        b = iio.imread(off.dir / f"frame_{f:04d}.png").astype(int)
        np.testing.assert_array_equal(on.log["view"][f - 1], off.log["view"][f - 1])  # the same drive, camera
        changed = np.abs(a - b).sum(axis=2) > 24
        changed[: int(0.12 * H)] = False  # the HUD's line: its counts differ
        assert 0.0005 < changed.mean() < 0.25, changed.mean()  # some pixels, not the whole frame
        st = replay.states[f]
        flying = st.positions[st.phase == 1]
        px, ok = _pixels(on.log["view"][f - 1], flying, on.log["origin"])
        px = px[ok & ~_hidden(on.log["eye"][f - 1], flying, st, game_scene())]  # the stones the camera sees
        near = np.zeros(len(px), bool)  # a changed pixel within 2 px of the stone
        for k, (x, y) in enumerate(px):
            x0, y0 = int(round(x)), int(round(y))
            near[k] = changed[max(y0 - 2, 0):y0 + 3, max(x0 - 2, 0):x0 + 3].any()
        found.append((len(px), near.mean()))
        # and the other way round: the changed pixels are where the two runs' rocks differ (in the air, landed
        # elsewhere, or gone from where they lay), or where a hit flashes or marks the car (FLASH_PX)
        other = replay_off.states[f].positions
        differ = np.linalg.norm(st.positions - other, axis=1) > 1e-3
        mp, mok = _pixels(on.log["view"][f - 1], np.concatenate([st.positions[differ], other[differ]]), on.log["origin"])
        ys, xs = np.nonzero(changed)
        d = np.min(np.hypot(xs[:, None] - mp[mok, 0][None], ys[:, None] - mp[mok, 1][None]), axis=1)
        assert np.mean(d < 6) > 0.9, (f, np.mean(d < 6))
    assert all(n >= 10 for n, _ in found), found
    assert all(share > 0.9 for _, share in found), found  # measured: every one


def test_bad_arguments_are_one_line_and_status_2(tmp_path):
    (tmp_path / "frame_0001.png").write_bytes(b"x")
    for args, want in ((["--resolution", "12x"], "--resolution: expected WIDTHxHEIGHT"),
                       (["--frames", "0"], "--frames: must be >= 1"),
                       (["--offscreen", "--out", str(tmp_path)], "already holds frames (--overwrite replaces them)"),
                       (["--out", str(tmp_path / "x")], "--out: frames are written offscreen only"),
                       (["--offscreen", "--drive", str(tmp_path / "none.drive")], "--drive: ")):
        r = subprocess.run([sys.executable, str(GAME), *args], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and want in r.stderr, r.stderr
    assert (tmp_path / "frame_0001.png").read_bytes() == b"x"


def test_the_shipped_drive_follows_the_truck():
    """follow.drive (autopilot.py wrote it) keeps behind the truck on the road for its 30 s."""
    from taichi_rocks.config.drivefile import read_drive
    from rockgame.scene import truck_path

    rows = np.array(read_drive(FOLLOW_DRIVE))
    path = truck_path(game_scene())
    assert rows[-1, 0] == pytest.approx(30.0) and len(rows) == 1801
    for t, x, y, *_ in rows[::60]:
        p = path.pose(t)
        gap = math.hypot(p.position[0] - x, p.position[1] - y)
        assert 5.0 < gap < 20.0, (t, gap)  # centre to centre: behind the truck, close enough to be hit
