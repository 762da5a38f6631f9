"""RKMPC and KMPC as the training data grow: :class:`DataStudy` (the paper's data-volume figure).

Sec. V of the paper: "RKMPC uses about 8000 data points while KMPC needs 50000
or more". One parallel job per (controller, size, seed) collects data as its
recipe says (LMPC laps of the track, or random excitation of the car), trains
on about ``size`` local-frame samples and drives one lap.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.analysis.statistics import Stats, stats
from rkmpc.analysis.study_plots import VolumeSeries
from rkmpc.analysis.tables import fmt, fmt_stats, markdown
from rkmpc.experiments.parallel import Job, JobOutcome
from rkmpc.experiments.runs import run_controller
from rkmpc.experiments.studies.common import json_object
from rkmpc.experiments.studies.data_job import DEFAULT_SIZES, DataRun, DataStudyConfig, data_job
from rkmpc.experiments.study import ConfigJournal, Say, StudyRun
from rkmpc.sim.run import RunSpec

__all__ = ["DEFAULT_SIZES", "DataJob", "DataStudy", "DataStudyConfig", "DataStudyResult"]


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


@dataclass(frozen=True, kw_only=True)
class DataJob:
    """One (controller, size, seed) job: its outcome and, when it ran, what it made."""

    controller: str
    size: int
    seed: int
    ok: bool
    error: str | None
    traceback: str | None
    seconds: float
    run: DataRun | None

    def to_json(self) -> dict[str, Any]:
        run = {} if self.run is None else self.run.to_json()
        return {
            **run,
            "controller": self.controller,
            "size": self.size,
            "seed": self.seed,
            "ok": self.ok,
            "error": self.error,
            "traceback": self.traceback,
            "seconds": self.seconds,
        }


def summarise_sizes(jobs: Sequence[DataJob]) -> list[SizeSummary]:
    """Per (controller, size) summaries of data-study jobs, by controller (first seen) and size."""
    groups: dict[tuple[str, int], list[DataJob]] = {}
    for job in jobs:
        groups.setdefault((job.controller, job.size), []).append(job)
    order = list(dict.fromkeys(job.controller for job in jobs))
    out = []
    for controller, size in sorted(groups, key=lambda k: (order.index(k[0]), k[1])):
        group = groups[(controller, size)]
        ran = [j.run for j in group if j.run is not None]
        done = [r for r in ran if r.metrics.completed]
        out.append(
            SizeSummary(
                controller=controller,
                size=size,
                seeds=[j.seed for j in group],
                jobs=len(group),
                failed_jobs=len(group) - len(ran),
                completed=len(done),
                completion_rate=len(done) / len(group),
                lateral_error_mean_m=stats(r.metrics.lateral_error_mean_m for r in done),
                lateral_error_max_m=stats(r.metrics.lateral_error_max_m for r in done),
                heading_error_mean_rad=stats(r.metrics.heading_error_mean_rad for r in done),
                progress=stats(r.metrics.progress for r in ran),
                augmented_count=stats(r.augmented_count for r in ran),
                raw_count=stats(r.raw_count for r in ran),
                train_s=stats(r.train_s for r in ran),
            )
        )
    return out


@dataclass(frozen=True)
class DataStudyResult:
    """What :class:`DataStudy` found: the summary per (controller, size), the LMPC level, every job."""

    config: DataStudyConfig
    run: StudyRun
    baseline: LapMetrics
    summary: list[SizeSummary]
    jobs: list[DataJob]

    def to_json(self) -> dict[str, Any]:
        out = {
            "study": "data",
            "config": self.config.to_json(),
            "track": self.config.track,
            "sizes": list(self.config.sizes),
            "seeds": list(self.config.seeds),
            "controllers": list(self.config.controllers),
            **self.run.to_json(),
            "baseline": {"controller": "lmpc", "metrics": self.baseline.to_json()},
            "summary": self.summary,
            "jobs": [job.to_json() for job in self.jobs],
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
        failed_jobs = [j for j in self.jobs if not j.ok]
        if failed_jobs:
            lines = ["", "Failed jobs:", ""]
            for j in failed_jobs:
                msg = str(j.error).splitlines()[0][:120] if j.error else ""
                lines.append(f"- {j.controller} {j.size} seed {j.seed}: {msg}")
            text += "\n".join(lines) + "\n"
        return text

    def figure(self) -> Any:
        """Lateral error and completion against the training samples, per controller."""
        from rkmpc.analysis.study_plots import plot_data_study

        title = f"training data volume, {self.config.track}"
        return plot_data_study(self.series(), self.baseline.lateral_error_mean_m, title)


@dataclass(frozen=True)
class DataStudy(ConfigJournal):
    """RKMPC and KMPC as the number of training samples grows (``rkmpc study data``).

    One job per (controller, size, seed): ``L`` LMPC laps of the track (the fewest, at least
    ``min_laps``, whose window origins reach ``round(size / n_points) / rkmpc_max_ratio``) for
    track recipes, random excitation sized the same way with ``kmpc_max_ratio`` for excitation
    recipes. The conversion ratio is then set so that the augmentation draws
    ``round(size / n_points)`` windows: ``augmented_count`` is within ``n_points / 2`` of ``size``
    (``target_met`` records it). The model is the recipe's default (100 epochs, or the car's) and
    the controller drives one lap.
    """

    config: DataStudyConfig
    name: ClassVar[str] = "data"
    run_type: ClassVar[type[DataRun]] = DataRun

    def keys(self) -> list[tuple[str, int, int]]:
        cfg = self.config
        return [(c, size, seed) for c in cfg.controllers for size in cfg.sizes for seed in cfg.seeds]

    def prepare(self, say: Say) -> None:
        """Nothing shared: every job makes its own data."""

    def jobs(self) -> list[Job]:
        return [
            Job(f"{c} {size} seed {seed}", data_job, (self.config, c, size, seed))
            for c, size, seed in self.keys()
        ]

    def result(self, outcomes: list[JobOutcome], run: StudyRun) -> DataStudyResult:
        jobs = [
            DataJob(
                controller=c,
                size=size,
                seed=seed,
                ok=out.ok,
                error=out.error,
                traceback=out.traceback,
                seconds=out.seconds,
                run=out.value if out.ok else None,
            )
            for (c, size, seed), out in zip(self.keys(), outcomes, strict=True)
        ]
        _, baseline = run_controller(self.config.scenario(), RunSpec("lmpc"))
        return DataStudyResult(
            config=self.config, run=run, baseline=baseline, summary=summarise_sizes(jobs), jobs=jobs
        )
