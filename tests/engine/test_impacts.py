"""The swept sphere-hull test (engine/impacts.py) against an independent NumPy reference (impacts_util.py).

Parts: boxes (5 mm thin to 8 m), cabin-like frustums and affine images of both (rotated, sheared); paths aimed
at faces, edges and corners, passing just inside or outside the dilated part, tangent to it (grazing),
starting in contact or inside, up to 100 m/s relative over a 2 ms step; coordinates small, negative or huge
(float64). Float64 results must agree with the reference to ~1e-9 m; float32 ones (the simulation's default
precision, in the vehicle's frame) to a few um, and no stone that goes deeper than that into a part is missed.
"""

import math

import numpy as np
import pytest
import taichi as ti
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from impacts_util import Hull, SweptKernel, first_contacts, min_on
from taichi_rocks.motion.bodies import EDGES, FACE_CORNERS, Part, hexahedron_planes

pytestmark = pytest.mark.usefixtures("taichi_cpu")

SETTINGS = dict(deadline=None, derandomize=True, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
STEP = 0.002  # s


@pytest.fixture(scope="module")
def k64(taichi_cpu):
    return SweptKernel(ti.f64)


@pytest.fixture(scope="module")
def k32(taichi_cpu):
    return SweptKernel(ti.f32)


def box_corners(center, size):
    return Part("p", "box", (tuple(center), tuple(size)), (), ()).corners()


def frustum_corners(bottom, top, z0, z1):
    return Part("p", "frustum", (bottom, top, z0, z1), (), ()).corners()


def rotation(q):
    q = np.asarray(q, np.float64)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


# ------------------------------------------------------------------------------------------ strategies
unit = st.floats(0.0, 1.0)


@st.composite
def parts(draw, thin=False):
    """Corners (8, 3) of a box, a frustum or an affine image of one, near the origin."""
    kind = draw(st.sampled_from(["box", "frustum", "affine"]))
    size = [draw(st.floats(0.005 if thin else 0.05, 4.0)) for _ in range(3)]
    if thin:
        size[draw(st.integers(0, 2))] = 0.005
    if kind == "box":
        return box_corners([draw(st.floats(-2.0, 2.0)) for _ in range(3)], size)
    a0 = -size[0] / 2
    a1 = size[0] / 2
    b0 = a0 + draw(unit) * 0.45 * size[0]
    b1 = a1 - draw(unit) * 0.45 * size[0]
    c = frustum_corners((a0, a1, size[1] / 2), (b0, b1, size[1] / 2 * (0.6 + 0.4 * draw(unit))), 0.0, size[2])
    if kind == "frustum":
        return c
    rot = rotation([draw(st.floats(-1.0, 1.0)) for _ in range(3)] + [1.0])
    shear = np.eye(3)
    shear[0, 1], shear[1, 2] = draw(st.floats(-0.5, 0.5)), draw(st.floats(-0.5, 0.5))
    return c @ (rot @ shear).T + np.array([draw(st.floats(-2.0, 2.0)) for _ in range(3)])


def normals_of(corners):
    return hexahedron_planes(corners)[:, :3]


def _unit(v):
    return v / np.linalg.norm(v)


@st.composite
def surface_point(draw, corners):
    """A point of the part's surface and an outward direction in its normal cone: on a face, an edge or at a
    corner."""
    n = normals_of(corners)
    where = draw(st.sampled_from(["face", "edge", "corner"]))
    if where == "face":
        f = draw(st.integers(0, 5))
        w = np.array([draw(st.floats(0.01, 1.0)) for _ in range(4)])
        return (w / w.sum()) @ corners[list(FACE_CORNERS[f])], n[f]
    if where == "edge":
        a, b = EDGES[draw(st.integers(0, 11))]
        faces = [f for f, fc in enumerate(FACE_CORNERS) if a in fc and b in fc]
        s = draw(st.floats(0.0, 1.0))
        mix = draw(st.floats(0.0, 1.0))
        return corners[a] + s * (corners[b] - corners[a]), _unit(mix * n[faces[0]] + (1 - mix) * n[faces[1]])
    i = draw(st.integers(0, 7))
    faces = [f for f, fc in enumerate(FACE_CORNERS) if i in fc]
    w = np.array([draw(st.floats(0.0, 1.0)) for _ in range(3)]) + 1e-3
    return corners[i], _unit(w @ n[faces])


@st.composite
def cases(draw, thin=False, max_speed=100.0, radius=(0.002, 0.05), offsets=(0.0,)):
    """(corners, p0, p1, r): a part and a path, shifted by one of ``offsets`` (and a few metres)."""
    corners = draw(parts(thin=thin))
    r = draw(st.floats(*radius))
    q, u = draw(surface_point(corners))
    kind = draw(st.sampled_from(["aimed", "grazing", "start_contact", "start_inside", "far"]))
    length = draw(st.floats(1e-4, max_speed * STEP)) if draw(st.booleans()) else draw(st.floats(1e-4, 3.0))
    w = _unit(np.array([draw(st.floats(-1.0, 1.0)) for _ in range(3)]) + 1e-6)
    if kind == "aimed":  # through the point at (1 + depth) r off the surface, closing in
        depth = draw(st.floats(-1.0, 1.0))
        c = q + (1.0 + depth) * r * u
        if w @ u > 0:
            w = -w
    elif kind == "grazing":  # tangent to the dilated part at c
        c = q + r * u
        w = _unit(w - (w @ u) * u + 1e-9 * np.cross(u, [0.3, 0.5, 0.7]))
    elif kind == "start_contact":  # at (up to) r from the part
        c = q + r * draw(st.floats(0.0, 1.0)) * u
        p0 = c
        return corners + 0, p0, p0 + length * w, r, draw(st.sampled_from(offsets))
    elif kind == "start_inside":
        wts = np.array([draw(st.floats(0.01, 1.0)) for _ in range(8)])
        p0 = (wts / wts.sum()) @ corners
        return corners, p0, p0 + length * w, r, draw(st.sampled_from(offsets))
    else:  # from anywhere around it
        c = q + u * draw(st.floats(0.0, 3.0))
    s0 = draw(st.floats(0.0, 1.0))
    return corners, c - s0 * length * w, c + (1 - s0) * length * w, r, draw(st.sampled_from(offsets))


# ------------------------------------------------------------------------------------------ the checks
def check(res, corners, p0, p1, r, tol, ref=None):
    """Kernel results against the reference, path by path: the same verdict unless the path grazes within
    ``tol``; a reported contact is a contact (centre at r from the part, point on it, unit normal from it to the
    centre) with no deeper one before it, at the reference's time where that is well conditioned; no path that
    goes deeper than ``tol`` into the dilated part is missed. ``ref``: first_contacts of these paths, if known."""
    hull = Hull(corners)
    hit_ref, t_ref, fmin, _ = ref if ref is not None else first_contacts(hull, p0, p1, r)
    hit, t, point, normal = res["hit"], res["t"], res["point"], res["normal"]

    def never(mask, what):
        if mask.any():
            i = int(np.flatnonzero(mask)[0])
            raise AssertionError(f"{what}: path {i} of {len(mask)}: corners {corners[i].tolist()}, p0 "
                                 f"{p0[i].tolist()}, p1 {p1[i].tolist()}, r {r[i]}, fmin {fmin[i]}, t {t[i]}, "
                                 f"t_ref {t_ref[i]}")

    never((fmin < -tol) & ~hit, "missed a contact")
    never((fmin > tol) & hit, "a contact that is not there")
    never(hit & ((t < 0) | (t > 1)), "t outside [0, 1]")
    d = p1 - p0
    c = p0 + t[:, None] * d
    dist0 = hull.distance(p0)
    start = hit & (t == 0) & (dist0 <= r + tol)
    moving = hit & ~start
    never(moving & (np.abs(hull.distance(c) - r) > tol), "not at r from the part")
    deeper = np.zeros(len(p0), bool)
    m = np.flatnonzero(moving)  # the search on these paths only
    deeper[m] = min_on(hull.take(m), p0[m], p1[m], r[m], t[m]) < -np.broadcast_to(tol, deeper.shape)[m]
    never(deeper, "a deeper contact before the reported one")
    t_probe = np.maximum(np.nan_to_num(t_ref) - 1e-3, 0.0)
    speed_in = (r - hull.distance(p0 + t_probe[:, None] * d)) / 1e-3  # how fast the path closes in there
    sharp = moving & hit_ref & (np.abs(fmin) > tol) & (np.nan_to_num(t_ref) > 0) & (speed_in > 0.01)
    never(sharp & (np.abs(t - np.nan_to_num(t_ref)) * np.linalg.norm(d, axis=1)
                   > 10 * tol / np.minimum(1.0, np.maximum(speed_in, 1e-9))), "the time differs")
    never(hit & (hull.closest(point)[0] > tol), "contact point not on the part")
    never(hit & (np.abs(np.linalg.norm(normal, axis=1) - 1.0) > 1e-5), "normal not a unit vector")
    inside = start & (dist0 == 0)  # started inside: any face's normal
    gap = np.where(start, dist0, r)[:, None]  # started within r: closest point and direction to the centre
    never(hit & ~inside & (np.linalg.norm(point + gap * normal - c, axis=1) > 3 * tol), "centre not off the "
                                                                                          "point along the normal")


def run_cases(kernel, items, tol_of):
    corners = np.array([it[0] + it[4] for it in items])
    p0 = np.array([it[1] + it[4] for it in items])
    p1 = np.array([it[2] + it[4] for it in items])
    r = np.array([it[3] for it in items])
    tol = np.array([tol_of(abs(it[4]) + 10.0) for it in items])
    check(kernel(p0, p1, r, corners), corners, p0, p1, r, tol)


# ------------------------------------------------------------------------------------------ property tests
@settings(max_examples=25, **SETTINGS)
@given(batch=st.lists(cases(offsets=(0.0, -3.0, 1.0e4, -2.5e5, 1.0e6)), min_size=1, max_size=32))
def test_swept_f64_matches_the_reference(k64, batch):
    run_cases(k64, batch, lambda scale: 1e-9 + 4e-15 * scale)


@settings(max_examples=12, **SETTINGS)
@given(batch=st.lists(cases(thin=True, radius=(0.002, 0.01)), min_size=1, max_size=32))
def test_swept_thin_boxes(k64, batch):
    run_cases(k64, batch, lambda scale: 1e-9)


@settings(max_examples=20, **SETTINGS)
@given(batch=st.lists(cases(max_speed=100.0, radius=(0.002, 0.04), offsets=(0.0, -4.0, 6.0)), min_size=1,
                      max_size=32))
def test_swept_f32_never_misses(k32, batch):
    """Float32 in the vehicle's frame (coordinates of a few metres): agreement to ~5 um and nothing deeper
    than that goes unseen."""
    run_cases(k32, batch, lambda scale: 6e-7 * scale)


# ------------------------------------------------------------------------------------------ closed forms
UNIT_BOX = box_corners((0.0, 0.0, 0.0), (2.0, 2.0, 2.0))


def one(kernel, p0, p1, r, corners=UNIT_BOX):
    res = kernel(np.array([p0]), np.array([p1]), np.array([r]), np.array([corners]))
    return {k: v[0] for k, v in res.items()}


def test_face_edge_and_corner_contacts_in_closed_form(k64):
    r = 0.1
    res = one(k64, (3.0, 0.2, -0.3), (0.0, 0.2, -0.3), r)  # face +x: the centre stops at x = 1 + r
    assert res["hit"] and res["face"] == 0
    assert res["t"] == pytest.approx((3.0 - 1.1) / 3.0, abs=1e-12)
    np.testing.assert_allclose(res["point"], (1.0, 0.2, -0.3), atol=1e-12)
    np.testing.assert_allclose(res["normal"], (1.0, 0.0, 0.0), atol=1e-12)
    res = one(k64, (2.0, 0.4, 2.0), (0.0, 0.4, 0.0), r)  # edge x = z = 1: centre at r/sqrt(2) off it per axis
    a = 1.0 + r / math.sqrt(2.0)
    assert res["hit"] and res["t"] == pytest.approx((2.0 - a) / 2.0, abs=1e-12)
    np.testing.assert_allclose(res["point"], (1.0, 0.4, 1.0), atol=1e-12)
    np.testing.assert_allclose(res["normal"], (1 / math.sqrt(2), 0.0, 1 / math.sqrt(2)), atol=1e-12)
    res = one(k64, (2.0, 2.0, 2.0), (0.0, 0.0, 0.0), r)  # corner (1, 1, 1) along the diagonal
    b = 1.0 + r / math.sqrt(3.0)
    assert res["hit"] and res["t"] == pytest.approx((2.0 - b) / 2.0, abs=1e-12)
    np.testing.assert_allclose(res["point"], (1.0, 1.0, 1.0), atol=1e-12)
    miss = one(k64, (2.0, 2.0, 2.0), (1.0 + 0.06, 1.0 + 0.06, 1.0 + 0.06), r)  # stops short: 0.104 off
    assert not miss["hit"]


@pytest.mark.parametrize("speed", [60.0, 100.0])
@pytest.mark.parametrize("real", ["f32", "f64"])
def test_a_4mm_stone_does_not_tunnel_through_a_corner(k32, k64, speed, real):
    """A 4 mm stone crossing a car's corner region within one 2 ms step, 3.9 mm from the corner: hit; 4.1 mm:
    no hit (the straight path misses the corner's sphere)."""
    kernel = k32 if real == "f32" else k64
    corner = np.array([2.25, 0.9, 0.76])  # a car's front top corner, body frame
    corners = box_corners((0.0, 0.0, 0.48), (4.5, 1.8, 0.56))
    r = 0.004
    out = _unit(np.array([1.0, 1.0, 1.0]))
    w = _unit(np.cross(out, [0.0, 0.0, 1.0]))  # the path passes the corner at right angles to the diagonal
    for gap, expect in ((0.0039, True), (0.0041, False), (0.0, True), (-0.002, True)):
        c = corner + gap * out
        res = one(kernel, c - 0.5 * speed * STEP * w, c + 0.5 * speed * STEP * w, r, corners)
        assert bool(res["hit"]) == expect, (gap, speed)
        if expect:
            assert 0.0 < res["t"] < 0.5


def test_grazing_paths_touch_once_or_not_at_all(k64):
    """A path tangent to the dilated face, 1e-12 m inside or outside: contact (or none) at the tangent point."""
    r = 0.05
    for dz, expect in ((-1e-12, True), (1e-9, False)):
        z = 1.0 + r + dz
        res = one(k64, (-3.0, 0.0, z), (0.5, 0.0, z), r)
        assert bool(res["hit"]) == expect
        if expect:
            assert res["t"] == pytest.approx((-1.0 + 3.0) / 3.5, abs=1e-6)  # meets the edge cylinder


def test_starting_in_contact_or_inside_counts_at_zero(k64):
    r = 0.1
    res = one(k64, (1.05, 0.0, 0.0), (5.0, 0.0, 0.0), r)  # within r of the +x face, leaving
    assert res["hit"] and res["t"] == 0.0 and res["face"] == 0
    res = one(k64, (1.0 + 1e-3, 1.0 + 1e-3, 0.0), (1.0 + 1e-3, 1.0 + 1e-3, 3.0), r)  # beside an edge
    assert res["hit"] and res["t"] == 0.0
    np.testing.assert_allclose(res["normal"], (1 / math.sqrt(2), 1 / math.sqrt(2), 0.0), atol=1e-12)
    res = one(k64, (0.9, 0.0, 0.2), (0.9, 0.0, 0.3), r)  # inside: the face of least depth (+x, 0.1 deep)
    assert res["hit"] and res["t"] == 0.0 and res["face"] == 0
    np.testing.assert_allclose(res["point"], (1.0, 0.0, 0.2), atol=1e-12)
    res = one(k64, (1.2, 0.0, 0.0), (1.2, 0.0, 0.0), r)  # at rest 0.1 m off: no contact
    assert not res["hit"]


def test_huge_and_negative_coordinates_give_the_same_contact(k64):
    """The same configuration shifted far away (float64): the same t to 1e-9 and the same normal."""
    base = one(k64, (3.0, 0.7, 1.6), (-1.0, 0.1, 0.2), 0.03)
    assert base["hit"]
    for shift in (np.array([-1e6, 2e5, -3e4]), np.array([-7.0, -8.0, -9.0])):
        res = one(k64, np.array((3.0, 0.7, 1.6)) + shift, np.array((-1.0, 0.1, 0.2)) + shift, 0.03, UNIT_BOX + shift)
        assert res["hit"] and res["t"] == pytest.approx(base["t"], abs=1e-9)
        np.testing.assert_allclose(res["normal"], base["normal"], atol=1e-6)


def aligned_paths(corners, r):
    """Adversarial paths: through points at (1 + delta) r off every corner, edge middle and face centre, along the outward directions of its normal cone (its middle and its rims: the adjacent
    faces' normals and, at corners, the edges' middles), moving along each of the 26 axis and diagonal
    directions that close in or graze; the feature is met exactly mid-path, with ties in every coordinate."""
    n = normals_of(corners)
    targets = []
    for i in range(8):
        adj = n[[f for f, fc in enumerate(FACE_CORNERS) if i in fc]]
        for u in [adj.sum(axis=0), *adj, adj[0] + adj[1], adj[1] + adj[2], adj[0] + adj[2]]:
            targets.append((corners[i], _unit(u)))
    for a, b in EDGES:
        adj = n[[f for f, fc in enumerate(FACE_CORNERS) if a in fc and b in fc]]
        for u in (adj.sum(axis=0), *adj):
            targets.append((corners[a] + 0.5 * (corners[b] - corners[a]), _unit(u)))
    for f, fc in enumerate(FACE_CORNERS):
        targets.append((corners[list(fc)].mean(axis=0), n[f]))
    dirs = [_unit(np.array(d) - 1.0) for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)]  # {-1, 0, 1}^3 but 0
    p0, p1 = [], []
    for q, u in targets:
        for w in dirs:
            if w @ u > 1e-12:
                continue
            for delta in (-0.5, -1e-6, 0.0, 1e-6):
                c = q + (1.0 + delta) * r * u
                p0.append(c - 0.1 * w)
                p1.append(c + 0.1 * w)
    return np.array(p0), np.array(p1)


@pytest.mark.parametrize("which", ["thin", "cube", "cabin"])
def test_aligned_paths_through_every_feature(k32, k64, which):
    corners = {"thin": box_corners((0.0, 0.0, 0.0), (0.005, 1.0, 1.0)),
               "cube": box_corners((0.5, -0.25, 1.0), (1.0, 0.5, 2.0)),
               "cabin": frustum_corners((-1.49, 0.99, 0.774), (-1.08, 0.27, 0.702), 0.954, 1.664)}[which]
    r = 0.0078125
    p0, p1 = aligned_paths(corners, r)
    n = len(p0)
    rr = np.full(n, r)
    many = np.repeat(corners[None], n, 0)
    ref = first_contacts(Hull(many), p0, p1, rr)
    check(k64(p0, p1, rr, many), many, p0, p1, rr, np.full(n, 1e-9), ref)
    check(k32(p0, p1, rr, many), many, p0, p1, rr, np.full(n, 2e-6), ref)


def test_a_batch_of_random_paths_round_a_cabin(k32, k64):
    """3,000 random 2 ms paths at up to 100 m/s around a car's cabin frustum, in both precisions: the same
    verdicts as the reference wherever the path is not within 5 um of grazing."""
    rng = np.random.default_rng(3)
    corners = frustum_corners((-1.49, 0.99, 0.774), (-1.08, 0.27, 0.702), 0.954, 1.664)
    n = 3000
    centre = corners.mean(axis=0)
    p0 = centre + rng.uniform(-1.6, 1.6, (n, 3))
    v = rng.normal(size=(n, 3))
    v *= (rng.uniform(0.0, 100.0, n) / np.linalg.norm(v, axis=1))[:, None]
    p1 = p0 + v * STEP
    r = rng.uniform(0.002, 0.05, n)
    _, _, fmin, _ = first_contacts(Hull(corners), p0, p1, r, iters=60, roots=False)
    for kernel, tol in ((k64, 1e-9), (k32, 5e-6)):
        res = kernel(p0, p1, r, np.repeat(corners[None], n, 0))
        clear = np.abs(fmin) > tol
        np.testing.assert_array_equal(res["hit"][clear], (fmin <= 0)[clear])
        assert (fmin <= 0).sum() > 150  # a real share of the paths touch
