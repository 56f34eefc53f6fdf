"""``python tests/engine/commands_in_turn.py ARCH OUT COMMANDS``: several ``taichi-rocks`` commands one after the
other in one process, on one Taichi runtime started on ARCH (Taichi allows one runtime per process). For the
tests that compare a backend with the CPU (test_backends.py): one Vulkan process runs every scene, where one
process per scene would pay each time for the imports, Taichi's start-up and the device's compiles of the
kernels the scenes share.

The first line on stdout is ``arch: A``, the arch Taichi really started (``cpu`` when the device is missing:
then nothing runs and the status is 1). COMMANDS is a JSON object, name -> the command's arguments; each is run
in turn as the command line runs it (``taichi_rocks.cli.main``, tests/cli_util.py ``cli_here``), and OUT/NAME.json
holds its exit status and what it printed on stdout and stderr. Not collected by the suite (no test_ prefix)."""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # cli_util

from cli_util import cli_here  # noqa: E402
from taichi_rocks.engine.runtime import init_taichi  # noqa: E402


def run_each(commands: dict) -> dict:
    """Each command in turn in this process: name -> (exit status, stdout, stderr)."""
    out = {}
    for name, args in commands.items():
        r = cli_here(None, *args)
        out[name] = (r.returncode, r.stdout, r.stderr)
    return out


def run(arch: str, out: Path, commands: dict) -> int:
    used = init_taichi(arch)  # a missing device: its warning on stderr, and "arch: cpu"
    print(f"arch: {used}", flush=True)
    if used != arch:
        return 1
    for name, (status, stdout, stderr) in run_each(commands).items():
        (out / f"{name}.json").write_text(json.dumps({"status": status, "stdout": stdout, "stderr": stderr}))
    return 0


if __name__ == "__main__":
    raise SystemExit(run(sys.argv[1], Path(sys.argv[2]), json.loads(sys.argv[3])))
