"""run_jobs: same results in job order through serial, loky and a local Dask cluster."""

from __future__ import annotations

import math
import operator
import os
import warnings

import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.experiments.parallel import Job, JobError, run_jobs

# Module-level functions of the standard library: picklable by reference in any worker.
JOBS = [Job(f"pow-{i}", operator.pow, (i, 2)) for i in range(6)] + [
    Job("hyp", math.hypot, (3.0, 4.0)),
    Job("threads", os.getenv, ("OMP_NUM_THREADS",)),
]
EXPECTED = [0, 1, 4, 9, 16, 25, 5.0]


def _values(outcomes):
    assert [o.name for o in outcomes] == [j.name for j in JOBS]
    assert [o.index for o in outcomes] == list(range(len(JOBS)))
    assert all(o.ok for o in outcomes)
    return [o.value for o in outcomes]


def test_serial_runs_in_order_and_reports_progress():
    seen = []
    out = run_jobs(JOBS, progress=lambda o, done, total: seen.append((o.name, done, total)))
    assert _values(out)[:-1] == EXPECTED
    assert [s[1] for s in seen] == list(range(1, len(JOBS) + 1))
    assert all(s[2] == len(JOBS) for s in seen)


def test_loky_matches_serial_with_one_thread_per_worker():
    out = run_jobs(JOBS, n_jobs=2, backend="loky")
    values = _values(out)
    assert values[:-1] == EXPECTED
    assert values[-1] == "1"  # numeric libraries limited to one thread in workers


def test_failures_raise_with_the_job_name_or_are_recorded():
    jobs = [Job("ok", math.sqrt, (4.0,)), Job("bad-sqrt", math.sqrt, (-1.0,))]
    with pytest.raises(JobError, match=r"bad-sqrt.*ValueError"):
        run_jobs(jobs)
    out = run_jobs(jobs, on_error="record")
    assert out[0].ok and out[0].value == 2.0
    assert not out[1].ok and out[1].value is None
    assert out[1].error.startswith("ValueError")
    assert "Traceback" in out[1].traceback


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"backend": "spark"}, "backend"),
        ({"n_jobs": 0}, "n_jobs"),
        ({"on_error": "ignore"}, "on_error"),
    ],
)
def test_bad_settings(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        run_jobs(JOBS, **kwargs)


def test_duplicate_names_and_bad_jobs():
    with pytest.raises(ParameterError, match="unique"):
        run_jobs([Job("a", abs, (1,)), Job("a", abs, (2,))])
    with pytest.raises(ParameterError, match="callable"):
        Job("x", 3)  # type: ignore[arg-type]
    assert run_jobs([]) == []


@pytest.mark.slow
def test_dask_local_cluster_matches_serial():
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster),
    ):
        out = run_jobs(JOBS, backend="dask")
        values = _values(out)
        failed = run_jobs([Job("bad", math.sqrt, (-1.0,))], backend="dask", on_error="record")
    assert values[:-1] == EXPECTED
    assert values[-1] == "1"
    assert not failed[0].ok and "ValueError" in failed[0].error


def test_dask_without_client_is_a_clear_error():
    pytest.importorskip("distributed")
    with pytest.raises(ParameterError, match="Client"):
        run_jobs(JOBS, backend="dask")


def test_no_more_workers_than_jobs(monkeypatch):
    """--jobs 8 for two jobs starts two workers, and each still runs on one thread."""
    import rkmpc.experiments.parallel as parallel

    seen = []
    real = parallel.backend_config

    def spy(backend, n_jobs, address):
        seen.append(n_jobs)
        return real(backend, n_jobs, address)

    monkeypatch.setattr(parallel, "backend_config", spy)
    out = run_jobs([JOBS[1], JOBS[-1]], n_jobs=8, backend="loky")
    assert seen == [2]
    assert [o.value for o in out] == [1, "1"]


def test_a_backend_whose_package_is_missing_is_one_clear_line_before_any_work(monkeypatch):
    import importlib.util

    from rkmpc.core.errors import MissingPackageError
    from rkmpc.experiments import backends

    real = importlib.util.find_spec
    monkeypatch.setattr(
        backends.importlib.util, "find_spec", lambda name, *rest: None if name == "ray" else real(name, *rest)
    )
    with pytest.raises(MissingPackageError, match=r"^backend 'ray' needs ray, not installed: pip install"):
        run_jobs(JOBS, backend="ray")
    assert issubclass(MissingPackageError, ImportError)  # what callers catching ImportError still see
    backends.check_backend("loky")  # nothing to install


def _warn_twice(x: int) -> int:
    warnings.warn(f"odd {x}", UserWarning, stacklevel=1)
    warnings.warn(f"odd {x}", UserWarning, stacklevel=1)  # the same message: kept once
    warnings.warn("late", RuntimeWarning, stacklevel=1)
    if x < 0:
        raise ValueError("negative")
    return x


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_job_s_warnings_are_recorded_in_its_outcome_not_printed(n_jobs, capfd):
    jobs = [Job("quiet", operator.pow, (2, 3)), Job("warns", _warn_twice, (3,))]
    jobs.append(Job("fails", _warn_twice, (-1,)))
    out = run_jobs(jobs, n_jobs=n_jobs, backend="loky", on_error="record")
    assert out[0].warnings == ()
    assert out[1].warnings == ("UserWarning: odd 3", "RuntimeWarning: late")
    assert not out[2].ok and out[2].warnings == ("UserWarning: odd -1", "RuntimeWarning: late")
    assert "odd" not in capfd.readouterr().err


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_warning_the_caller_ignores_is_ignored_in_every_worker(n_jobs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        (out,) = run_jobs([Job("warns", _warn_twice, (3,))], n_jobs=n_jobs, backend="loky")
    assert out.warnings == ("UserWarning: odd 3",)
