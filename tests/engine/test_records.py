"""The typed records (config/records.py, engine/records.py, output/export.py ExportFrame): every field has a unit
and a line; a record reads as the dict it replaced, key for key and in the same order; it survives np.savez;
a checkpoint record and its file both restore."""

import io

import numpy as np
import pytest

from taichi_rocks.config.records import Record, describe
from taichi_rocks.engine.records import RECORDS, Changes, Checkpoint, State
from taichi_rocks.output.export import ExportFrame

pytestmark = pytest.mark.usefixtures("taichi_cpu")

UNITS = {"", "-", "s", "m", "m/s", "rad", "rad/s"}


@pytest.mark.parametrize("cls", [*RECORDS, ExportFrame], ids=lambda c: c.__name__)
def test_every_field_has_a_unit_and_a_line(cls):
    rows = describe(cls)
    assert rows and issubclass(cls, Record)
    for name, unit, doc, _ in rows:
        assert unit in UNITS, (name, unit)
        assert doc and "\n" not in doc and len(doc) > 10, name


def _sim(tumble=False):
    from scenes_util import reference_scene
    from taichi_rocks.engine.simulation import Simulation

    sim = Simulation(reference_scene(), tumble=tumble)
    sim.step(40)
    return sim


def test_state_reads_as_its_dict():
    sim = _sim()
    st = sim.state()
    assert isinstance(st, State)
    assert list(st) == ["time", "step", "positions", "velocities", "radii", "phase", "bed_center",
                        "vehicle_positions", "vehicle_headings", "vehicle_names", "launches_total", "recycles_total"]
    assert "orientations" not in st and st.orientations is None and st.get("orientations") is None
    with pytest.raises(KeyError):
        st["orientations"]
    assert st["positions"] is st.positions and st.positions.dtype == np.float64
    d = st.as_dict()
    assert type(d) is dict and list(d) == list(st) and all(d[k] is st[k] for k in d)
    buf = io.BytesIO()
    np.savez(buf, **st)
    buf.seek(0)
    with np.load(buf) as f:
        assert sorted(f.files) == sorted(st) and np.array_equal(f["positions"], st.positions)
    st["step"] = 7
    assert st.step == 7
    light = sim.state(rocks=False)
    assert "positions" not in light and light.positions is None and "bed_center" in light


def test_tumbling_adds_its_arrays_and_changes_are_a_record():
    sim = _sim(tumble=True)
    st = sim.state()
    assert list(st)[6:8] == ["angular_velocities", "orientations"] and st.orientations.shape == (sim.n_rocks, 4)
    rows = sim.changes(velocities=True)
    assert isinstance(rows, Changes) and list(rows) == ["ids", "positions", "phase", "orientations", "velocities"]
    assert np.array_equal(rows.positions, st.positions[rows.ids])


def test_checkpoint_lists_its_rock_fields_first_and_restores_from_a_file():
    sim = _sim()
    cp = sim.checkpoint()
    assert isinstance(cp, Checkpoint)
    keys = list(cp)
    rock_keys = [k for k in keys if k.startswith("rock_")]
    assert keys[:len(rock_keys)] == rock_keys and "rock_pos" in rock_keys and "rock_fields" not in keys
    assert keys[len(rock_keys):] == ["step_count", "time", "origin", "origin_anchor", "origin_shift", "bed_center",
                                     "bed_rel", "lead", "launches", "recycles", "impacts_dropped", "scene", "seed",
                                     "rocks"]
    assert cp["rock_pos"] is cp.rock_fields["pos"]
    with pytest.raises(KeyError):
        cp["rock_fields"]
    buf = io.BytesIO()
    np.savez(buf, **cp)
    sim.step(25)
    after = sim.state()
    for data in (cp, np.load(io.BytesIO(buf.getvalue()))):
        sim.restore(data)
        sim.step(25)
        again = sim.state()
        assert np.array_equal(again.positions, after.positions) and again.step == after.step
