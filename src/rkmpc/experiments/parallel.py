"""Run independent jobs in parallel: local processes, a Dask cluster or a Ray cluster.

Every study in :mod:`rkmpc.experiments.studies.tracks` is a list of independent
jobs (one track, one seed, one data size...). :func:`run_jobs` runs such a
list through :mod:`joblib`:

``"loky"`` (default)
    Local worker processes started with ``spawn`` semantics (never ``fork``:
    forking a process in which PyTorch has started its thread pools can
    deadlock).
``"dask"``
    joblib's own Dask backend. It uses the :class:`dask.distributed.Client`
    already created in this process, or connects to the scheduler at
    ``address``. Concurrency is the cluster's (its worker threads), not
    ``n_jobs``.
``"ray"``
    joblib's Ray backend (:func:`ray.util.joblib.register_ray`). Ray is
    started locally when it is not running yet (``address=None``), or joined
    at ``address``; a Ray session started here is shut down afterwards.

Jobs run with one numeric thread each (``OMP_NUM_THREADS``,
``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS`` and PyTorch's intra-op
threads set to 1), so that ``n_jobs`` jobs use ``n_jobs`` cores. With
``n_jobs=1`` on ``"loky"`` the jobs run one after the other in the calling
process and its thread settings are left alone.

A local (loky) worker watches the process that started it and ends soon after it
(:func:`rkmpc.experiments.backends.watch_parent`): a study killed with ``kill -9`` leaves
no worker running its job on for minutes.

Failures: a job that raises is caught in its worker. With
``on_error="raise"`` (default) :func:`run_jobs` raises :class:`JobError`
naming the first failed job (in completion order) and its message, and the
jobs still queued are cancelled; with ``on_error="record"`` every job runs and
the failure is returned as a :class:`JobOutcome` with ``ok=False`` and the
message, which the studies use so that one bad track does not lose a long run.
A worker process that dies (killed, out of memory) cannot be attributed to a
job and raises :class:`JobError` in both modes.

Resuming: with a :class:`~rkmpc.experiments.journal.JobJournal`, every job that finishes
without error is kept on disk as it finishes, and the jobs a journal already holds are not run
again (their outcomes come back with ``resumed=True``).
"""

from __future__ import annotations

import os
import sys
import time
import traceback
import warnings
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol, cast

import joblib

from rkmpc.core.errors import ParameterError, RkmpcError
from rkmpc.experiments.backends import backend_config, check_backend, watch_parent

#: Environment variables set to ``"1"`` in workers (numeric libraries' thread pools).
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


class JobError(RkmpcError, RuntimeError):
    """A job (or the worker running it) failed.

    Parameters
    ----------
    name : str or None
        Name of the failed job, None when a worker died and the job is unknown.
    message : str
        What went wrong.
    """

    def __init__(self, name: str | None, message: str) -> None:
        self.name = name
        self.message = message
        where = f"job {name!r} failed" if name is not None else "a parallel worker failed"
        super().__init__(f"{where}: {message}")


@dataclass(frozen=True)
class Job:
    """One independent unit of work.

    Parameters
    ----------
    name : str
        Label used in progress reports and error messages (unique in a run).
    func : callable
        A picklable callable (a module-level function), called as
        ``func(*args, **kwargs)`` in a worker.
    args : tuple
        Positional arguments (picklable).
    kwargs : mapping
        Keyword arguments (picklable).
    key : str
        What identifies the job in a :class:`~rkmpc.experiments.journal.JobJournal` across runs
        (default: ``name``; a study whose names are short labels gives the full spec here).
    """

    name: str
    func: Callable[..., Any]
    args: tuple[Any, ...] = ()
    kwargs: Mapping[str, Any] = field(default_factory=dict)
    key: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(f"Job.name must be a non-empty string, got {self.name!r}")
        if not callable(self.func):
            raise ParameterError(f"Job.func of job {self.name!r} is not callable: {self.func!r}")
        if not self.key:
            object.__setattr__(self, "key", self.name)


@dataclass(frozen=True)
class JobOutcome:
    """What one job returned.

    Parameters
    ----------
    name : str
        The job's name.
    index : int
        Position of the job in the list given to :func:`run_jobs`.
    ok : bool
        False when the job raised.
    value : object
        The job's return value (None when it failed).
    error : str or None
        ``"ExceptionType: message"`` of a failed job.
    traceback : str or None
        Formatted traceback of a failed job (from the worker).
    seconds : float
        Wall time of the job in its worker (s), in the run that ran it.
    resumed : bool
        Taken from a journal (an earlier run) instead of run now.
    warnings : tuple of str
        ``"WarningType: message"`` of every distinct warning the job raised, in order.
    """

    name: str
    index: int
    ok: bool
    value: Any = None
    error: str | None = None
    traceback: str | None = None
    seconds: float = 0.0
    resumed: bool = False
    warnings: tuple[str, ...] = ()


#: Progress callback: ``(outcome, jobs_done, jobs_total)``, called in the calling process.
ProgressCallback = Callable[[JobOutcome, int, int], None]


class Journal(Protocol):
    """Where finished jobs are kept (:class:`rkmpc.experiments.journal.JobJournal`)."""

    def load(self, key: str) -> JobOutcome | None:
        """The outcome kept under ``key``, or None."""

    def save(self, key: str, outcome: JobOutcome) -> object:
        """Keep a finished job's outcome under ``key`` (never raising: a journal that fails is counted)."""


def limit_threads() -> None:
    """Use one thread in numeric libraries from now on, in this process.

    Sets :data:`THREAD_VARIABLES` to ``"1"`` (read when the libraries are
    first loaded) and, when PyTorch is loaded already, its intra-op threads.
    """
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(1)


#: A warnings filter as :data:`warnings.filters` holds it: action, message, category, module, line.
WarningFilter = tuple[str, Any, Any, Any, int]


def _run_one(
    index: int,
    job: Job,
    single_thread: bool,
    parent: int | None = None,
    filters: Sequence[WarningFilter] | None = None,
) -> JobOutcome:
    """Worker side: run one job and catch its failure; a local worker ends with its ``parent``.

    The job's warnings are recorded, filtered by the calling process's ``filters`` (what it
    ignores, a worker ignores too; None: this process's own filters).
    """
    if parent is not None:
        watch_parent(parent)
    if single_thread:
        limit_threads()
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        if filters is not None:
            _use_filters(filters)
        try:
            value = job.func(*job.args, **dict(job.kwargs))
        except Exception as exc:
            return JobOutcome(
                name=job.name,
                index=index,
                ok=False,
                error=f"{type(exc).__name__}: {exc}",
                traceback=traceback.format_exc(),
                seconds=time.perf_counter() - t0,
                warnings=_messages(caught),
            )
    return JobOutcome(
        name=job.name,
        index=index,
        ok=True,
        value=value,
        seconds=time.perf_counter() - t0,
        warnings=_messages(caught),
    )


def _use_filters(filters: Sequence[WarningFilter]) -> None:
    """Make ``filters`` (a snapshot of :data:`warnings.filters`, in order) the warnings filters.

    Called first inside :class:`warnings.catch_warnings`, which restores the process's own ones
    and, on entering, has marked every warning registry stale: nothing is cached before this.
    """
    cast(list[WarningFilter], warnings.filters)[:] = filters


def _messages(caught: Iterable[warnings.WarningMessage]) -> tuple[str, ...]:
    """Each distinct warning of ``caught`` once, as ``"WarningType: message"``, in order."""
    return tuple(dict.fromkeys(f"{w.category.__name__}: {w.message}" for w in caught))


def _check(jobs: Sequence[Job], n_jobs: int, backend: str, on_error: str) -> None:
    check_backend(backend)
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs == 0 or n_jobs < -1:
        raise ParameterError(f"n_jobs must be a positive integer or -1 (all cores), got {n_jobs!r}")
    if on_error not in ("raise", "record"):
        raise ParameterError(f"on_error must be 'raise' or 'record', got {on_error!r}")
    if not all(isinstance(j, Job) for j in jobs):
        raise ParameterError("run_jobs: every job must be a Job")
    for field_name in ("name", "key"):
        counts = Counter(getattr(j, field_name) for j in jobs)
        dup = sorted(v for v, n in counts.items() if n > 1)
        if dup:
            raise ParameterError(f"run_jobs: job {field_name}s must be unique, repeated: {dup}")


def run_jobs(
    jobs: Sequence[Job],
    *,
    n_jobs: int = 1,
    backend: str = "loky",
    address: str | None = None,
    on_error: str = "raise",
    progress: ProgressCallback | None = None,
    journal: Journal | None = None,
) -> list[JobOutcome]:
    """Run independent jobs and return their outcomes in job order.

    Parameters
    ----------
    jobs : sequence of Job
        The jobs; names must be unique.
    n_jobs : int
        Concurrent jobs for ``"loky"`` and ``"ray"`` (-1: all cores); the
        Dask backend runs as many as the cluster has worker threads.
    backend : {"loky", "dask", "ray"}
        Where the jobs run (see the module docstring).
    address : str, optional
        Dask scheduler (``"tcp://host:8786"``) or Ray cluster
        (``"ray://host:10001"``, ``"auto"``) address. With ``"dask"`` and no
        address the process's current :class:`dask.distributed.Client` is used.
        Ignored by ``"loky"``.
    on_error : {"raise", "record"}
        Raise :class:`JobError` at the first failed job, or record failures
        in the outcomes and run every job.
    progress : callable, optional
        ``progress(outcome, done, total)``, called in this process as each job
        finishes (in completion order; with ``"ray"``, whose joblib backend
        returns results only at the end, once per job after all have run).
    journal : JobJournal, optional
        Jobs whose outcome the journal holds (by :attr:`Job.key`) are not run: their outcome is
        taken from it (``resumed=True``, reported first); every job that finishes without error
        is stored in it as it finishes (:mod:`rkmpc.experiments.journal`). It must be open.

    Returns
    -------
    list of JobOutcome
        One per job, in the order of ``jobs``.

    Raises
    ------
    ParameterError
        Bad ``n_jobs``, ``backend``, ``on_error`` or jobs.
    JobError
        A job failed (``on_error="raise"``), or a worker process died.
    MissingPackageError
        ``dask``/``distributed`` or ``ray`` is not installed (``pip install rkmpc[cluster]``), an
        :class:`ImportError`.
    """
    jobs = list(jobs)
    _check(jobs, n_jobs, backend, on_error)
    total = len(jobs)
    outcomes: list[JobOutcome | None] = [None] * total
    done = 0
    todo: list[tuple[int, Job]] = []
    for i, job in enumerate(jobs):
        earlier = None if journal is None else journal.load(job.key)
        if earlier is None:
            todo.append((i, job))
            continue
        outcome = outcomes[i] = replace(earlier, name=job.name, index=i, resumed=True)
        done += 1
        if progress is not None:
            progress(outcome, done, total)
    if todo:
        _run(
            todo,
            outcomes,
            done,
            n_jobs=n_jobs,
            backend=backend,
            address=address,
            on_error=on_error,
            progress=progress,
            journal=journal,
        )
    missing = [jobs[i].name for i, o in enumerate(outcomes) if o is None]
    if missing:
        raise JobError(missing[0], "no result came back from the backend")
    return [o for o in outcomes if o is not None]


def _run(
    todo: list[tuple[int, Job]],
    outcomes: list[JobOutcome | None],
    done: int,
    *,
    n_jobs: int,
    backend: str,
    address: str | None,
    on_error: str,
    progress: ProgressCallback | None,
    journal: Journal | None,
) -> None:
    """Run the jobs of ``todo`` (index, job), filling ``outcomes`` and the journal as they finish."""
    total = len(outcomes)
    single_thread = not (backend == "loky" and n_jobs == 1)
    if backend == "loky" and n_jobs > len(todo):
        n_jobs = len(todo)  # no more workers than jobs (the threads per job stay as asked, above)
    config, started_ray = backend_config(backend, n_jobs, address)
    keys = {i: job.key for i, job in todo}
    parent = os.getpid() if backend == "loky" else None  # local workers end with this process
    filters = tuple(warnings.filters)  # the workers filter the jobs' warnings as this process does
    calls = (joblib.delayed(_run_one)(i, job, single_thread, parent, filters) for i, job in todo)
    try:
        with joblib.parallel_config(**config):
            for outcome in _results(calls, unordered=backend != "ray"):
                outcomes[outcome.index] = outcome
                if journal is not None and outcome.ok:  # failed jobs are not kept: they run again
                    journal.save(keys[outcome.index], outcome)
                done += 1
                if progress is not None:
                    progress(outcome, done, total)
                if not outcome.ok and on_error == "raise":
                    raise JobError(outcome.name, f"{outcome.error}\n{outcome.traceback}")
    finally:
        if started_ray:
            import ray

            ray.shutdown()


def _results(calls: Iterable[Any], *, unordered: bool) -> Iterator[JobOutcome]:
    """Outcomes as the backend hands them back; a failing backend or worker is a :class:`JobError`."""
    parallel = joblib.Parallel(return_as="generator_unordered" if unordered else "list")
    try:
        results = iter(parallel(calls))
    except Exception as exc:
        raise JobError(None, f"{type(exc).__name__}: {exc}") from exc
    while True:
        try:
            yield next(results)
        except StopIteration:
            return
        except Exception as exc:  # a worker died, or the backend failed
            raise JobError(None, f"{type(exc).__name__}: {exc}") from exc
