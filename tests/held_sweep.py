"""``python tests/held_sweep.py WHEN MARKER ARGS...`` runs ``python -m taichi_rocks ARGS`` (a sweep) with one
change for the tests that interrupt a sweep at a given moment: at that moment the driver creates the file MARKER
and goes on there until it is interrupted or killed.

WHEN is
* ``row``: once it has written results.csv with its first finished run (the file renamed into place), it holds
  (sleeping): the sweep cannot finish its other runs, however fast the machine;
* ``build``: once it has announced its run count and builds the runs (validating each combination's scene with
  pydantic, the slow part), it keeps building (the same combination again and again, pydantic's work each time):
  an interrupt lands inside that work, as it does in a big sweep, and the building never ends by itself.

A test waits for MARKER (what the process reports) and then interrupts, instead of hoping that the moment lasts
longer than the signal takes. Nothing else differs from the command line (``python -m taichi_rocks`` as the main
module, its handling of signals, exit codes and outputs); the workers are the sweep's own.
"""

import runpy
import sys
import time
from pathlib import Path

HOLD_S = 600.0  # at most (a test that never interrupts still ends)


def _hold(marker: str, work=lambda: time.sleep(0.05)) -> None:
    open(marker, "ab").close()
    deadline = time.monotonic() + HOLD_S
    while time.monotonic() < deadline:  # an interrupt raises here, inside ``work``
        work()


def main() -> None:
    when, marker = sys.argv[1], sys.argv[2]
    from taichi_rocks.app.sweep import sweep
    from taichi_rocks.config import sweep as config_sweep

    if when == "row":
        write = sweep.write_atomically

        def held_write(path, fill):
            write(path, fill)
            if Path(path).name == "results.csv":
                _hold(marker)

        sweep.write_atomically = held_write  # looked up at call time by app/sweep/sweep.py
    elif when == "build":
        runs, scene_with, building = config_sweep.sweep_runs, config_sweep.scene_with, []

        def held_runs(*args, checked=None, **kwargs):
            def said():
                if checked is not None:
                    checked()
                building.append(True)
            return runs(*args, checked=said, **kwargs)

        def held_scene_with(base, overrides):
            if building:
                _hold(marker, lambda: scene_with(base, overrides))
            return scene_with(base, overrides)

        sweep.sweep_runs = held_runs  # looked up at call time by app/sweep/sweep.py
        config_sweep.scene_with = held_scene_with  # and by config/sweep.py's sweep_runs
    else:
        raise SystemExit(f"held_sweep: WHEN must be row or build, got {when!r}")
    sys.argv = [sys.argv[0]] + sys.argv[3:]
    runpy.run_module("taichi_rocks", run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    main()
