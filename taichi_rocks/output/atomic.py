"""The one atomic-write helper of every output: temporaries beside the final name, renamed when complete
(:func:`atomic_path`, :func:`write_atomically`), folders a failed command leaves behind removed again
(:func:`new_folders`), the temporaries of killed writers cleaned up (:func:`remove_stale_temporaries`), and an
output place checked before any work starts (:func:`check_place`)."""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from pathlib import Path

__all__ = ["temp_name", "atomic_path", "write_atomically", "atomic_folder", "new_folders", "remove_stale_temporaries",
           "check_place", "remove_stale_in"]


def check_place(path, folder: bool = False) -> None:
    """Refuse (ValueError, one line saying what was expected) an output ``path`` that cannot be written: a file
    where a folder on its way must be, or a folder that is not writable. ``folder``: ``path`` is itself a folder
    the output goes into (it may exist); else a file name whose folders are made as needed."""
    path = Path(path)
    place = path if folder else path.parent
    while not (place.exists() or place.is_symlink()):
        if place == place.parent:
            return
        place = place.parent
    if not place.is_dir():
        what = "a folder" if place == path else f"a folder to hold {path}"
        raise ValueError(f"{place}: is {'a broken link' if place.is_symlink() and not place.exists() else 'a file'}"
                         f", expected {what}")
    if not os.access(place, os.W_OK | os.X_OK):
        raise ValueError(f"{place}: is not writable, cannot write {path} there")


def _temp_prefix(final: Path) -> str:
    """Temporaries of ``final`` are hidden, next to it, and carry the writer's process id:
    ``.NAME.PID.XXXXXXXX.part`` (files) and ``.NAME.PID.XXXXXXXX`` (work folders)."""
    return f".{final.name}.{os.getpid()}."


def temp_name(final: Path, suffix: str = "") -> Path:
    """A new temporary name next to ``final`` (same folder, so the rename is atomic). Nothing is created: the
    writer knows the name before the file or folder exists, so a Ctrl-C at any moment can remove it."""
    final = Path(final)
    return final.parent / f"{_temp_prefix(final)}{secrets.token_hex(4)}{suffix}"


@contextlib.contextmanager
def atomic_path(final: Path, suffix: str = ".part"):
    """For writers that open files by name (a library's own writer): yields a new temporary name beside
    ``final`` (same folder; nothing is created), ending in ``suffix`` (a library may pick the format by
    extension). When the body returns, the temporary is renamed over ``final``; on any failure (or Ctrl-C) it
    is removed. Temporaries left by a killed writer are removed by :func:`remove_stale_temporaries`."""
    final = Path(final)
    tmp = temp_name(final, suffix)
    try:
        yield tmp
        os.replace(tmp, final)
    finally:
        tmp.unlink(missing_ok=True)


def write_atomically(final: Path, write) -> None:
    """Write ``final`` complete or not at all: ``write(f)`` fills a temporary file beside it (binary, the
    usual permissions), which is then renamed over ``final``; on any failure the temporary is removed."""
    with atomic_path(final) as tmp:
        with open(tmp, "xb") as f:
            write(f)


@contextlib.contextmanager
def atomic_folder(final: Path, overwrite: bool = False):
    """Write the folder ``final`` complete or not at all: yields a new empty temporary folder beside it, which
    replaces ``final`` when the body returns (an existing ``final`` only with ``overwrite``: FileExistsError,
    before the body runs, otherwise); on any failure (or Ctrl-C) the temporary is removed and ``final`` is as it
    was. Missing parents of ``final`` are made, and removed again on failure."""
    final = Path(final)
    if (final.exists() or final.is_symlink()) and not overwrite:
        raise FileExistsError(f"{final}: exists; pass --overwrite to replace it")
    check_place(final, folder=True)
    remove_stale_temporaries(final)
    with new_folders(final.parent):
        tmp = temp_name(final)
        try:
            tmp.mkdir()
            yield tmp
            old = None
            if final.exists() or final.is_symlink():
                old = temp_name(final)
                os.rename(final, old)
            os.rename(tmp, final)
            if old is not None:
                shutil.rmtree(old) if old.is_dir() and not old.is_symlink() else old.unlink()
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)


@contextlib.contextmanager
def new_folders(*folders):
    """Create ``folders`` and their missing parents for a writer; if the body raises (an error, Ctrl-C),
    remove again, deepest first, those of them it created that are empty by then, so that a command that
    fails or is interrupted leaves no folder of its own behind. Folders that existed before, and folders
    holding finished output (a render's kept frames), stay. Yields the folders created, parents first."""
    created: list = []
    try:
        for folder in folders:
            missing = []
            path = Path(folder)
            while not path.is_dir():
                missing.append(path)
                path = path.parent
            for path in reversed(missing):
                created.append(path)  # before mkdir: a Ctrl-C right after it must still find it here
                try:
                    path.mkdir()
                except FileExistsError:
                    created.pop()  # made meanwhile by someone else: not ours to remove
                    if not path.is_dir():
                        raise
        yield list(created)
    except BaseException:
        for path in sorted(set(created), key=lambda q: len(q.parts), reverse=True):
            try:
                path.rmdir()  # only when empty
            except OSError:
                pass
        raise



def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    return True


def remove_stale_temporaries(final: Path) -> list[Path]:
    """Remove the temporaries that writers of ``final`` left behind when they were killed (kill -9, power
    loss): those whose process no longer exists. Temporaries of a running writer are left alone. Returns
    what was removed."""
    final = Path(final)
    removed = []
    if not final.parent.is_dir():
        return removed
    for path in final.parent.glob(f".{final.name}.*"):
        rest = path.name[len(final.name) + 2:]
        pid = rest.split(".", 1)[0]
        if not pid.isdigit() or _alive(int(pid)):
            continue
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


def remove_stale_in(folder: Path) -> list[Path]:
    """:func:`remove_stale_temporaries` for every output whose temporaries lie in ``folder`` (the files of a
    folder output: ``.frame_00000.ply.PID.XXXXXXXX.part``)."""
    removed = []
    folder = Path(folder)
    if folder.is_dir():
        names = set()
        for tmp in folder.glob(".*.*.*"):
            parts = tmp.name[1:].split(".")
            for i in range(1, len(parts)):
                if parts[i].isdigit():  # NAME.PID.XXXXXXXX[.suffix]
                    names.add(".".join(parts[:i]))
                    break
        for name in sorted(names):
            removed += remove_stale_temporaries(folder / name)
    return removed
