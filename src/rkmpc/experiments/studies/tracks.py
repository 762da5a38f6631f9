"""Every controller on many tracks: :class:`TracksStudy`.

The comparison of :func:`rkmpc.experiments.compare.compare` on a list of tracks and seeds, one
job per (track, seed) (:func:`rkmpc.experiments.study.run_study`), summarised per controller over
all of them (:func:`rkmpc.analysis.statistics.summarise_runs`): mean and spread of every lap metric
and of its change in % against a baseline controller (``lmpc``) on the same track and seed. A job
that raises is recorded (its message in the result) and the others go on.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

from rkmpc.analysis.statistics import ControllerSummary, RunGroup, RunRow, summarise_runs
from rkmpc.config.car import CarConfig
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.compare import LEARNED_CONTROLLERS, CompareConfig, compare
from rkmpc.experiments.journal import canonical_json
from rkmpc.experiments.models import excitation_model
from rkmpc.experiments.parallel import Job, JobOutcome
from rkmpc.experiments.results import TrackResult
from rkmpc.experiments.studies.common import (
    MultiTrackConfig,
    int_tuple,
    json_object,
    track_label,
)
from rkmpc.experiments.studies.tables import runs_table, summary_table
from rkmpc.experiments.study import Say, StudyRun
from rkmpc.learning.recipes import DataSource, recipe_for

__all__ = [
    "ComparisonJournal",
    "TrackJob",
    "TracksStudy",
    "TracksStudyConfig",
    "TracksStudyResult",
    "job_records",
]


@dataclass(frozen=True, kw_only=True)
class TracksStudyConfig(MultiTrackConfig):
    """Settings of the tracks study: :class:`MultiTrackConfig`'s (the car's training seed is
    replaced by each job's seed; ``controllers`` each job drives, the learned ones by default) and:

    Parameters
    ----------
    seeds : sequence of int
        Seeds (>= 0); one job per (track, seed). The seed sets the data collection, training and runs.
    baseline : str or None
        Controller the changes in % are measured against (must be in ``controllers``); None for none.
    fault : str or None
        A fault every controller also drives with (:data:`rkmpc.sim.faults.FAULTS`).
    model_files : tuple of (str, str)
        ``(controller, path)`` models to use instead of learning.
    """

    controllers: Sequence[str] = LEARNED_CONTROLLERS
    seeds: Sequence[int] = (0,)
    baseline: str | None = "lmpc"
    fault: str | None = None
    model_files: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "seeds", int_tuple("TracksStudyConfig.seeds", self.seeds, minimum=0))
        if self.baseline is not None and self.baseline not in self.controllers:
            raise ParameterError(
                f"TracksStudyConfig.baseline {self.baseline!r} is not among the controllers "
                f"{list(self.controllers)}; add it or set baseline=None"
            )
        self.job_config(self.tracks[0], self.seeds[0])  # refuses what a comparison would refuse

    def job_config(self, track: str, seed: int, car: CarConfig | None = None) -> CompareConfig:
        """The comparison of one (track, seed) job (of ``car`` instead of the study's, when given)."""
        return CompareConfig(
            track=track,
            car=(self.car if car is None else car).with_training(seed=seed),
            controllers=tuple(self.controllers),
            scale=self.scale,
            fault=self.fault,
            model_files=self.model_files,
            cache_dir=self.cache_dir,
            use_cache=self.use_cache,
        )

    def to_json(self) -> dict[str, Any]:
        """The settings, the car written out whole."""
        return json_object(
            {
                "tracks": list(self.tracks),
                "controllers": list(self.controllers),
                "seeds": list(self.seeds),
                "scale": self.scale,
                "baseline": self.baseline,
                "fault": self.fault,
                "model_files": [list(pair) for pair in self.model_files],
                "cache_dir": self.cache_dir,
                "use_cache": self.use_cache,
                "car": self.car.to_json(),
            }
        )


@dataclass(frozen=True, kw_only=True)
class TrackJob:
    """One (track, seed) job of a study: its outcome and, when it ran, its comparison."""

    spec: str
    seed: int
    ok: bool
    error: str | None
    traceback: str | None
    seconds: float
    result: TrackResult | None

    @property
    def track(self) -> str:
        return self.result.track if self.result is not None else track_label(self.spec)

    def group(self) -> RunGroup:
        metrics = {} if self.result is None else self.result.metrics()
        return RunGroup(track=self.track, seed=self.seed, ok=self.ok, error=self.error, metrics=metrics)

    def to_json(self) -> dict[str, Any]:
        res = self.result.to_json() if self.result is not None else {}
        return {
            "track": self.track,
            "spec": self.spec,
            "seed": self.seed,
            "ok": self.ok,
            "error": self.error,
            "traceback": self.traceback,
            "seconds": self.seconds,
            "controllers": res["controllers"] if res else {},
            "training": res["training"] if res else None,
            "config": res["config"] if res else None,
        }


def job_records(configs: Sequence[CompareConfig], outcomes: Sequence[JobOutcome]) -> list[TrackJob]:
    """One :class:`TrackJob` per comparison job and its outcome."""
    return [
        TrackJob(
            spec=cfg.track,
            seed=cfg.seed,
            ok=out.ok,
            error=out.error,
            traceback=out.traceback,
            seconds=out.seconds,
            result=out.value if out.ok else None,
        )
        for cfg, out in zip(configs, outcomes, strict=True)
    ]


def train_shared_models(configs: Sequence[CompareConfig], say: Say) -> None:
    """Learn the track-independent models of ``configs`` (one per seed and car) once, into their cache."""
    for job in configs:
        plan = job.plan()
        cache = plan.cache()
        if cache is None:
            return
        for name in plan.controllers:
            recipe = recipe_for(name)
            if recipe is None or recipe.data is not DataSource.EXCITATION or name in plan.model_files:
                continue
            say(f"{name} model, seed {plan.seed}: {plan.excitation_samples} samples (cached)")
            excitation_model(
                job.scenario(),
                recipe,
                samples=plan.excitation_samples,
                seed=plan.seed,
                cache=cache,
                epochs=plan.epochs,
            )


@dataclass(frozen=True)
class TracksStudyResult:
    """What the tracks study found: the summary per controller, one row per run, every job."""

    config: TracksStudyConfig
    run: StudyRun
    summary: dict[str, ControllerSummary]
    rows: list[RunRow]
    jobs: list[TrackJob]

    def to_json(self) -> dict[str, Any]:
        out = {
            "study": "tracks",
            "config": self.config.to_json(),
            **self.run.to_json(),
            "summary": {name: s.to_json() for name, s in self.summary.items()},
            "rows": [row.to_json() for row in self.rows],
            "jobs": [job.to_json() for job in self.jobs],
        }
        return json_object(out)

    def to_markdown(self) -> str:
        """The summary table (``mean ± std [min, max]`` over completed laps), then one row per run."""
        cfg = self.config
        intro = f"Tracks: {len(cfg.tracks)}, seeds: {', '.join(str(s) for s in cfg.seeds)}.\n\n"
        summary = summary_table(self.summary, cfg.controllers, cfg.baseline)
        return intro + summary + "\n" + runs_table(self.rows, cfg.baseline)

    def figure(self) -> None:
        """The tracks study has no figure (its tables say it)."""
        return None


class ComparisonJournal:
    """The journal of a study whose jobs are comparisons (:func:`compare`), each one keyed by its config.

    A job's key is its whole comparison's settings, so the journal needs no settings of its own; a
    job's value is its :class:`TrackResult`, stored as JSON.
    """

    def journal_settings(self) -> dict[str, Any]:
        return {}  # everything else is in each job's key (its whole comparison)

    def encode(self, value: TrackResult) -> dict[str, Any]:
        return value.to_json()

    def decode(self, data: Any) -> TrackResult:
        return TrackResult.from_json(data)


@dataclass(frozen=True)
class TracksStudy(ComparisonJournal):
    """Every controller on every track and seed (``rkmpc study tracks``)."""

    config: TracksStudyConfig
    name: ClassVar[str] = "tracks"

    def configs(self) -> list[CompareConfig]:
        return [self.config.job_config(t, s) for t in self.config.tracks for s in self.config.seeds]

    def prepare(self, say: Say) -> None:
        train_shared_models(
            [self.config.job_config(self.config.tracks[0], s) for s in self.config.seeds], say
        )

    def jobs(self) -> list[Job]:
        return [
            Job(f"{cfg.track} seed {cfg.seed}", compare, (cfg,), key=canonical_json(cfg.to_json()))
            for cfg in self.configs()
        ]

    def result(self, outcomes: list[JobOutcome], run: StudyRun) -> TracksStudyResult:
        jobs = job_records(self.configs(), outcomes)
        summary, rows = summarise_runs(
            [j.group() for j in jobs], self.config.controllers, self.config.baseline
        )
        return TracksStudyResult(self.config, run, summary, rows, jobs)
