"""Running the command line in a subprocess, as a user would, or in this process (``cli_here``: for tests about
what a command does rather than about the process around it)."""

import contextlib
import io
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

ROOT = Path(__file__).resolve().parents[1]


def _env(**extra):
    return dict(os.environ, PYTHONPATH=str(ROOT), **{k: str(v) for k, v in extra.items()})


def cli(*args, cwd=None, timeout=300):
    """Run ``taichi-rocks ARGS`` to completion; a CompletedProcess with text stdout/stderr."""
    return subprocess.run([sys.executable, "-m", "taichi_rocks", *map(str, args)], cwd=cwd, env=_env(),
                          capture_output=True, text=True, timeout=timeout)


def cli_here(capsys, *args):
    """Run ``taichi-rocks ARGS`` in this process (``taichi_rocks.cli.main``; Taichi already started on the CPU by
    the ``taichi_cpu`` fixture, kernels compiled once per layout): like :func:`cli`, an object with ``returncode``, ``stdout``
    and ``stderr`` (text), read from ``capsys``, or with ``capsys=None`` (module fixtures) from the redirected
    ``sys.stdout`` and ``sys.stderr``. argparse's own refusals (it exits) give their status too."""
    from taichi_rocks.cli import main

    def call():
        try:
            return main([str(a) for a in args])
        except SystemExit as e:
            return e.code

    if capsys is None:
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            status = call()
        out, err = out.getvalue(), err.getvalue()
    else:
        capsys.readouterr()  # what earlier code printed is not this command's
        status = call()
        out, err = capsys.readouterr()
    return SimpleNamespace(returncode=status, stdout=out, stderr=err, args=args)


def run_here(*commands):
    """Run several ``taichi-rocks`` commands (argument tuples) in this process, one after the other (their
    Worlds pooled); fail naming the command if one fails."""
    for c in commands:
        r = cli_here(None, *c)
        assert r.returncode == 0, f"{' '.join(map(str, c))}: status {r.returncode}\n{r.stderr}"


def start_cli(*args, env=None):
    """Start ``taichi-rocks ARGS`` in the background (stdout and stderr piped, text); ``env``: more
    environment variables."""
    return subprocess.Popen([sys.executable, "-m", "taichi_rocks", *map(str, args)], env=_env(**(env or {})),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@contextlib.contextmanager
def reaped(proc):
    """``proc`` for the block (work done meanwhile in this process); killed and reaped if the block leaves
    before it ended, so a failure meanwhile leaves no process running."""
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def start_held_writer(marker, *args):
    """Start ``taichi-rocks ARGS`` in the background with its .npz writer holding once it has written into its
    ``.part`` temporary, after creating ``marker`` (tests/held_writer.py): wait for ``marker``, then interrupt."""
    return subprocess.Popen([sys.executable, str(ROOT / "tests" / "held_writer.py"), str(marker), *map(str, args)],
                            env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def start_held_sweep(when: str, marker, *args, new_session: bool = False):
    """Start ``taichi-rocks sweep ARGS`` in the background, holding at ``when`` ("row": after its first finished
    run's row; "build": while it builds its runs) after creating ``marker`` (tests/held_sweep.py): wait for
    ``marker``, then interrupt. ``new_session``: in a process group of its own (to signal it as a terminal
    does, with its workers)."""
    return subprocess.Popen([sys.executable, str(ROOT / "tests" / "held_sweep.py"), when, str(marker), "sweep",
                             *map(str, args)], env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=new_session)


def wait_for(condition, proc, timeout=180.0, poll=0.01):
    """Poll ``condition()`` until true; fail if ``proc`` ends first or time runs out."""
    deadline = time.time() + timeout
    while not condition():
        if proc.poll() is not None:
            out, err = proc.communicate()
            raise AssertionError(f"process ended (status {proc.returncode}) before the condition held:\n{err}")
        if time.time() > deadline:
            proc.kill()
            raise AssertionError("timed out waiting")
        time.sleep(poll)


def run_all(*commands, timeout=600):
    """Run several ``taichi-rocks`` commands (argument tuples), two at a time (the machine may have only two
    cores); fail naming the command if one fails."""
    for i in range(0, len(commands), 2):
        batch = commands[i:i + 2]
        procs = [start_cli(*c) for c in batch]
        for c, p in zip(batch, procs):
            _, err = p.communicate(timeout=timeout)
            assert p.returncode == 0, f"{' '.join(map(str, c))}: status {p.returncode}\n{err}"


def refused(r, *words) -> str:
    """A run refused as bad input: exit status 2, one line on stderr holding ``words``, no traceback."""
    assert r.returncode == 2, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def child_pids(pid: int) -> list:
    """The processes whose parent is ``pid`` now (from /proc)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def wait_gone(pids, timeout=120.0) -> None:
    """Wait until every process of ``pids`` has ended (gone, or a zombie no one has reaped yet)."""
    deadline = time.time() + timeout
    for pid in pids:
        while True:
            try:
                state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except (OSError, IndexError):
                break
            if state in ("Z", "X"):
                break
            if time.time() > deadline:
                raise AssertionError(f"process {pid} still running after {timeout} s")
            time.sleep(0.05)
