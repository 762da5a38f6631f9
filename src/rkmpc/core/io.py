"""Files written whole or not at all, and archives read with clear errors.

Every file rkmpc writes (models, data sets, logs, results, tables, plots)
goes through :func:`atomic_write`: the content is written to a temporary file
in the destination folder and renamed into place, so a reader never sees a
half-written file and a crash (even ``kill -9``) leaves the old file intact.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import math
import os
import shutil
import stat
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import numpy as np

from rkmpc.core.errors import InputFileError, OutputError
from rkmpc.core.jsonutil import json_default

__all__ = [
    "MAX_NPZ_BYTES",
    "atomic_write",
    "check_output_file",
    "check_output_folder",
    "check_regular_file",
    "claim_output",
    "display_name",
    "output_folder",
    "read_npz",
    "write_json_atomic",
    "write_text_atomic",
]

#: Largest total size (bytes) of the arrays an ``.npz`` file may declare: 512 MiB, about four
#: million transitions of a data set (over 50 hours at 20 Hz) and thousands of times any model
#: file. The sizes are read from the archive's headers before anything is decompressed, so a
#: small file declaring huge arrays is refused at once rather than filling the memory.
MAX_NPZ_BYTES = 512 * 2**20


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


def check_output_file(path: str | Path) -> None:
    """Raise :class:`OutputError` when a file cannot be written at ``path`` (checked before any work).

    ``path`` must not be a folder, and its nearest existing ancestor must be a folder in which a
    file can be written: a small temporary file is written there, flushed to the disk and removed,
    so a full disk, a read-only file system or a folder without permission is found before hours
    of work rather than when the result is saved. An existing file is replaced (atomically) when
    the work is done.
    """
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{path} is a folder; give the name of the file to write")
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise OutputError(f"cannot write {path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write {path}: no permission to write in {parent}")
    try:
        with tempfile.NamedTemporaryFile(dir=parent, prefix=f".{path.name}.", suffix=".check") as probe:
            probe.write(bytes(_PROBE_BYTES))
            probe.flush()
            os.fsync(probe.fileno())
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise OutputError(f"cannot write {path}: {reason} (a test file in {parent} failed)") from None


#: Bytes of the test file :func:`check_output_file` writes: a few blocks, so a full disk refuses it.
_PROBE_BYTES = 64 * 1024


def check_output_folder(out: str | Path, *, force: bool, markers: tuple[str, ...]) -> bool:
    """Whether ``out`` is an earlier output to replace; :class:`OutputError` when it may not be used.

    A missing or empty folder is used as it is. A folder with anything in it is refused unless
    ``force``, and even then only when it holds one of ``markers`` (the file every completed output
    of the command has), so that ``--force`` never deletes a folder rkmpc did not write.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out} is a file, not a folder")
    if not out.exists() or not any(out.iterdir()):
        return False
    if not force:
        raise OutputError(
            f"{out} exists and is not empty (an earlier run's output?); "
            "choose another --out, or pass --force to replace it"
        )
    if not any((out / marker).is_file() for marker in markers):
        raise OutputError(f"{out} is not an rkmpc output (no {' or '.join(markers)}); not replacing it")
    return True


@contextlib.contextmanager
def output_folder(out: str | Path, *, force: bool, markers: tuple[str, ...]) -> Iterator[Path]:
    """A new folder to write a run's outputs in; it becomes ``out`` only when the run succeeds.

    ``out`` is first claimed (:func:`claim_output`: a second rkmpc writing it at the same time is
    refused at once) and checked (:func:`check_output_folder`). The outputs are written into a
    hidden temporary sibling folder, which is renamed to ``out`` when the block ends without error
    (replacing an earlier output as a whole with ``force``). When the block raises (an error,
    Ctrl-C), the temporary folder is removed, with any parent folder made for it: a failed run
    leaves ``out`` as it was and nothing half-written.

    Parameters
    ----------
    out : str or Path
        The output folder.
    force : bool
        Replace an earlier output (one holding one of ``markers``).
    markers : tuple of str
        File names, one of which every completed output of the command holds.

    Yields
    ------
    Path
        The folder to write in (not ``out``: name files relative to it).
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{out} is a file, not a folder")
    made = [p for p in (out.parent, *out.parent.parents) if not p.exists()]
    try:
        with claim_output(out):
            replace = check_output_folder(out, force=force, markers=markers)
            work = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.", suffix=".tmp"))
            try:
                os.chmod(work, 0o777 & ~_umask())  # mkdtemp's folder is private: make it like any new one
                yield work
                if replace:
                    old = work.with_suffix(".old")
                    os.replace(out, old)
                    try:
                        os.replace(work, out)
                    except OSError:
                        os.replace(old, out)
                        raise
                    shutil.rmtree(old, ignore_errors=True)
                else:
                    os.replace(work, out)  # also over an empty folder
            except BaseException:
                shutil.rmtree(work, ignore_errors=True)
                raise
    except BaseException:
        for folder in made:  # deepest first; only those still empty
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


#: Output folders this process holds (:func:`claim_output`), with how many claims each.
_CLAIMS: dict[Path, int] = {}


@contextlib.contextmanager
def claim_output(out: str | Path) -> Iterator[None]:
    """Hold the output ``out`` for this process while the block runs.

    The claim is an exclusive lock (``flock``) on a hidden file ``.NAME.lock`` beside ``out``,
    which holds the process id and is removed at the end; the operating system lets it go when
    the process dies (even of ``kill -9``), so no claim outlives its process. A process may claim
    the same output again (the claims nest). The folder ``out`` is in is made when missing.

    Raises
    ------
    OutputError
        When another process holds ``out``: two runs writing one folder would find out only when
        the second renames its finished work into place, after all of it.
    """
    out = Path(out)
    key = out.absolute()
    if key in _CLAIMS:
        _CLAIMS[key] += 1
        try:
            yield
        finally:
            _CLAIMS[key] -= 1
        return
    out.parent.mkdir(parents=True, exist_ok=True)
    lock = out.parent / f".{out.name}.lock"
    fd = _lock(lock, out)
    _CLAIMS[key] = 1
    try:
        yield
    finally:
        del _CLAIMS[key]
        with contextlib.suppress(OSError):
            lock.unlink()  # while still held: a process waiting on the old file then tries again
        os.close(fd)


def _lock(lock: Path, out: Path) -> int:
    """The descriptor of ``lock``, locked by this process and still the file under that name."""
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666 & ~_umask())
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise OutputError(f"cannot claim {out}: {exc.strerror} ({lock})") from None
            raise OutputError(
                f"{out} is being written by another rkmpc process now (process {holder}); "
                "wait for it to end, or choose another --out"
            ) from None
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:  # not a file its last holder removed meanwhile
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
            return fd
        os.close(fd)


def display_name(text: str) -> str:
    """``text`` (a file name) safe to show and write: undecodable bytes as ``\\xNN``.

    A file name that is not valid UTF-8 comes into Python with its bad bytes as lone surrogates
    (:func:`os.fsdecode`), which no UTF-8 file, terminal font or plot can take; here they become
    the escapes ``\\xe9``, so ``ov\\xe9al`` names the file ``ov<0xe9>al``.
    """
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")


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
