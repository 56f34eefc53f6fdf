"""``python tests/held_writer.py MARKER ARGS...`` runs ``python -m taichi_rocks ARGS`` with one change for the
tests of interrupted writes: the .npz writer, once it has written its first megabyte into the ``.part``
temporary, creates the file MARKER and holds there (sleeping) until the process is interrupted or killed.

A test then waits for MARKER (a file that stays) instead of polling for the ``.part`` file, which the writer
may rename into place between two polls on a fast machine: the Ctrl-C or kill -9 lands while the .npz is
being written, every time, however fast or slow the machine. Nothing else differs from the command line:
``python -m taichi_rocks`` is run as the main module, with its handling of Ctrl-C, exit codes and outputs.
"""

import runpy
import sys
import time

HOLD_AFTER = 1 << 20  # bytes written into the .part before holding
HOLD_S = 600.0  # at most (a test that never interrupts still ends)


class _Held:
    """A file object that holds after HOLD_AFTER bytes (everything else is the file's own)."""

    def __init__(self, f, marker):
        self._f, self._marker, self._written, self._held = f, marker, 0, False

    def write(self, data):
        n = self._f.write(data)
        self._written += len(data)
        if not self._held and self._written >= HOLD_AFTER:
            self._held = True
            self._f.flush()
            open(self._marker, "ab").close()
            deadline = time.monotonic() + HOLD_S
            while time.monotonic() < deadline:  # a Ctrl-C raises KeyboardInterrupt here, inside the writer
                time.sleep(0.05)
        return n

    def __getattr__(self, name):
        return getattr(self._f, name)


def main() -> None:
    marker = sys.argv[1]
    from taichi_rocks.app import simulate

    write_npz = simulate.write_npz

    def held_write_npz(f, members):
        write_npz(_Held(f, marker), members)

    simulate.write_npz = held_write_npz  # looked up at call time by app/simulate.py's writer
    sys.argv = [sys.argv[0]] + sys.argv[2:]
    runpy.run_module("taichi_rocks", run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    main()
