"""Deterministic .npz files (what ``np.load`` reads): members stored in a fixed order with fixed time stamps
and permissions, so that the same arrays give the same bytes; arrays may be streamed from files (:class:`Raw`,
.npy files) so that memory stays flat; the memory-mapped .npy files a run is recorded into have their space
reserved when made (:func:`reserved_memmap`), so that a full disk is an OSError then, not a SIGBUS later."""

from __future__ import annotations

import os
import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["ZIP_EPOCH", "Raw", "write_npz", "reserved_memmap"]


def reserved_memmap(path: Path, dtype, shape) -> np.memmap:
    """A new .npy file at ``path`` mapped for writing (``np.lib.format.open_memmap``), its whole size reserved
    on disk first: the file NumPy makes is sparse, and a store into a page the disk has no room for kills the
    process with SIGBUS. OSError (ENOSPC) here instead, naming ``path``."""
    arr = np.lib.format.open_memmap(path, mode="w+", dtype=dtype, shape=shape)
    size = os.path.getsize(path)
    if size:
        fd = os.open(path, os.O_RDWR)
        try:
            os.posix_fallocate(fd, 0, size)
        except OSError as e:
            del arr
            raise OSError(e.errno, os.strerror(e.errno), str(path)) from None
        finally:
            os.close(fd)
    return arr


# Zip members written by write_npz: no time stamp (the zip epoch), a regular file rw-r--r-- made on Unix.
ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)
_COPY_CHUNK = 1 << 20


def _zip_member(name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=ZIP_EPOCH)
    info.compress_type = zipfile.ZIP_STORED
    info.create_system = 3
    info.external_attr = 0o100644 << 16
    return info


@dataclass(frozen=True)
class Raw:
    """An array kept as bare bytes in a file (C order, no header), e.g. rows appended frame by frame; its
    dtype and shape are known only at the end. write_npz streams it behind an .npy header."""

    path: Path
    dtype: np.dtype
    shape: tuple


def write_npz(f, members: dict) -> None:
    """Write an .npz (what ``np.load`` reads) into the binary file ``f``, the same bytes for the same arrays:
    members ``NAME.npy`` in the order of ``members``, stored, with fixed time stamps and permissions. A
    value is an array, the Path of an .npy file or a :class:`Raw` file; files are streamed (memory stays
    flat)."""
    with zipfile.ZipFile(f, "w", zipfile.ZIP_STORED, allowZip64=True) as z:
        for name, value in members.items():
            with z.open(_zip_member(f"{name}.npy"), "w", force_zip64=True) as dst:
                if isinstance(value, Raw):
                    header = {"descr": np.lib.format.dtype_to_descr(np.dtype(value.dtype)),
                              "fortran_order": False, "shape": tuple(int(n) for n in value.shape)}
                    np.lib.format.write_array_header_1_0(dst, header)
                if isinstance(value, (Path, Raw)):
                    with open(value if isinstance(value, Path) else value.path, "rb") as src:
                        shutil.copyfileobj(src, dst, _COPY_CHUNK)
                else:
                    np.lib.format.write_array(dst, np.asanyarray(value), allow_pickle=False)
