"""Files read with clear errors: regular files only, archives within the sizes they declare.

Every data set and model file is read through here (:func:`read_npz`) or checked first
(:func:`check_regular_file`): a FIFO, a device or a folder is named as what it is before anything
opens it (a FIFO blocks its reader, ``/dev/zero`` never ends), and an archive declaring more than
:data:`MAX_NPZ_BYTES` is refused from its headers.
"""

from __future__ import annotations

import contextlib
import math
import os
import stat
import zipfile
import zlib
from pathlib import Path
from typing import IO, Any

import numpy as np

from rkmpc.core.errors import InputFileError

__all__ = ["MAX_NPZ_BYTES", "check_regular_file", "read_npz"]

#: Largest total size (bytes) of the arrays an ``.npz`` file may declare: 512 MiB, about four
#: million transitions of a data set (over 50 hours at 20 Hz) and thousands of times any model
#: file. The sizes are read from the archive's headers before anything is decompressed, so a
#: small file declaring huge arrays is refused at once rather than filling the memory.
MAX_NPZ_BYTES = 512 * 2**20


#: What a path that is not a regular file is, by the test of its mode.
_SPECIAL = (
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def check_regular_file(path: str | Path) -> int:
    """The size (bytes) of the regular file ``path``; :class:`InputFileError` saying what it is else.

    Checked before a file is opened: a FIFO blocks the reader until something writes to it, a
    device such as ``/dev/zero`` never ends, and ``/dev/null`` or a folder is no file of any kind.
    """
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise InputFileError(path, "file not found") from None
    except OSError as exc:
        raise InputFileError(path, f"cannot read the file: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        kinds = [name for test, name in _SPECIAL if test(info.st_mode)]
        what = kinds[0] if kinds else "not a regular file"
        raise InputFileError(path, f"{what}, not a regular file: give the file itself")
    return info.st_size


def read_npz(path: Path, *, max_bytes: int = MAX_NPZ_BYTES) -> dict[str, np.ndarray]:
    """All arrays of an ``.npz`` file, or :class:`InputFileError` when it is not a readable archive.

    Pickled objects are never loaded (``allow_pickle=False``). Before anything is read, the sizes
    the archive declares (each member's uncompressed size and each array's shape and dtype) must
    add up to at most ``max_bytes`` (bytes, default :data:`MAX_NPZ_BYTES`): every data set and
    model file is read through here, so none can exhaust the memory or run for minutes.
    """
    check_regular_file(path)
    _check_declared_sizes(path, max_bytes)
    try:
        loaded = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        problem = f"not a readable .npz archive, corrupted or truncated? ({type(exc).__name__}: {exc})"
        raise InputFileError(path, problem) from None
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise InputFileError(path, "not an .npz archive (a single .npy array)")
    key = ""
    try:
        with loaded:
            arrays = {}
            for key in loaded.files:
                arrays[key] = loaded[key]
            return arrays
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        if isinstance(exc, ValueError) and "allow_pickle" in str(exc):
            problem = "holds pickled Python objects, which rkmpc never loads: not a file rkmpc wrote?"
            raise InputFileError(path, problem, field=key.removesuffix(".npy") or None) from None
        problem = f"damaged .npz archive, corrupted or truncated? ({type(exc).__name__}: {exc})"
        raise InputFileError(path, problem) from None


def _check_declared_sizes(path: Path, max_bytes: int) -> None:
    """Refuse an archive whose members or arrays declare more than ``max_bytes`` (bytes) in all.

    Reads only the zip directory and each ``.npy`` header; a file that is not a zip archive is
    left to :func:`numpy.load` to refuse (a single ``.npy`` array is refused here, unread).
    """
    if not zipfile.is_zipfile(path):
        with contextlib.suppress(OSError), open(path, "rb") as handle:
            if handle.read(6) == b"\x93NUMPY":
                raise InputFileError(path, "not an .npz archive (a single .npy array)")
        return
    limit = f"more than the limit of {max_bytes / 2**20:.0f} MiB: not a file rkmpc wrote?"
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            stored = sum(member.file_size for member in members)
            if stored > max_bytes:
                raise InputFileError(path, f"its members unpack to {stored / 2**20:.1f} MiB, {limit}")
            declared = 0
            for member in members:
                if not member.filename.endswith(".npy"):
                    continue
                with archive.open(member) as handle:
                    shape, dtype = _npy_header(handle)
                declared += math.prod(shape) * dtype.itemsize
                if declared > max_bytes:
                    field = member.filename[: -len(".npy")]
                    raise InputFileError(
                        path,
                        f"declares arrays of {declared / 2**20:.1f} MiB (this one of shape {shape}, "
                        f"{dtype}), {limit}",
                        field,
                    )
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        if isinstance(exc, InputFileError):
            raise
        problem = f"damaged .npz archive, corrupted or truncated? ({type(exc).__name__}: {exc})"
        raise InputFileError(path, problem) from None


def _npy_header(handle: IO[bytes]) -> tuple[tuple[int, ...], np.dtype[Any]]:
    """Shape and dtype declared by the header of a ``.npy`` member (format 1.0 or 2.0)."""
    version = np.lib.format.read_magic(handle)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(handle)
    elif version == (2, 0):
        shape, _, dtype = np.lib.format.read_array_header_2_0(handle)
    else:
        raise ValueError(f"unsupported .npy format version {version}")
    return tuple(int(n) for n in shape), dtype
