"""Files written whole or not at all, and archives read with clear errors.

Every file rkmpc writes (models, data sets, logs, results, tables, plots)
goes through :func:`atomic_write`: the content is written to a temporary file
in the destination folder and renamed into place, so a reader never sees a
half-written file and a crash (even ``kill -9``) leaves the old file intact.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

from rkmpc.core.errors import InputFileError
from rkmpc.core.jsonutil import json_default

__all__ = ["atomic_write", "read_npz", "write_json_atomic", "write_text_atomic"]


@contextlib.contextmanager
def atomic_write(path: str | Path, mode: str = "w", *, suffix: str = ".tmp") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` for writing; rename it to ``path`` on success.

    Parameters
    ----------
    path : str or Path
        Destination; its folder is created when missing.
    mode : str
        ``"w"`` (text) or ``"wb"`` (bytes).
    suffix : str
        Suffix of the temporary file (some writers choose the format by it).

    Yields
    ------
    file object
        The open temporary file. When the block raises, the temporary file is
        removed and ``path`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    # mkstemp makes the file private (0600); give it the permissions of any new file instead.
    os.chmod(tmp, 0o666 & ~_umask())
    try:
        handle: IO[Any] = os.fdopen(fd, mode) if "b" in mode else os.fdopen(fd, mode, newline="")
        with handle:
            yield handle
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _umask() -> int:
    """The process's file-creation mask (read by setting it and putting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (:func:`atomic_write`)."""
    with atomic_write(path) as handle:
        handle.write(text)


def write_json_atomic(path: str | Path, payload: Any) -> None:
    """Write ``payload`` as indented JSON to ``path`` atomically (:func:`atomic_write`)."""
    with atomic_write(path) as handle:
        json.dump(payload, handle, indent=2, sort_keys=False, default=json_default)
        handle.write("\n")


def read_npz(path: Path) -> dict[str, np.ndarray]:
    """All arrays of an ``.npz`` file, or :class:`InputFileError` when it is not a readable archive.

    Pickled objects are never loaded (``allow_pickle=False``).
    """
    try:
        loaded = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        problem = f"not a readable .npz archive, corrupted or truncated? ({type(exc).__name__}: {exc})"
        raise InputFileError(path, problem) from None
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        raise InputFileError(path, "not an .npz archive (a single .npy array)")
    try:
        with loaded:
            return {key: loaded[key] for key in loaded.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        problem = f"damaged .npz archive, corrupted or truncated? ({type(exc).__name__}: {exc})"
        raise InputFileError(path, problem) from None
