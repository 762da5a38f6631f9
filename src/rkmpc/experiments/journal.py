"""Finished jobs of a long study kept on disk, so that a stopped run resumes where it was.

A pace study over every shared track runs for hours; a crash, a reboot or a Ctrl-C used to lose
all of it, because a study writes its result only at the end. A :class:`JobJournal` is a folder
in which :func:`rkmpc.experiments.parallel.run_jobs` keeps the outcome of every job that
finished without error, as it finishes. A later run given the same folder takes those outcomes
from it instead of running the jobs again, and runs only the rest (the jobs that failed, were
not reached, or are new: a study can be widened to more tracks and keep what it has).

What must match for an outcome to be reused is the study's *settings* (a JSON-ready mapping the
study builds: its configuration without the list of jobs, and the package's version). The
journal records them in ``journal.json`` when it is first opened; opening it with other settings
raises :class:`JournalError` naming the keys that differ, so results of other settings are never
mixed in. Each job is stored under its key (by default its name) in ``<sha256>.json``, written to
a temporary name and renamed, so an interrupted write leaves no half entry.

Entries are JSON: the job's outcome with its value encoded by the study (``encode``) and decoded
when read (``decode``); nothing in a journal can run code. Journals of format 1 held pickles: they
are refused, never unpickled.

A journal that cannot be written (a full disk, a folder gone read-only) never stops the study it
keeps: the first failure is said once (``warn``, naming the folder and the reason), every entry not
kept is counted (:attr:`JobJournal.unkept`), and the study's results are whole; only a later
resumed run would run those jobs again.
"""

from __future__ import annotations

import hashlib
import json
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rkmpc.core.errors import OutputError
from rkmpc.core.io import write_json_atomic
from rkmpc.core.jsonutil import to_json_ready

__all__ = ["JobJournal", "JournalError", "JournalWarning", "canonical_json"]

#: Version of the journal's layout (``journal.json`` and the entries); 1 held pickles.
JOURNAL_FORMAT = 2


class JournalError(OutputError):
    """A journal folder cannot be used: other settings, an unreadable entry, a file in the way."""


class JournalWarning(UserWarning):
    """A journal could not keep a finished job (its study goes on, its result whole)."""


def _warn(message: str) -> None:
    warnings.warn(message, JournalWarning, stacklevel=3)


def canonical_json(value: Any) -> str:
    """One text per JSON-ready value (sorted keys, no spaces): how settings and job keys compare."""
    return json.dumps(to_json_ready(value), sort_keys=True, separators=(",", ":"))


def _differences(old: Any, new: Any, where: str) -> list[str]:
    """Dotted paths of the entries in which two JSON values differ (mappings are entered)."""
    if isinstance(old, dict) and isinstance(new, dict):
        out: list[str] = []
        for key in sorted(set(old) | set(new)):
            out += _differences(old.get(key), new.get(key), f"{where}.{key}" if where else key)
        return out
    return [] if canonical_json(old) == canonical_json(new) else [where]


@dataclass(frozen=True)
class JobJournal:
    """A folder of finished jobs, valid for one study's settings.

    Parameters
    ----------
    folder : str or Path
        Where the entries live (made when missing).
    settings : mapping
        JSON-ready description of everything that makes a job's outcome what it is, apart from
        the job itself (whose key names it).
    encode : callable
        A job's value as JSON-ready data (default: :func:`~rkmpc.core.jsonutil.to_json_ready`).
    decode : callable
        The value back from that data (default: as read).
    outcome : callable
        Makes an outcome from its fields (:class:`rkmpc.experiments.parallel.JobOutcome`; given by
        the caller, this module sits below the one that defines it).
    warn : callable or None
        Told once, in one line, when the journal first fails to keep a job (None: a
        :class:`JournalWarning`).
    """

    folder: Path
    settings: Mapping[str, Any]
    encode: Callable[[Any], Any] = field(default=to_json_ready, compare=False)
    decode: Callable[[Any], Any] = field(default=lambda data: data, compare=False)
    outcome: Callable[..., Any] = field(default=dict, compare=False)
    warn: Callable[[str], None] | None = field(default=None, compare=False)
    _unkept: list[str] = field(default_factory=list, init=False, compare=False, repr=False)
    _failure: list[str] = field(default_factory=list, init=False, compare=False, repr=False)
    _headless: list[bool] = field(default_factory=list, init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "folder", Path(self.folder))
        object.__setattr__(self, "settings", json.loads(canonical_json(dict(self.settings))))

    @property
    def unkept(self) -> int:
        """Finished jobs this journal could not keep (a write failed: a full disk, ...)."""
        return len(self._unkept)

    @property
    def failure(self) -> str | None:
        """Why the journal could not keep a job (the first error), or None."""
        return self._failure[0] if self._failure else None

    def _failed(self, key: str | None, exc: OSError) -> None:
        """Count a job's entry that could not be written (``key``; None: the header); say the first."""
        if key is not None:
            self._unkept.append(key)
        if self._failure:
            return
        reason = exc.strerror or str(exc)
        self._failure.append(reason)
        (self.warn if self.warn is not None else _warn)(
            f"journal {self.folder}: cannot keep finished jobs ({reason}); the study goes on and its "
            "results are whole, but a resumed run would run the jobs not kept again"
        )

    @property
    def _header(self) -> Path:
        return self.folder / "journal.json"

    def open(self) -> JobJournal:
        """Make the folder, or check that it was made for the same settings; returns ``self``.

        Raises
        ------
        JournalError
            ``folder`` is a file, holds files but no ``journal.json``, or its settings differ.
        """
        if self.folder.exists() and not self.folder.is_dir():
            raise JournalError(f"journal {self.folder} is a file, not a folder")
        if not self._header.is_file():
            if self.folder.is_dir() and any(self.folder.iterdir()):
                raise JournalError(f"journal {self.folder} is not empty and holds no journal.json")
            try:
                write_json_atomic(self._header, {"format": JOURNAL_FORMAT, "settings": self.settings})
            except OSError as exc:
                self._headless.append(True)
                self._failed(None, exc)
            return self
        try:
            header = json.loads(self._header.read_text())
            old = header["settings"]
            fmt = header["format"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise JournalError(f"journal {self._header}: unreadable ({exc})") from exc
        if fmt == 1:
            raise JournalError(
                f"journal {self.folder} was written by an older rkmpc as pickles, which are never read "
                "(they could run code); give another journal folder or delete this one"
            )
        if fmt != JOURNAL_FORMAT:
            raise JournalError(f"journal {self._header}: format {fmt!r}, this version reads {JOURNAL_FORMAT}")
        if canonical_json(old) != canonical_json(self.settings):
            keys = _differences(old, self.settings, "")
            raise JournalError(
                f"journal {self.folder} was written by a study with other settings "
                f"(differing: {', '.join(keys)}); give another journal folder or delete this one"
            )
        return self

    def _entry(self, key: str) -> Path:
        return self.folder / f"{hashlib.sha256(key.encode()).hexdigest()[:32]}.json"

    def load(self, key: str) -> Any:
        """The outcome stored under ``key`` (a :class:`~rkmpc.experiments.parallel.JobOutcome`), or None.

        Raises
        ------
        JournalError
            The entry cannot be read, belongs to another key or its value does not decode.
        """
        path = self._entry(key)
        if not path.is_file():
            return None
        try:
            stored = json.loads(path.read_text(encoding="utf-8"))
            stored_key, data = stored["key"], stored["outcome"]
            outcome = self.outcome(
                name=str(data["name"]),
                index=int(data["index"]),
                ok=bool(data["ok"]),
                value=self.decode(data["value"]),
                error=data["error"],
                traceback=data["traceback"],
                seconds=float(data["seconds"]),
                warnings=tuple(str(m) for m in data["warnings"]) if "warnings" in data else (),
            )
        except Exception as exc:
            raise JournalError(f"journal entry {path} (job {key!r}): unreadable ({exc})") from exc
        if stored_key != key:
            raise JournalError(f"journal entry {path} holds job {stored_key!r}, not {key!r}")
        return outcome

    def save(self, key: str, outcome: Any) -> bool:
        """Store a finished job's outcome under ``key``, its value encoded as JSON; whether it was kept.

        A write that fails (:class:`OSError`: a full disk, ...) is counted (:attr:`unkept`), the
        first one said (``warn``), and never raised: the study goes on. Once the journal's own
        ``journal.json`` could not be written, no entry is written (it could never be resumed).
        """
        if self._headless:
            self._unkept.append(key)
            return False
        entry = {
            "name": outcome.name,
            "index": outcome.index,
            "ok": outcome.ok,
            "value": self.encode(outcome.value),
            "error": outcome.error,
            "traceback": outcome.traceback,
            "seconds": outcome.seconds,
            "warnings": list(outcome.warnings),
        }
        try:
            write_json_atomic(self._entry(key), {"key": key, "outcome": entry})
        except OSError as exc:
            self._failed(key, exc)
            return False
        return True
