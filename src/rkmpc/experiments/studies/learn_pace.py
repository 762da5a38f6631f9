"""Learning to race: :class:`LearnPaceStudy` (issue 14, item 4).

Iteration 0: the LMPC drives ``laps`` laps at the ladder's first pace (a safe pace: the preset's);
they start the pool of data. Iteration ``i >= 1``: the learned controller (``rkmpc``) is trained
on everything in the pool, then drives ``laps`` laps at the ladder's pace ``i``, recording them;
when they are clean (:mod:`.pace_rules`) they join the pool and the next iteration goes a step
faster. The loop stops at the first unclean laps, at the top of the ladder or after
``max_iterations``. For comparison, the LMPC also drives one lap at every pace (it is not trained).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

from rkmpc.analysis.metrics import LapMetrics, lap_metrics
from rkmpc.analysis.tables import fmt, markdown
from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.core.errors import NotLearnedError, ParameterError
from rkmpc.core.validation import is_integer
from rkmpc.experiments.models import make_model
from rkmpc.experiments.parallel import Job, JobOutcome
from rkmpc.experiments.studies.common import check_car, check_scale, check_track, json_object, track_label
from rkmpc.experiments.studies.pace_job import PaceStudyConfig
from rkmpc.experiments.studies.pace_rules import Pace, car_ladder, check_ladder, pace_label, run_verdict
from rkmpc.experiments.study import ConfigJournal, Say, StudyRun
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.recipes import recipe_for, track_learners
from rkmpc.sim.closed_loop import SimResult
from rkmpc.sim.collect import record
from rkmpc.sim.run import RunSpec

__all__ = [
    "LearnIteration",
    "LearnPaceConfig",
    "LearnPaceResult",
    "LearnPaceRun",
    "LearnPaceStudy",
    "learn_pace_job",
]


@dataclass(frozen=True, kw_only=True)
class LearnPaceConfig:
    """Settings of learning to race.

    Parameters
    ----------
    track : str
        Built-in name or centre-line CSV path.
    car : CarConfig
        The car; its training settings give the seed, the laps recorded at every iteration (all
        must be clean to go on) and the epochs.
    controller : str
        The learned controller (a recipe learning from laps of the track,
        :func:`~rkmpc.learning.recipes.track_learners`: ``lmpc-id``, ``nmpc-id``, ``rkmpc-paper``,
        ``rkmpc``).
    paces : sequence of (float, float) or None
        The ladder; its first pace is the safe one the LMPC starts at. None: the car's (from its
        own pace: :func:`~rkmpc.experiments.studies.pace_rules.car_ladder`).
    scale : float or None
        Track scale (default: the car's).
    max_iterations : int or None
        Iterations after the LMPC's (None: up the whole ladder).
    cache_dir : str or None
        Model cache folder (default when None).
    use_cache : bool
        Read and write trained models in the cache.
    """

    track: str = "builtin"
    car: CarConfig = field(default_factory=lambda: load_preset("f1tenth"))
    controller: str = "rkmpc"
    paces: Sequence[Pace] | None = None
    scale: float | None = None
    max_iterations: int | None = None
    cache_dir: str | None = None
    use_cache: bool = True

    def __post_init__(self) -> None:
        check_track(str(self.track))
        object.__setattr__(self, "track", str(self.track))
        learners = track_learners()
        if self.controller not in learners:
            raise ParameterError(
                f"LearnPaceConfig.controller must learn from laps of the track "
                f"({', '.join(learners)}), got {self.controller!r}"
            )
        check_scale("LearnPaceConfig.scale", self.scale)
        car = check_car("LearnPaceConfig.car", self.car)
        paces = (
            check_ladder("LearnPaceConfig.paces", self.paces) if self.paces is not None else car_ladder(car)
        )
        if len(paces) < 2:
            raise ParameterError("LearnPaceConfig.paces: need a safe pace and at least one faster")
        object.__setattr__(self, "paces", paces)
        if self.max_iterations is not None and not is_integer(self.max_iterations, 1):
            raise ParameterError(
                f"LearnPaceConfig.max_iterations must be None or an integer >= 1, got {self.max_iterations!r}"
            )

    def study(self) -> PaceStudyConfig:
        """The same settings as a pace-study configuration (scenarios, training)."""
        return PaceStudyConfig(
            tracks=(self.track,),
            car=self.car,
            controllers=(self.controller,),
            paces=self.paces,
            scale=self.scale,
            cache_dir=self.cache_dir,
            use_cache=self.use_cache,
        )

    def to_json(self) -> dict[str, Any]:
        """The settings, the car written out whole."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "car"}
        return {**json_object(out), "car": self.car.to_json()}


@dataclass(frozen=True, kw_only=True)
class LearnIteration:
    """One iteration: who drove at which pace, the verdict, the laps, what the model learned from.

    ``metrics`` are over the ``laps`` recorded laps (lap time and errors of the first);
    ``lmpc_metrics`` the LMPC's single lap at the same pace; ``trained_on`` the pool the model
    learned from (recorder, pace, samples of each part; None for the LMPC's iteration);
    ``pool_samples`` its size.
    """

    iteration: int
    controller: str
    pace: Pace
    clean: bool
    reason: str | None
    outcome: str
    metrics: LapMetrics
    lmpc_clean: bool
    lmpc_metrics: LapMetrics
    trained_on: list[dict[str, Any]] | None
    pool_samples: int
    recorded_samples: int
    model: dict[str, Any] | None

    def to_json(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in fields(self) if "metrics" not in f.name}
        return {
            **json_object(out),
            "metrics": self.metrics.to_json(),
            "lmpc_metrics": self.lmpc_metrics.to_json(),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> LearnIteration:
        values = {f.name: data[f.name] for f in fields(cls) if "metrics" not in f.name}
        lateral, speed = values["pace"]
        values["pace"] = (float(lateral), float(speed))
        return cls(
            **values,
            metrics=LapMetrics.from_json(data["metrics"]),
            lmpc_metrics=LapMetrics.from_json(data["lmpc_metrics"]),
        )


@dataclass(frozen=True, kw_only=True)
class LearnPaceRun:
    """One climb: the iterations and why it stopped."""

    iterations: list[LearnIteration]
    stopped: str

    def to_json(self) -> dict[str, Any]:
        return {"stopped": self.stopped, "iterations": [it.to_json() for it in self.iterations]}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> LearnPaceRun:
        iterations = [LearnIteration.from_json(it) for it in data["iterations"]]
        return cls(iterations=iterations, stopped=str(data["stopped"]))


@dataclass(frozen=True)
class LearnPaceResult:
    """What learning to race found: the iterations and why it stopped (or the job's error)."""

    config: LearnPaceConfig
    run: StudyRun
    iterations: list[LearnIteration]
    stopped: str

    def to_json(self) -> dict[str, Any]:
        out = {
            "study": "learn-pace",
            "config": self.config.to_json(),
            "track": track_label(self.config.track),
            "seed": self.config.car.training.seed,
            **self.run.to_json(),
            "stopped": self.stopped,
            "iterations": [it.to_json() for it in self.iterations],
        }
        return json_object(out)

    def figure(self) -> Any:
        """Lap time and lateral error of every iteration, against the LMPC's at the same pace."""
        from rkmpc.analysis.study_plots import plot_learn_pace

        its = self.iterations
        cfg = self.config
        return plot_learn_pace(
            [pace_label(it.pace) for it in its],
            [it.metrics.lap_time_s for it in its],
            [it.clean for it in its],
            [it.lmpc_metrics.lap_time_s if it.lmpc_clean else None for it in its],
            [it.metrics.lateral_error_mean_m for it in its],
            f"learning to race: {cfg.controller} on {track_label(cfg.track)}, seed {cfg.car.training.seed}",
        )

    def to_markdown(self) -> str:
        cfg = self.config
        intro = (
            f"Learning to race on {track_label(cfg.track)} (seed {cfg.car.training.seed}): {cfg.controller} "
            f"trained on every clean lap recorded so far, one pace step faster each iteration; "
            f"{cfg.car.training.data_laps} laps per iteration. Stopped: {self.stopped}.\n\n"
        )
        head = [
            "iter",
            "driver",
            "pace",
            "clean",
            "lap (s)",
            "lat (m)",
            "lat max (m)",
            "trained on",
            "recorded",
            "LMPC lap (s)",
        ]
        rows = []
        for it in self.iterations:
            m, lm = it.metrics, it.lmpc_metrics
            rows.append(
                [
                    str(it.iteration),
                    it.controller,
                    pace_label(it.pace),
                    "yes" if it.clean else f"no: {it.reason}",
                    fmt(m.lap_time_s, ".2f"),
                    fmt(m.lateral_error_mean_m, ".4f"),
                    fmt(m.lateral_error_max_m, ".3f"),
                    "-" if it.trained_on is None else str(it.pool_samples),
                    str(it.recorded_samples),
                    fmt(lm.lap_time_s, ".2f") + ("" if it.lmpc_clean else " (unclean)"),
                ]
            )
        return intro + markdown(head, rows)


def learn_pace_job(config: LearnPaceConfig) -> LearnPaceRun:
    """Learn to drive faster from one's own clean laps (see the module)."""
    study = config.study()
    recipe = recipe_for(config.controller)
    if recipe is None:  # pragma: no cover - checked by the configuration
        raise ParameterError(f"learn-pace: {config.controller!r} learns no model")
    cache = study.cache()
    seed, laps = config.car.training.seed, config.car.training.data_laps
    ladder = study.ladder
    last = len(ladder) - 1 if config.max_iterations is None else min(len(ladder) - 1, config.max_iterations)

    def lmpc_lap(pace: Pace) -> tuple[bool, LapMetrics]:
        result, _ = record(study.scenario(config.track, pace), RunSpec("lmpc", laps=1, seed=seed))
        return run_verdict(result, 1) is None, lap_metrics(result, laps=1)

    def iteration(
        i: int,
        controller: str,
        pace: Pace,
        run: tuple[SimResult, TransitionDataset],
        trained_on: list[dict[str, Any]] | None,
        pool_samples: int,
        model: dict[str, Any] | None,
    ) -> LearnIteration:
        """Iteration ``i``: the verdict on ``controller``'s ``run`` at ``pace``, and the LMPC's lap there."""
        result, data = run
        reason = run_verdict(result, laps)
        lmpc_clean, lmpc_metrics = lmpc_lap(pace)
        return LearnIteration(
            iteration=i,
            controller=controller,
            pace=pace,
            clean=reason is None,
            reason=reason,
            outcome=result.outcome,
            metrics=lap_metrics(result, laps=laps),
            lmpc_clean=lmpc_clean,
            lmpc_metrics=lmpc_metrics,
            trained_on=trained_on,
            pool_samples=pool_samples,
            recorded_samples=len(data),
            model=model,
        )

    run = record(study.scenario(config.track, ladder[0]), RunSpec("lmpc", laps=laps, seed=seed))
    pool: list[tuple[str, Pace, TransitionDataset]] = [("lmpc", ladder[0], run[1])]
    iterations = [iteration(0, "lmpc", ladder[0], run, None, 0, None)]
    reason = iterations[0].reason
    if reason is not None:
        stopped = f"the LMPC's laps at the first pace {pace_label(ladder[0])} are not clean ({reason})"
        return LearnPaceRun(iterations=iterations, stopped=stopped)
    stopped = "top of the ladder" if last == len(ladder) - 1 else f"after {last} iterations (max_iterations)"
    for i in range(1, last + 1):
        pace = ladder[i]
        scenario = study.scenario(config.track, pace)
        joined = TransitionDataset.concatenate([d for _, _, d in pool]) if len(pool) > 1 else pool[0][2]
        key = {"data_hash": joined.content_hash()}
        try:
            model, model_record = make_model(
                recipe,
                scenario,
                _given(joined),
                key,
                seed=seed,
                epochs=config.car.training.epochs,
                cache=cache,
            )
        except NotLearnedError as exc:
            stopped = f"no model at {pace_label(pace)}: {exc.reason}"
            break
        run = record(scenario, RunSpec(config.controller, laps=laps, seed=seed), model=model)
        trained_on = [{"recorder": who, "pace": list(at), "samples": len(d)} for who, at, d in pool]
        iterations.append(
            iteration(i, config.controller, pace, run, trained_on, len(joined), model_record.to_json())
        )
        reason = iterations[-1].reason
        if reason is not None:
            stopped = f"laps at {pace_label(pace)} not clean ({reason})"
            break
        pool.append((config.controller, pace, run[1]))
    return LearnPaceRun(iterations=iterations, stopped=stopped)


def _given(data: TransitionDataset) -> Callable[[], TransitionDataset]:
    return lambda: data


@dataclass(frozen=True)
class LearnPaceStudy(ConfigJournal):
    """Learning to race on one track (``rkmpc learn-pace``): one job, the whole climb."""

    config: LearnPaceConfig
    name: ClassVar[str] = "learn-pace"
    run_type: ClassVar[type[LearnPaceRun]] = LearnPaceRun

    def prepare(self, say: Say) -> None:
        """Nothing shared: the climb learns at every iteration."""

    def jobs(self) -> list[Job]:
        return [
            Job(f"{track_label(self.config.track)} {self.config.controller}", learn_pace_job, (self.config,))
        ]

    def result(self, outcomes: list[JobOutcome], run: StudyRun) -> LearnPaceResult:
        out = outcomes[0]
        if not out.ok:
            return LearnPaceResult(self.config, run, [], f"failed: {out.error}")
        climb: LearnPaceRun = out.value
        return LearnPaceResult(self.config, run, climb.iterations, climb.stopped)
