"""The body shapes (motion/bodies.py): convex parts that are what the renderer draws, and their hit labels."""

from pathlib import Path

import numpy as np
import pytest

from scenes_util import scene
from taichi_rocks.config.scene import load_scene
from taichi_rocks.motion.bodies import (FACE_CORNERS, FACES, LABELS, body_parts, hexahedron_planes, label_table,
                                        vehicle_kind)
from taichi_rocks.render.bodies import vehicle_mesh

SIZES = {"car": {}, "van": {"height": 2.2, "length": 5.2}, "truck": {"height": 3.4, "length": 9.0, "width": 2.5,
                                                                   "wheelbase": 5.0, "track": 2.0,
                                                                   "tire_radius": 0.5}}


def specs():
    """Every shipped scene's vehicles, and one of each kind at typical sizes."""
    out = [v for p in sorted((Path(__file__).parents[2] / "scenes").glob("*.toml")) for v in load_scene(p).vehicles]
    sc = scene(vehicles=[{"name": k, "kind": k, **sz, "path": {"points": [[0.0, 3.0 * i], [99.0, 3.0 * i]]}}
                         for i, (k, sz) in enumerate(SIZES.items())])
    return out + list(sc.vehicles)


@pytest.mark.parametrize("spec", specs(), ids=lambda v: f"{v.name}-{vehicle_kind(v)}")
def test_parts_are_convex_and_drawn_as_they_collide(spec):
    """Every part is a convex hexahedron with planar faces, every corner of a part (but the lower body, which the
    wheel wells cut) is a vertex of the rendered body, and the parts span the body's box."""
    body = body_parts(spec)
    mesh = vehicle_mesh(spec)
    verts = {tuple(v) for v in mesh.verts[mesh.wheel < 0]}
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for p in body.parts:
        c = p.corners()
        planes = hexahedron_planes(c)
        assert np.allclose(np.linalg.norm(planes[:, :3], axis=1), 1.0)
        assert np.all(c @ planes[:, :3].T <= planes[:, 3] + 1e-12)  # every corner inside every face plane
        for f, idx in enumerate(FACE_CORNERS):  # each face's corners on its plane
            assert np.allclose(c[list(idx)] @ planes[f, :3], planes[f, 3], atol=1e-12), (p.name, FACES[f])
        if p.name != "lower":
            assert all(tuple(x) in verts for x in c), p.name
        lo, hi = np.minimum(lo, c.min(axis=0)), np.maximum(hi, c.max(axis=0))
    L, W, H = spec.length, spec.width, spec.height
    z0 = 0.8 * spec.tire_radius
    np.testing.assert_allclose(hi[2], z0 + H, atol=1e-12)
    assert lo[2] == pytest.approx(z0 - 0.01, abs=1e-12)  # the bumpers reach 1 cm below the body
    assert hi[0] == pytest.approx(L / 2 + 0.06) and lo[0] == pytest.approx(-L / 2 - 0.06)
    assert hi[1] == pytest.approx(0.51 * W) and lo[1] == pytest.approx(-0.51 * W)


def test_labels_of_a_car():
    """A car's windscreen is its cabin's front, the roof its top; its lower body's top is the bonnet ahead of
    the cabin and the boot ("rear") behind it; the bumpers are front_bumper and rear."""
    (car,) = scene(vehicles=[{"name": "c", "kind": "car"}]).vehicles
    body = body_parts(car)
    cabin, lower = body.part("cabin"), body.part("lower")
    front, top, back, left = (FACES.index(f) for f in ("front", "top", "back", "left"))
    assert cabin.label(front, 0.0) == "windscreen" and cabin.label(top, 0.0) == "roof"
    assert cabin.label(back, 0.0) == "rear" and cabin.label(left, 0.0) == "side"
    assert lower.label(top, 0.4 * car.length) == "bonnet" and lower.label(top, -0.45 * car.length) == "rear"
    assert lower.label(front, 0.0) == "front_bumper"
    assert {body.part("front_bumper").label(f, 0.0) for f in range(6)} == {"front_bumper"}
    assert {body.part("rear_bumper").label(f, 0.0) for f in range(6)} == {"rear"}
    table, split = label_table(body.parts)
    assert table.shape == (len(body.parts), 6, 2) and split.shape == (len(body.parts),)
    k = [p.name for p in body.parts].index("lower")
    assert LABELS[table[k, top, 0]] == "bonnet" and LABELS[table[k, top, 1]] == "rear"
    assert -0.33 * car.length < split[k] < 0.22 * car.length  # under the cabin, where the top is hidden


def test_windscreens_lean_back_and_every_kind_has_one():
    """The windscreen faces of each kind point forwards (cars and vans: and up, they slope back)."""
    for kind in ("car", "van", "truck"):
        (v,) = scene(vehicles=[{"name": "v", "kind": kind, **SIZES[kind]}]).vehicles
        body = body_parts(v)
        faces = [(p, f) for p in body.parts for f in range(6) if p.labels[f] == "windscreen"
                 and p.name != "upper"]  # a van's closed upper body: its front is hidden in the glazed part
        normals = [hexahedron_planes(p.corners())[f, :3] for p, f in faces]
        assert normals and max(n[0] for n in normals) > 0.7, kind
        if kind != "truck":
            assert max(n[2] for n in normals) > 0.3, kind


def test_hexahedron_planes_refuses_bad_solids():
    cube = body_parts(scene(vehicles=[{"name": "c", "kind": "car"}]).vehicles[0]).part("front_bumper").corners()
    twisted = cube.copy()
    twisted[6] += (0.0, 0.0, 0.05)  # one corner out of its faces' planes
    with pytest.raises(ValueError, match="not planar"):
        hexahedron_planes(twisted)
    flat = cube.copy()
    flat[4:] = flat[:4]  # no height: top face = bottom face
    with pytest.raises(ValueError):
        hexahedron_planes(flat)
