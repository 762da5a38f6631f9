"""Files written whole or not at all, and output folders claimed before the work.

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
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from rkmpc.core.errors import OutputError
from rkmpc.core.jsonutil import json_default

__all__ = [
    "atomic_write",
    "check_output_file",
    "check_output_folder",
    "claim_output",
    "display_name",
    "output_folder",
    "write_json_atomic",
    "write_text_atomic",
]


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
