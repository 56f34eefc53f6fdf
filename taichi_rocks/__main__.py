"""``python -m taichi_rocks``: the command line, with Ctrl-C held back from the first line until the
imports are done (see cli.main)."""

import signal

_held: list = []
signal.signal(signal.SIGINT, lambda signum, frame: _held.append(signum))

from .cli import main  # noqa: E402

raise SystemExit(main(held=_held, restore=signal.default_int_handler))
