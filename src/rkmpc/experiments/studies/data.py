"""RKMPC and KMPC as the training data grow: :func:`study_data` (the paper's data-volume figure).

Sec. V of the paper: "RKMPC uses about 8000 data points while KMPC needs 50000
or more". One parallel job per (controller, size, seed) collects data as its
recipe says (LMPC laps of the track, or random excitation of the car), trains
on about ``size`` local-frame samples and drives one lap.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.analysis.statistics import Stats, stats
from rkmpc.analysis.study_plots import VolumeSeries
from rkmpc.analysis.tables import fmt, fmt_stats, markdown
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.parallel import Job, JobOutcome, run_jobs
from rkmpc.experiments.runs import run_controller
from rkmpc.experiments.studies.common import (
    check_parallel,
    json_object,
    settings_json,
    study_versions,
)
from rkmpc.experiments.studies.data_job import DEFAULT_SIZES, DataStudyConfig, data_job
from rkmpc.sim.run import RunSpec

__all__ = ["DEFAULT_SIZES", "DataStudyConfig", "DataStudyResult", "study_data"]


@dataclass(frozen=True)
class SizeSummary:
    """One (controller, size) of the data study: completion and errors over the seeds.

    ``completion_rate`` counts a failed job as a lap not completed; the lateral
    and heading errors are over completed laps only (a lap cut short is not
    comparable); ``progress`` over the jobs that drove; sample counts and
    training time over the jobs that ran.
    """

    controller: str
    size: int
    seeds: list[int]
    jobs: int
    failed_jobs: int
    completed: int
    completion_rate: float
    lateral_error_mean_m: Stats
    lateral_error_max_m: Stats
    heading_error_mean_rad: Stats
    progress: Stats
    augmented_count: Stats
    raw_count: Stats
    train_s: Stats


def summarise_sizes(jobs: Sequence[dict[str, Any]]) -> list[SizeSummary]:
    """Per (controller, size) summaries of data-study job records, by controller (first seen) and size."""
    groups: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for job in jobs:
        groups.setdefault((job["controller"], int(job["size"])), []).append(job)
    order = list(dict.fromkeys(job["controller"] for job in jobs))
    out = []
    for controller, size in sorted(groups, key=lambda k: (order.index(k[0]), k[1])):
        group = groups[(controller, size)]
        ran = [j for j in group if j["ok"]]
        done = [j for j in ran if j["metrics"]["completed"]]
        out.append(
            SizeSummary(
                controller=controller,
                size=size,
                seeds=[j["seed"] for j in group],
                jobs=len(group),
                failed_jobs=len(group) - len(ran),
                completed=len(done),
                completion_rate=len(done) / len(group),
                lateral_error_mean_m=stats(j["metrics"]["lateral_error_mean_m"] for j in done),
                lateral_error_max_m=stats(j["metrics"]["lateral_error_max_m"] for j in done),
                heading_error_mean_rad=stats(j["metrics"]["heading_error_mean_rad"] for j in done),
                progress=stats(j["metrics"]["progress"] for j in ran),
                augmented_count=stats(j["augmented_count"] for j in ran),
                raw_count=stats(j["raw_count"] for j in ran),
                train_s=stats(j["train_s"] for j in ran),
            )
        )
    return out


@dataclass(frozen=True)
class DataStudyResult:
    """What :func:`study_data` found: the summary per (controller, size), the LMPC level, every job."""

    config: DataStudyConfig
    parallel: dict[str, Any]
    versions: dict[str, str]
    wall_s: float
    baseline: LapMetrics
    summary: list[SizeSummary]
    jobs: list[dict[str, Any]]

    def to_json(self) -> dict[str, Any]:
        out = {
            "study": "data",
            "config": settings_json(self.config, self.config.car_config),
            "track": self.config.track,
            "sizes": list(self.config.sizes),
            "seeds": list(self.config.seeds),
            "controllers": list(self.config.controllers),
            "parallel": self.parallel,
            "versions": self.versions,
            "wall_s": self.wall_s,
            "baseline": {"controller": "lmpc", "metrics": self.baseline.to_json()},
            "summary": self.summary,
            "jobs": self.jobs,
        }
        return json_object(out)

    def series(self) -> list[VolumeSeries]:
        """The summary as one plot series per controller (see :mod:`rkmpc.analysis.study_plots`)."""
        out = []
        for name in dict.fromkeys(s.controller for s in self.summary):
            rows = sorted((s for s in self.summary if s.controller == name), key=lambda s: s.size)
            samples = [
                float(s.size if s.augmented_count.mean is None else s.augmented_count.mean) for s in rows
            ]
            lateral = [s.lateral_error_mean_m for s in rows]
            out.append(VolumeSeries(name, samples, lateral, [s.completion_rate for s in rows]))
        return out

    def to_markdown(self) -> str:
        """One row per (controller, size); lateral errors ``mean ± std [min, max]`` over completed laps."""
        head = [
            "controller",
            "target samples",
            "augmented",
            "raw",
            "completed",
            "lat mean (m)",
            "lat max (m)",
        ]
        head += ["progress", "train (s)"]
        base = self.baseline
        intro = (
            f"Track: {self.config.track}, seeds: {', '.join(str(s) for s in self.config.seeds)}. "
            "Samples are local-frame transitions after augmentation (M = N x N_p); raw: transitions recorded."
            f" LMPC on the same track: lateral error {fmt(base.lateral_error_mean_m)} m"
            f" (max {fmt(base.lateral_error_max_m, '.3f')} m), needs no training data."
        )
        rows = []
        for s in self.summary:
            failed = f" ({s.failed_jobs} failed)" if s.failed_jobs else ""
            rows.append(
                [
                    s.controller,
                    str(s.size),
                    fmt(s.augmented_count.mean, ".0f"),
                    fmt(s.raw_count.mean, ".0f"),
                    f"{s.completed}/{s.jobs}{failed}",
                    fmt_stats(s.lateral_error_mean_m),
                    fmt_stats(s.lateral_error_max_m),
                    fmt(s.progress.mean, ".0%"),
                    fmt(s.train_s.mean, ".1f"),
                ]
            )
        text = intro + "\n\n" + markdown(head, rows)
        failed_jobs = [j for j in self.jobs if not j["ok"]]
        if failed_jobs:
            lines = ["", "Failed jobs:", ""]
            for j in failed_jobs:
                msg = str(j["error"]).splitlines()[0][:120] if j["error"] else ""
                lines.append(f"- {j['controller']} {j['size']} seed {j['seed']}: {msg}")
            text += "\n".join(lines) + "\n"
        return text


def study_data(
    config: DataStudyConfig | None = None,
    *,
    n_jobs: int = 1,
    backend: str = "loky",
    address: str | None = None,
    progress: Callable[[JobOutcome, int, int], None] | None = None,
) -> DataStudyResult:
    """RKMPC and KMPC as the number of training samples grows.

    One job per (controller, size, seed): ``L`` LMPC laps of the track (the fewest, at least
    ``min_laps``, whose window origins reach ``round(size / n_points) / rkmpc_max_ratio``) for
    track recipes, random excitation sized the same way with ``kmpc_max_ratio`` for excitation
    recipes. The conversion ratio is then set so that the augmentation draws
    ``round(size / n_points)`` windows: ``augmented_count`` is within ``n_points / 2`` of ``size``
    (``target_met`` records it). The model is the recipe's default (100 epochs, or ``epochs``) and
    the controller drives one lap.

    Parameters
    ----------
    config : DataStudyConfig, optional
        Track, sizes, seeds, controllers, augmentation and training settings.
    n_jobs, backend, address
        Where the jobs run: :func:`rkmpc.experiments.parallel.run_jobs`.
    progress : callable, optional
        ``progress(outcome, done, total)`` as each job finishes
        (``outcome.name`` is ``"<controller> <size> seed <seed>"``).
    """
    cfg = config if config is not None else DataStudyConfig()
    if not isinstance(cfg, DataStudyConfig):
        raise ParameterError("study_data: config must be a DataStudyConfig")
    check_parallel(n_jobs, backend)
    keys = [(c, size, seed) for c in cfg.controllers for size in cfg.sizes for seed in cfg.seeds]
    jobs = [Job(f"{c} {size} seed {seed}", data_job, (cfg, c, size, seed)) for c, size, seed in keys]
    t0 = time.perf_counter()
    outcomes = run_jobs(
        jobs, n_jobs=n_jobs, backend=backend, address=address, on_error="record", progress=progress
    )
    wall = time.perf_counter() - t0
    scenario = cfg.scenario()
    _, baseline = run_controller(scenario, RunSpec("lmpc"))
    records = []
    for (c, size, seed), out in zip(keys, outcomes, strict=True):
        rec = {"controller": c, "size": size, "seed": seed, "metrics": {}, **(out.value if out.ok else {})}
        rec.update({"ok": out.ok, "error": out.error, "traceback": out.traceback, "seconds": out.seconds})
        records.append(rec)
    return DataStudyResult(
        config=cfg,
        parallel={"n_jobs": n_jobs, "backend": backend, "address": address},
        versions=study_versions(),
        wall_s=wall,
        baseline=baseline,
        summary=summarise_sizes(records),
        jobs=records,
    )
