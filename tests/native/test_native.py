"""The native host (native/: librocks and rocks_run, docs/native.md) against Python, on x64.

A module of tests/native/native.toml (``taichi-rocks aot --arch x64``, 20,000 rocks, impacts and tumbling, a live
vehicle, an origin shift) run by rocks_run for 300 frames at 60 Hz gives Python's twin's positions, phases,
orientations, counts and impact events to the bit. The C API's bad input (a missing or broken module, an unknown
or scripted vehicle, NaN, NULL) comes back as a status and a message, never an abort, and leaves the simulation
as it was. About 60 s here: making the module (its kernels compile) and the twin's run; the build of native/ when
``make native`` has not made it (about 30 s more)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from native_util import FRAMES, SCENE, aot, build, event_columns, run, twin_run
from taichi_rocks.config.scene import load_scene

PROBE = Path(__file__).resolve().parent / "capi_probe.py"


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    return build(tmp_path_factory.mktemp("native"))


@pytest.fixture(scope="module")
def module(tmp_path_factory, taichi_cpu):
    out = tmp_path_factory.mktemp("aot") / "native-x64"
    r = aot(SCENE, "x64", out)
    assert r.returncode == 0, f"aot: status {r.returncode}\n{r.stdout}\n{r.stderr}"
    assert r.stdout.startswith(f"wrote {out}: x64 module of "), r.stdout
    return out


@pytest.fixture(scope="module")
def runs(built, module, tmp_path_factory):
    cpp = run(built, module, tmp_path_factory.mktemp("dump"))
    py = twin_run(load_scene(SCENE), module)
    return cpp, py


def test_the_run_covers_what_it_compares(runs):
    """The 300 frames launch rocks, hit bodies, tumble stones, move the floating origin and steer the live
    vehicle between keyframes (two steps a frame): what the comparison below holds to the bit."""
    cpp, py = runs
    sim = py["sim"]
    assert sim.launches_total > 500 and len(py["events"]) > 5
    assert np.any(sim._host.shift != 0.0), "no origin shift in the run"
    assert sim.step_count == 2 * FRAMES and cpp["counts"]["steps"] == 2 * FRAMES
    (i, name, _), = py["live"]
    assert len(sim.drive_track(name)) == FRAMES + 1  # a keyframe a frame: the steps between are interpolated
    st = py["state"]
    assert np.array_equal(py["mirror"], st.positions) and np.array_equal(py["phase"], st.phase)
    assert np.count_nonzero(np.abs(st.angular_velocities).sum(1)) > 0 or np.count_nonzero(
        st.orientations[:, 3] != 1.0) > 100


def test_cpp_gives_python_twins_bits(runs):
    """Positions, phases, orientations (rocks_run's mirror from rocks_changes, by id), the counts and every impact
    event (time, vehicle, part, rock) are Python's to the bit."""
    cpp, py = runs
    st, sim = py["state"], py["sim"]
    assert cpp["positions"].view(np.uint64).tolist() == st.positions.view(np.uint64).tolist()
    assert np.array_equal(cpp["phase"], st.phase)
    assert np.array_equal(cpp["orientations"].view(np.uint64),
                          st.orientations.astype(np.float64).view(np.uint64))
    assert cpp["counts"] == {"launches": sim.launches_total, "recycles": sim.recycles_total,
                             "impacts": len(py["events"]), "steps": sim.step_count}
    ev = event_columns(py["events"])
    assert cpp["impacts"].shape == ev.shape and np.array_equal(cpp["impacts"].view(np.uint64), ev.view(np.uint64))


def test_rocks_run_reports_its_frame(runs):
    """rocks_run's last line is the JSON of its per-call medians, each a positive time, the frame their sum or more."""
    s = runs[0]["summary"]
    assert set(s) == {"frames", "open_s", "frame_ms", "advance_ms", "changes_ms", "impacts_ms"} and s["frames"] == FRAMES
    assert all(s[k] > 0 for k in s)
    assert s["frame_ms"] >= 0.9 * (s["advance_ms"] + s["changes_ms"] + s["impacts_ms"])


def test_module_folder(module):
    """The folder holds what docs/native.md says: Taichi's files, a buffer per group of the manifest's shape, a
    drive per vehicle (the scripted ones at every step time, the live one its pose at t = 0), the manifest's
    kernels with 32-bit scalars and arrays only."""
    m = json.loads((module / "manifest.json").read_text())
    assert m["format"] == "taichi-rocks module 1" and m["arch"] == "x64" and m["rocks"] == 20000
    assert (module / "module" / "metadata.json").exists()
    for g in m["groups"]:
        a = np.load(module / g["file"])
        assert a.shape[0] == g["length"] and (a.shape[1:] == ((g["components"],) if g["components"] > 1 else ()))
    assert [v["kind"] for v in m["vehicles"]] == ["recorded", "recorded", "live"]
    lines = (module / "drives" / "0.drive").read_text().splitlines()
    rows = [ln for ln in lines if ln and ln[0].isdigit()]
    assert len(rows) == m["scene"]["steps_recorded"] + 1 == 625 and rows[1].split()[0] == repr(m["host"]["dt"])
    assert len([ln for ln in (module / "drives" / "2.drive").read_text().splitlines() if ln[:1].isdigit()]) == 1
    kinds = {a["kind"] for k in m["kernels"].values() for a in k["args"]}
    assert kinds == {"group", "i32", "array"}
    assert all(f["meaning"] for f in m["fields"] if not f["name"].startswith(("tmp_", "scan_")))


def _probe(built, *args) -> dict:
    """capi_probe.py in a subprocess (librocks through ctypes, without Taichi's Python package in the process)."""
    r = subprocess.run([sys.executable, str(PROBE), str(built / "librocks.so"), *map(str, args)], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, f"capi_probe: status {r.returncode}\n{r.stdout}\n{r.stderr}"
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_bad_calls_return_errors(built, module):
    """Bad arguments give ROCKS_ERROR_ARGUMENT and a message naming what is wrong, and leave the simulation as it
    was: after them it steps on to the same state as a simulation that never saw them."""
    out = _probe(built, "calls", module)
    assert out["errors"] == {
        "drive unknown": [-1, "drive('nobody'): no vehicle of that name"],
        "drive recorded": [-1, "drive('player'): a vehicle replaying its recorded drive; only a live vehicle (path "
                               "kind \"live\" in the scene) is driven at run time"],
        "drive nan heading": [-1, "drive('chaser'): heading must be finite"],
        "drive inf x": [-1, "drive('chaser'): position must be finite"],
        "drive inf speed": [-1, "drive('chaser'): speed must be finite"],
        "drive null": [-1, "drive: vehicle is NULL"],
        "advance nan": [-1, "advance_to: t must be a finite time in seconds"],
        "advance far": [-1, "advance_to: t is past the last step the kernels count"],
        "changes null": [-1, "changes: out is NULL"],
        "vehicle index": [-1, "vehicle: index 3 out of range"],
        "buffer name": [-1, "buffer: no field nothing (manifest.json: fields)"],
        "null sim": [-1, ""],
    }
    assert out["same_after"] is True and out["steps"] == 20
    assert out["buffer"]["count"] == 20000 and out["buffer"]["components"] == 3


def _broken(module: Path, tmp: Path, name: str, edit) -> Path:
    folder = tmp / name
    shutil.copytree(module, folder)
    edit(folder)
    return folder


def _manifest_edit(change):
    def edit(folder):
        p = folder / "manifest.json"
        m = json.loads(p.read_text())
        change(m)
        p.write_text(json.dumps(m))
    return edit


def test_broken_modules_are_refused(built, module, tmp_path):
    """rocks_open gives NULL and one line naming the file and what is wrong with it, for each way a module folder
    can be unusable; nothing aborts."""
    cases = {
        "missing": (lambda f: shutil.rmtree(f), "manifest.json: cannot be read (not a module folder?)"),
        "not json": (lambda f: (f / "manifest.json").write_text("{\"format\": "), "manifest.json: not valid JSON at byte"),
        "format": (_manifest_edit(lambda m: m.update(format="taichi-rocks module 0")), "not a module of this library's "
                                                                                        "format"),
        "taichi": (_manifest_edit(lambda m: m.update(taichi="1.6.0")), "a module of Taichi 1.6.0, this library runs "
                                                                        "Taichi 1.7.x"),
        "kernel args": (_manifest_edit(lambda m: m["kernels"]["active_step"]["args"].pop()),
                        "kernel active_step takes ("),
        "no key": (_manifest_edit(lambda m: m["host"].pop("reach")), "manifest.json: host: no key \"reach\""),
        "wrong kind": (_manifest_edit(lambda m: m["host"].update(dt="0.01")), "manifest.json: host.dt: expected a "
                                                                              "number, got a string"),
        "drive": (lambda f: (f / "drives" / "1.drive").write_text("taichi-rocks drive 1\nt x y heading speed "
                                                                  "yaw_rate wheel_spin\n0 0 0 0 x 0 -\n"),
                  "drives/1.drive:3: speed: expected a number"),
        "buffer": (lambda f: np.save(f / "buffers" / "r3.npy", np.zeros((5, 3), np.float32)),
                   "buffers/r3.npy: not the group the manifest names"),
        "kernel file": (lambda f: (f / "module" / "active_step.ll").write_text("not IR"), "module"),
        "start": (_manifest_edit(lambda m: m["host"]["start"].update(shift=[64.0, 0.0])),
                  "host.start: the drives do not start where the module's bed does"),
    }
    for name, (edit, want) in cases.items():
        folder = _broken(module, tmp_path, name.replace(" ", "_"), edit)
        out = _probe(built, "open", folder)
        assert out["opened"] is False, name
        assert want in out["error"] and "\n" not in out["error"], (name, out["error"])


def test_aot_refuses_what_it_cannot_export(tmp_path):
    """One line naming the key, exit status 2, nothing written: full stepping, an optional effect, an empty bed,
    f64 on Vulkan, an existing folder without --overwrite."""
    text = SCENE.read_text()
    cases = {
        "full": (text.replace("[sim]\n", '[sim]\nstepping = "full"\n'), "x64", "sim.stepping: only active stepping"),
        "dust": (text.replace("[effects]\n", "[effects]\ndust = true\n"), "x64", "effects.dust: the optional effect"),
        "empty": (text.replace("rocks = 20000", "rocks = 0"), "x64", "bed.rocks: a module steps a bed of rocks"),
        "f64": (text.replace("[sim]\n", '[sim]\nprecision = "f64"\n'), "vulkan", "sim.precision: \"f64\""),
    }
    for name, (scene_text, arch, want) in cases.items():
        scene = tmp_path / f"{name}.toml"
        scene.write_text(scene_text)
        out = tmp_path / f"{name}-module"
        r = aot(scene, arch, out)
        assert r.returncode == 2, (name, r.stdout, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1 and want in r.stderr and "Traceback" not in r.stderr, name
        assert not out.exists() and not list(tmp_path.glob(f".{name}-module*")), name
    (tmp_path / "exists").mkdir()
    r = aot(SCENE, "x64", tmp_path / "exists")
    assert r.returncode == 2 and "exists; pass --overwrite" in r.stderr and not any((tmp_path / "exists").iterdir())
