"""Every controller on cars it was not built for: :class:`CarsStudy`.

For each car of the zoo (:mod:`rkmpc.vehicle.zoo`), track and seed, one job
runs the comparison of :func:`rkmpc.experiments.compare.compare` on that car:
two LMPC laps are recorded on THAT car, the learned
controllers are trained or identified from them (KMPC from random excitation
of that car), and every controller, built with the nominal parameters, drives
it. Jobs run in parallel (:func:`rkmpc.experiments.study.run_study`); each
car is summarised like a tracks study, and :meth:`CarsStudyResult.targets`
checks the targets of RKMPC against the LMPC on every (car, track, seed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

from rkmpc.analysis.statistics import ControllerSummary, Stats, summarise_runs
from rkmpc.analysis.tables import fmt, markdown
from rkmpc.config.car import CarConfig
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.compare import CompareConfig, compare
from rkmpc.experiments.journal import canonical_json
from rkmpc.experiments.parallel import Job, JobOutcome
from rkmpc.experiments.results import NOT_LEARNED
from rkmpc.experiments.studies.common import json_object, str_tuple
from rkmpc.experiments.studies.tables import summary_table
from rkmpc.experiments.studies.tracks import (
    ComparisonJournal,
    TrackJob,
    TracksStudyConfig,
    job_records,
    train_shared_models,
)
from rkmpc.experiments.study import Say, StudyRun
from rkmpc.vehicle.zoo import get_car

__all__ = [
    "CARS_CONTROLLERS",
    "DEFAULT_CARS",
    "CarJob",
    "CarTargets",
    "CarsStudy",
    "CarsStudyConfig",
    "CarsStudyResult",
]

#: Cars of ``rkmpc study cars`` by default: every named variant but the nominal one.
DEFAULT_CARS = ("gym", "overshoot", "cheap-servo", "low-grip", "heavy-long", "light-short", "laggy-odom")

#: Controllers of the cars study, in table order.
CARS_CONTROLLERS = ("pp", "lmpc", "lmpc-id", "nmpc-dynamic", "kmpc", "rkmpc-paper", "rkmpc")


@dataclass(frozen=True)
class CarsStudyConfig:
    """Settings of the cars study.

    Parameters
    ----------
    cars : sequence of str
        Zoo variants (:func:`rkmpc.vehicle.zoo.get_car` names, ``"random-<seed>"`` included).
    tracks : TracksStudyConfig
        Tracks, controllers, seeds and comparison settings, applied to every car (its car must be
        a 1:10 car on the ``f1tenth`` plant, whose nominal model the controllers keep).
    """

    cars: Sequence[str]
    tracks: TracksStudyConfig

    def __post_init__(self) -> None:
        cars = str_tuple("CarsStudyConfig.cars", self.cars)
        object.__setattr__(self, "cars", cars)
        if not isinstance(self.tracks, TracksStudyConfig):
            raise ParameterError("CarsStudyConfig.tracks must be a TracksStudyConfig")
        for name in cars:
            self.car(name)

    def car(self, name: str) -> CarConfig:
        """The study's car driving the zoo car ``name``."""
        try:
            return self.tracks.car.with_zoo_car(name)
        except ParameterError as exc:
            raise ParameterError(f"CarsStudyConfig.cars: {exc}") from None

    def job_config(self, car: str, track: str, seed: int) -> CompareConfig:
        """The comparison of one (car, track, seed) job."""
        return self.tracks.job_config(track, seed, self.car(car))

    def to_json(self) -> dict[str, Any]:
        return {"cars": list(self.cars), **self.tracks.to_json()}


@dataclass(frozen=True)
class CarJob:
    """One (car, track, seed) job: the car and the job's outcome."""

    car: str
    job: TrackJob

    def to_json(self) -> dict[str, Any]:
        return {"car": self.car, **self.job.to_json()}


#: Targets of RKMPC against the LMPC: largest allowed change (%) of each metric.
TARGET_LIMITS: Mapping[str, float] = {
    "lateral_pct": -40.0,
    "heading_pct": -30.0,
    "lateral_max_pct": 0.0,
    "command_rate_pct": 0.0,
}


@dataclass(frozen=True)
class CarTargets:
    """RKMPC against the LMPC on one (car, track, seed), and whether each target holds.

    Targets: lateral error <= -40 %, heading error <= -30 %, maximum lateral
    error no larger than the LMPC's, commanded-steering rate no larger than
    the LMPC's; all on completed laps of both. ``not_learned``: RKMPC did not drive, its data or
    its model were refused (:data:`~rkmpc.experiments.results.NOT_LEARNED`).
    """

    car: str
    track: str
    seed: int
    lateral_pct: float | None
    heading_pct: float | None
    lateral_max_pct: float | None
    command_rate_pct: float | None
    both_completed: bool
    not_learned: bool = False

    def missed(self) -> list[str]:
        """Names of the targets not met (all of them when a lap did not complete)."""
        if not self.both_completed:
            return list(TARGET_LIMITS)
        return [k for k, limit in TARGET_LIMITS.items() if (v := getattr(self, k)) is None or v > limit]

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "missed": self.missed()}


@dataclass(frozen=True)
class CarsStudyResult:
    """What :class:`CarsStudy` found: a summary per car and controller, every job."""

    config: CarsStudyConfig
    run: StudyRun
    summary: dict[str, dict[str, ControllerSummary]]
    jobs: list[CarJob]

    def targets(self, learned: str = "rkmpc", baseline: str = "lmpc") -> list[CarTargets]:
        """``learned`` against ``baseline`` on every job where both ran."""
        out = []
        for cj in self.jobs:
            result = cj.job.result
            if result is None or learned not in result.controllers or baseline not in result.controllers:
                continue
            a = result.controllers[learned].metrics
            b = result.controllers[baseline].metrics
            both = bool(a.completed and b.completed)

            def pct(key: str, a: Any = a, b: Any = b) -> float | None:
                x, y = a[key], b[key]
                return None if x is None or y is None or y == 0 else 100.0 * (x - y) / y

            out.append(
                CarTargets(
                    car=cj.car,
                    track=result.track,
                    seed=cj.job.seed,
                    lateral_pct=pct("lateral_error_mean_m"),
                    heading_pct=pct("heading_error_mean_rad"),
                    lateral_max_pct=pct("lateral_error_max_m"),
                    command_rate_pct=pct("command_rate_mean_rad_s"),
                    both_completed=both,
                    not_learned=result.controllers[learned].outcome == NOT_LEARNED,
                )
            )
        return out

    def plot_data(
        self,
    ) -> tuple[list[str], list[str], dict[str, dict[str, Stats]], dict[str, dict[str, float]]]:
        """Arguments of :func:`rkmpc.analysis.study_plots.plot_cars_study`: cars, controllers,
        lateral-error statistics and completion rates by car and controller."""
        controllers = list(self.config.tracks.controllers)
        lateral = {
            car: {name: per[name].metrics["lateral_error_mean_m"] for name in controllers}
            for car, per in self.summary.items()
        }
        rates = {
            car: {name: per[name].completed / max(per[name].jobs, 1) for name in controllers}
            for car, per in self.summary.items()
        }
        return list(self.config.cars), controllers, lateral, rates

    def to_json(self) -> dict[str, Any]:
        out = {
            "study": "cars",
            "cars": list(self.config.cars),
            "cars_described": {name: get_car(name).describe() for name in self.config.cars},
            "tracks": list(self.config.tracks.tracks),
            "seeds": list(self.config.tracks.seeds),
            "controllers": list(self.config.tracks.controllers),
            "baseline": self.config.tracks.baseline,
            "config": self.config.to_json(),
            **self.run.to_json(),
            "summary": {
                car: {name: s.to_json() for name, s in per.items()} for car, per in self.summary.items()
            },
            "targets": [t.to_json() for t in self.targets()],
            "jobs": [job.to_json() for job in self.jobs],
        }
        return json_object(out)

    def to_markdown(self) -> str:
        """One summary table per car, then the targets of RKMPC against the LMPC on every run."""
        parts = [
            f"Cars: {', '.join(self.config.cars)}; tracks: {len(self.config.tracks.tracks)}; "
            f"seeds: {', '.join(str(s) for s in self.config.tracks.seeds)}.",
            "",
        ]
        for car in self.config.cars:
            parts += [
                f"### {car}: {get_car(car).summary}",
                "",
                summary_table(self.summary[car], self.config.tracks.controllers, self.config.tracks.baseline),
                "",
            ]
        parts += ["### RKMPC against the LMPC, every run", "", targets_table(self.targets())]
        return "\n".join(parts)

    def figure(self) -> Any:
        """Lateral error and completion per car and controller."""
        from rkmpc.analysis.study_plots import plot_cars_study

        return plot_cars_study(*self.plot_data())


@dataclass(frozen=True)
class CarsStudy(ComparisonJournal):
    """Every controller on cars it was not built for (``rkmpc study cars``)."""

    config: CarsStudyConfig
    name: ClassVar[str] = "cars"

    def keys(self) -> list[tuple[str, str, int]]:
        tracks = self.config.tracks
        return [
            (car, spec, seed) for car in self.config.cars for spec in tracks.tracks for seed in tracks.seeds
        ]

    def prepare(self, say: Say) -> None:
        tracks = self.config.tracks
        for car in self.config.cars:
            train_shared_models([self.config.job_config(car, tracks.tracks[0], s) for s in tracks.seeds], say)

    def jobs(self) -> list[Job]:
        return [
            Job(f"{car} {spec} seed {seed}", compare, (cfg,), key=canonical_json(cfg.to_json()))
            for (car, spec, seed) in self.keys()
            for cfg in (self.config.job_config(car, spec, seed),)
        ]

    def result(self, outcomes: list[JobOutcome], run: StudyRun) -> CarsStudyResult:
        keys = self.keys()
        configs = [self.config.job_config(*key) for key in keys]
        records = [
            CarJob(car=key[0], job=job) for key, job in zip(keys, job_records(configs, outcomes), strict=True)
        ]
        tracks = self.config.tracks
        summary = {}
        for car in self.config.cars:
            groups = [cj.job.group() for cj in records if cj.car == car]
            summary[car], _ = summarise_runs(groups, tracks.controllers, tracks.baseline)
        return CarsStudyResult(config=self.config, run=run, summary=summary, jobs=records)


def targets_table(targets: Sequence[CarTargets]) -> str:
    """Markdown: one row per (car, track, seed) with the four changes and the targets missed."""
    head = [
        "car",
        "track",
        "seed",
        "lat vs lmpc",
        "head vs lmpc",
        "lat max vs lmpc",
        "cmd rate vs lmpc",
        "missed",
    ]
    rows = []
    for t in targets:
        cells = [t.car, t.track, str(t.seed)]
        cells += [
            fmt(v, "+.0f") + ("%" if v is not None else "")
            for v in (t.lateral_pct, t.heading_pct, t.lateral_max_pct, t.command_rate_pct)
        ]
        missed = t.missed()
        if not missed:
            cells.append("-")
        elif t.not_learned:
            cells.append("not learned")
        else:
            cells.append("not completed" if not t.both_completed else ", ".join(missed))
        rows.append(cells)
    met = sum(1 for t in targets if not t.missed())
    return markdown(head, rows) + f"\nAll four targets met on {met} of {len(targets)} runs.\n"
