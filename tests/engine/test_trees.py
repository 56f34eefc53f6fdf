"""SNode trees are owned and given back (engine/trees.py): Taichi 1.7.4 allows 512 per process and a process past
it dies of a segfault at its next kernel launch, so long-lived processes (sweep workers, the viewer, this suite)
must give back what their Renderers and effects allocated (a World holds ndarrays, not trees); and destroying a
tree recompiles every kernel, so trees are destroyed rarely and together. The cases that destroy trees run in a
process of their own (trees_destroying.py)."""

import os
import subprocess
import sys
from pathlib import Path


HERE = Path(__file__).resolve().parent


def test_the_destroying_cases_pass_in_a_process_of_their_own():
    cases = HERE / "trees_destroying.py"
    n = cases.read_text().count("\ndef test_")
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", str(cases)],
                       cwd=HERE.parents[1], capture_output=True, text=True, timeout=900,
                       env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    tail = r.stdout.strip().splitlines()[-1:] if r.stdout.strip() else [r.stderr[-500:]]
    assert r.returncode == 0 and f"{n} passed" in tail[0], r.stdout[-3000:] + r.stderr[-1000:]
    assert n >= 4
