"""The launch study (`taichi-rocks bench --only launch`) on its tiny run: every target in its table, the plots,
and the release angle it recovers from launch velocities."""

import json
import math

import numpy as np
import pytest

from taichi_rocks.bench import launch

pytestmark = pytest.mark.usefixtures("taichi_cpu")

# what the table must report (the study's targets and reports, README "The throw")
EXPECTED = ("peak below 1.5 m", "peak below 3 m", "median release angle", "released above 25 deg",
            "r >= 3 cm", "median apex rises with speed", "wet ground", "small stones", "m behind the tire",
            "landing > 40 m", "launches per metre")


def test_release_angle_is_recovered_from_the_launch_velocity():
    rng = np.random.default_rng(2)
    n, V, e = 2000, 20.0, 0.35
    s = V * (1 + launch.SLIP)
    alpha = rng.uniform(0, math.pi, n)
    beta = rng.uniform(-0.14, 0.14, n)
    k = rng.uniform(0.3, 1.0, n)
    v = k[:, None] * np.column_stack([V - s * np.cos(alpha) * np.cos(beta), -s * np.cos(alpha) * np.sin(beta),
                                      s * np.sin(alpha)])
    stopped = alpha > math.radians(50)
    v[stopped] = e * np.column_stack([v[stopped, :2], -np.abs(v[stopped, 2])])
    np.testing.assert_allclose(launch.release_angles(v, V, e), alpha, atol=1e-9)


@pytest.fixture(scope="module")
def study(tmp_path_factory, taichi_cpu):
    out = tmp_path_factory.mktemp("launch")
    return out, launch.run_launch_study(out, tiny=True, progress=False)


def test_the_table_has_every_target(study):
    out, res = study
    names = [r["target"] for r in res["table"]]
    for what in EXPECTED:
        assert sum(what in n for n in names) >= 1, what
    for r in res["table"]:
        if r["met"] is not None:  # a target: a verdict and a number behind it
            assert isinstance(r["met"], bool) and isinstance(r["value"], float)
    report = (out / "launch_study.md").read_text()
    for r in res["table"]:
        assert f"| {r['target']} | {r['shown']} |" in report
    data = json.loads((out / "launch_study.json").read_text())
    assert [r["target"] for r in data["table"]] == names
    assert len(res["plots"]) >= 3
    assert sorted(p.name for p in out.iterdir()) == sorted(launch.OUTPUTS)  # all it writes, and no temporaries
    for p in res["plots"]:
        assert (out / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"]({p})" in report


def test_the_study_measures_the_engine(study):
    _, res = study
    for name, s in res["stats"].items():
        assert s["launches"] > 20, name  # rocks were thrown and followed
        assert s["launches"] <= s["launches_total"]
        assert 0.0 <= s["alpha_median_deg"] <= 180.0 and s["apex_max"] >= s["apex_median"] >= 0.0
        # no launch faster than a tread point (slip 0.15) turned by the spread: |v| / V <= 2.15 + 0.15
        assert s["speed_ratio_max"] <= 2.0 + launch.SLIP + 0.15
    rate = res["rate"]
    assert rate["patch"]["per_metre"] > rate["swept"]["per_metre"] > 0  # the tread's width counts
