"""Golden digests: the SHA-256 of the state of each shipped scene after STEPS steps, compared with the values
committed in tests/golden/states.json. A change of behaviour (any bit of any rock, the launches, the recycles,
the vehicles) fails here instead of passing in silence.

On purpose, after a change that is meant to change what the scenes do (and says so in its commit message),
refresh them with:

    PYTHONPATH=. python tests/engine/test_golden.py --refresh

The digests are of the CPU backend (bit-identical across runs, processes and thread counts); another
processor family may round differently and would need its own file. The suite compiles with Taichi's own IR
optimisation off (tests/conftest.py, engine/runtime.py ``quick_compile``); the digests are checked in that mode
in process and in the mode the package ships in, in a process of its own:

    PYTHONPATH=. TAICHI_ROCKS_QUICK_COMPILE=0 python tests/engine/test_golden.py --check
"""

import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = ROOT / "tests" / "golden" / "states.json"
SCENES = sorted((ROOT / "scenes").glob("*.toml"))
STEPS = 60
ARRAYS = ("positions", "velocities", "phase", "radii", "bed_center", "vehicle_positions", "vehicle_headings")


def _sha(a) -> str:
    a = np.ascontiguousarray(a)
    return hashlib.sha256(str(a.dtype).encode() + str(a.shape).encode() + a.tobytes()).hexdigest()


def digest(path: Path) -> dict:
    """The digests of ``path``'s state after STEPS steps, in process on the CPU (same bits as the CLI)."""
    from taichi_rocks.engine.simulation import Simulation

    sim = Simulation.from_scene(path)
    sim.step(STEPS)
    st = sim.state()
    out = {"steps": STEPS, "launches_total": int(st["launches_total"]), "recycles_total": int(st["recycles_total"])}
    out.update({k: _sha(st[k]) for k in ARRAYS})
    return out


@pytest.fixture(scope="module")
def golden():
    return json.loads(GOLDEN.read_text())


def test_every_shipped_scene_has_a_golden_digest(golden):
    assert sorted(golden["scenes"]) == [p.stem for p in SCENES]
    for name, d in golden["scenes"].items():
        assert d["steps"] == STEPS and d["launches_total"] > 0, name  # the digests cover launches


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_state_after_steps_equals_the_golden_digest(taichi_cpu, golden, path):
    want = golden["scenes"][path.stem]
    got = digest(path)
    changed = [k for k in want if got.get(k) != want[k]]
    assert not changed, (f"{path.stem}: {', '.join(changed)} changed after {STEPS} steps; if the change of "
                         "behaviour is meant, refresh: PYTHONPATH=. python tests/engine/test_golden.py --refresh")


def test_the_shipped_compile_gives_the_same_digests():
    """Both compile modes, both ways of the hash's prefix sum and both variants of the step, one answer: the
    digests of every shipped scene compiled as the package ships (Taichi's IR optimisation on), with the parallel
    scan that GPUs run (engine/hashgrid.py block_scan) and the step's parallel loops (engine/loops.py), in a
    process of its own, against the committed ones (the test above: the suite's quick compile, the CPU's serial
    scan and the serial loops the engine picks for these scenes on two threads)."""
    import os
    import subprocess

    from taichi_rocks.engine.runtime import QUICK_COMPILE
    from taichi_rocks.engine.variant import LOOPS
    from taichi_rocks.engine.world import PARALLEL_SCAN

    env = dict(os.environ, PYTHONPATH=str(ROOT), **{QUICK_COMPILE: "0", PARALLEL_SCAN: "1", LOOPS: "parallel"})
    out = subprocess.run([sys.executable, str(Path(__file__)), "--check"], env=env, capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    assert out.stdout.split() == ["advanced_optimization=True", "parallel_scan=True", "loops=parallel"] + [
        f"{p.stem}:same" for p in SCENES], out.stdout


def test_the_suite_compiles_quickly(taichi_cpu):
    """The in-process digests above are of the quick compile (else the pair of modes would be one mode twice)."""
    import taichi as ti

    assert ti.lang.impl.current_cfg().advanced_optimization is False


def check() -> int:
    """Print the compile mode, the scan's way and, per shipped scene, ``name:same`` or ``name:changed``; 1 if any
    changed."""
    import taichi as ti

    from taichi_rocks.engine.runtime import init_taichi
    from taichi_rocks.engine.variant import loops_from_env
    from taichi_rocks.engine.world import scan_in_parallel

    init_taichi("cpu")
    print(f"advanced_optimization={ti.lang.impl.current_cfg().advanced_optimization}")
    print(f"parallel_scan={scan_in_parallel()}")
    print(f"loops={loops_from_env()}")
    want = json.loads(GOLDEN.read_text())["scenes"]
    bad = 0
    for p in SCENES:
        same = digest(p) == want[p.stem]
        bad += not same
        print(f"{p.stem}:{'same' if same else 'changed'}", flush=True)
    return int(bad > 0)


def refresh() -> None:
    from taichi_rocks.engine.runtime import init_taichi

    init_taichi("cpu")
    data = {"comment": "SHA-256 of each shipped scene's state after 'steps' steps (tests/engine/test_golden.py); "
                       "refresh on purpose only: PYTHONPATH=. python tests/engine/test_golden.py --refresh",
            "scenes": {p.stem: digest(p) for p in SCENES}}
    GOLDEN.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    print(f"wrote {GOLDEN}")


if __name__ == "__main__":
    if sys.argv[1:] == ["--check"]:
        raise SystemExit(check())
    if sys.argv[1:] != ["--refresh"]:
        raise SystemExit("usage: PYTHONPATH=. python tests/engine/test_golden.py --refresh | --check")
    refresh()
