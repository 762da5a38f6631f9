"""One way to run a study: the :class:`Study` protocol and :func:`run_study`.

A study is a list of independent jobs (one track and seed, one car, one controller up the pace
ladder, ...) and what it makes of their outcomes. Every study of :mod:`rkmpc.experiments.studies`
implements :class:`Study`; :func:`run_study` runs any of them the same way: the shared models first
(:meth:`Study.prepare`), then the jobs in parallel (:func:`rkmpc.experiments.parallel.run_jobs`,
a failing job recorded and the others going on), each finished job kept in a journal when one is
given (JSON, :mod:`rkmpc.experiments.journal`) and reported as it finishes, and the typed result
built from the outcomes (:meth:`Study.result`), which writes itself as JSON, Markdown and a figure.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Protocol, TypeVar

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer, require_choice
from rkmpc.core.versions import versions
from rkmpc.experiments.backends import BACKENDS, check_backend
from rkmpc.experiments.journal import JobJournal
from rkmpc.experiments.parallel import Job, JobOutcome, ProgressCallback, run_jobs

__all__ = ["ConfigJournal", "Parallel", "Study", "StudyResult", "StudyRun", "run_study", "study_versions"]

Say = Callable[[str], None]


def study_versions() -> dict[str, str]:
    """:func:`rkmpc.core.versions.versions` plus the learning and parallel packages."""
    return versions(extra=("torch", "joblib", "dask", "distributed", "ray"))


@dataclass(frozen=True, kw_only=True)
class Parallel:
    """Where a study's jobs run (:func:`rkmpc.experiments.parallel.run_jobs`).

    Parameters
    ----------
    n_jobs : int
        Concurrent jobs (-1: every core).
    backend : str
        ``"loky"`` (local processes), ``"dask"`` or ``"ray"``.
    address : str or None
        The scheduler of a running Dask or Ray cluster; only with those backends.
    """

    n_jobs: int = 1
    backend: str = "loky"
    address: str | None = None

    def __post_init__(self) -> None:
        require_choice(self, "backend", BACKENDS)
        if not is_integer(self.n_jobs) or self.n_jobs == 0 or self.n_jobs < -1:
            raise ParameterError(f"Parallel.n_jobs must be a positive integer or -1, got {self.n_jobs!r}")
        if self.address is not None and self.backend == "loky":
            raise ParameterError("an address is for a dask or ray cluster: give the backend too (--backend)")

    def to_json(self) -> dict[str, Any]:
        return {"n_jobs": self.n_jobs, "backend": self.backend, "address": self.address}


@dataclass(frozen=True, kw_only=True)
class StudyRun:
    """How a study ran: where, with which versions, how long (wall time, for reports only), and
    what its jobs warned (job name -> ``"WarningType: message"`` of each distinct warning; only
    the jobs that warned)."""

    parallel: Parallel
    versions: Mapping[str, str]
    wall_s: float
    warnings: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "parallel": self.parallel.to_json(),
            "versions": dict(self.versions),
            "wall_s": self.wall_s,
            "warnings": {name: list(messages) for name, messages in self.warnings.items()},
        }


class StudyResult(Protocol):
    """What a study returns: it writes itself as JSON and Markdown, and draws its figure."""

    def to_json(self) -> dict[str, Any]: ...

    def to_markdown(self) -> str: ...

    def figure(self) -> Any:
        """A matplotlib figure of the result, or None for a study without one."""
        ...


R = TypeVar("R", bound=StudyResult, covariant=True)


class Study(Protocol[R]):
    """A study: its jobs, what a journal of it must match, and its result from the jobs' outcomes."""

    #: The study's name (``rkmpc study NAME``, ``study_NAME.json``).
    name: ClassVar[str]

    def prepare(self, say: Say) -> None:
        """Work shared by the jobs, done once in this process first (models every job reads)."""
        ...

    def jobs(self) -> Sequence[Job]:
        """The independent jobs; each job's ``key`` identifies it in a journal."""
        ...

    def journal_settings(self) -> dict[str, Any]:
        """What a journal's outcomes must have been made with (JSON-ready) to be reused."""
        ...

    def encode(self, value: Any) -> Any:
        """A job's return value as JSON-ready data (what the journal stores)."""
        ...

    def decode(self, data: Any) -> Any:
        """A job's return value from :meth:`encode`'s data."""
        ...

    def result(self, outcomes: list[JobOutcome], run: StudyRun) -> R:
        """The study's typed result from its jobs' outcomes (in job order)."""
        ...


class ConfigJournal:
    """The journal of a study whose settings are its ``config`` and whose jobs each return a ``run_type``.

    A journal is reused only by a study of the same ``config.to_json()``; a job's value is stored as
    its ``to_json()`` and read back with ``run_type.from_json``.
    """

    config: Any
    #: The type every job returns.
    run_type: ClassVar[Any]

    def journal_settings(self) -> dict[str, Any]:
        return dict(self.config.to_json())

    def encode(self, value: Any) -> dict[str, Any]:
        return dict(value.to_json())

    def decode(self, data: Any) -> Any:
        return self.run_type.from_json(data)


def run_study(
    study: Study[R],
    *,
    parallel: Parallel | None = None,
    journal: str | Path | None = None,
    progress: ProgressCallback | None = None,
    say: Say | None = None,
) -> R:
    """Run ``study``: its shared work, then its jobs in parallel, then its result.

    Parameters
    ----------
    study : Study
        What to run.
    parallel : Parallel, optional
        Where the jobs run (one local job at a time by default).
    journal : path, optional
        A folder that keeps every finished job (JSON); a later run given it runs only the others.
        It must have been made for the same :meth:`Study.journal_settings`.
    progress : callable, optional
        ``progress(outcome, done, total)`` as each job finishes.
    say : callable, optional
        Called with a short message before each slow stage.
    """
    where = parallel if parallel is not None else Parallel()
    check_backend(where.backend)  # a missing package said before the shared models are trained
    tell = say if say is not None else (lambda _message: None)
    kept = None
    if journal is not None:
        settings = {"study": study.name, "settings": study.journal_settings(), "versions": study_versions()}
        kept = JobJournal(
            Path(journal), settings, encode=study.encode, decode=study.decode, outcome=JobOutcome, warn=say
        ).open()
    study.prepare(tell)
    jobs = list(study.jobs())
    tell(f"{len(jobs)} jobs on {where.n_jobs} {where.backend} workers")
    t0 = time.perf_counter()
    outcomes = run_jobs(
        jobs,
        n_jobs=where.n_jobs,
        backend=where.backend,
        address=where.address,
        on_error="record",
        progress=progress,
        journal=kept,
    )
    run = StudyRun(
        parallel=where,
        versions=study_versions(),
        wall_s=time.perf_counter() - t0,
        warnings={o.name: o.warnings for o in outcomes if o.warnings},
    )
    if kept is not None and kept.unkept:
        tell(
            f"journal {kept.folder}: {kept.unkept} of {len(jobs)} finished jobs not kept ({kept.failure}); "
            "the results below are whole"
        )
    return study.result(outcomes, run)
