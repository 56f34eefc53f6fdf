"""``python -m taichi_rocks``: the command line, with Ctrl-C (and SIGTERM, SIGHUP) held back from the first
line until the imports are done (see cli.main).

``TAICHI_ROCKS_STARTED=PATH`` (optional): create the empty file PATH as soon as Ctrl-C is held back, so that a
supervising program (the tests) knows when a Ctrl-C starts to end the run cleanly."""

import os
import signal

_held: list = []
for _signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
    signal.signal(_signum, lambda signum, frame: _held.append(signum))
if os.environ.get("TAICHI_ROCKS_STARTED"):
    open(os.environ["TAICHI_ROCKS_STARTED"], "ab").close()

from .cli import main  # noqa: E402

raise SystemExit(main(held=_held, restore=signal.default_int_handler))
