"""Deterministic .npz files (what ``np.load`` reads): members stored in a fixed order with fixed time stamps
and permissions, so that the same arrays give the same bytes; arrays may be streamed from files (:class:`Raw`,
.npy files) so that memory stays flat."""

from __future__ import annotations

import shutil
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["ZIP_EPOCH", "Raw", "write_npz"]


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
