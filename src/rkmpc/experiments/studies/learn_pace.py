"""Learning to race: :func:`learn_pace` (issue 14, item 4).

Iteration 0: the LMPC drives ``laps`` laps at the ladder's first pace (a safe pace: the preset's);
they start the pool of data. Iteration ``i >= 1``: the learned controller (``rkmpc``) is trained
on everything in the pool, then drives ``laps`` laps at the ladder's pace ``i``, recording them;
when they are clean (:mod:`.pace_rules`) they join the pool and the next iteration goes a step
faster. The loop stops at the first unclean laps, at the top of the ladder or after
``max_iterations``. For comparison, the LMPC also drives one lap at every pace (it is not trained).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from rkmpc.analysis.metrics import LapMetrics, lap_metrics
from rkmpc.analysis.tables import fmt, markdown
from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer
from rkmpc.experiments.cache import ModelCache
from rkmpc.experiments.studies.common import (
    check_car_config,
    check_scale_vehicle,
    check_track,
    json_object,
    settings_json,
    study_versions,
    track_label,
)
from rkmpc.experiments.studies.pace_job import PaceStudyConfig, train_on
from rkmpc.experiments.studies.pace_rules import (
    Pace,
    car_ladder,
    check_ladder,
    pace_label,
    pace_ladder,
    run_verdict,
)
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.recipes import recipe_for
from rkmpc.sim.carfile import CarConfig
from rkmpc.sim.collect import record
from rkmpc.sim.run import RunSpec

__all__ = ["LearnIteration", "LearnPaceConfig", "LearnPaceResult", "learn_pace"]


@dataclass(frozen=True)
class LearnPaceConfig:
    """Settings of :func:`learn_pace`.

    Parameters
    ----------
    track : str
        Built-in name or centre-line CSV path.
    controller : str
        The learned controller (a recipe learning from laps of the track: ``rkmpc``,
        ``rkmpc-paper``, ``lmpc-id``).
    paces : sequence of (float, float) or None
        The ladder; its first pace is the safe one the LMPC starts at. None: the vehicle's default,
        or with ``car_config`` the car's (from its own pace:
        :func:`~rkmpc.experiments.studies.pace_rules.car_ladder`).
    seed : int
        Seed of the runs and the training.
    scale : float or None
        Track scale (default: the vehicle's).
    vehicle : str
        Vehicle preset.
    laps : int
        Laps recorded at every iteration (all must be clean to go on).
    epochs : int or None
        Training epochs (None: the recipe's default).
    max_iterations : int or None
        Iterations after the LMPC's (None: up the whole ladder).
    cache_dir : str or None
        Model cache folder (default when None).
    use_cache : bool
        Read and write trained models in the cache.
    car_config : CarConfig or None
        The car as a car file set it up, a car of the ``vehicle`` preset (as for
        :class:`~rkmpc.experiments.studies.pace_job.PaceStudyConfig`); the copy kept here takes
        the seed, laps and epochs above, and the result records it.
    """

    track: str = "builtin"
    controller: str = "rkmpc"
    paces: Sequence[Pace] | None = None
    seed: int = 0
    scale: float | None = None
    vehicle: str = "f1tenth"
    laps: int = 2
    epochs: int | None = None
    max_iterations: int | None = None
    cache_dir: str | None = None
    use_cache: bool = True
    car_config: CarConfig | None = None

    def __post_init__(self) -> None:
        check_track(str(self.track))
        object.__setattr__(self, "track", str(self.track))
        recipe = recipe_for(self.controller)
        if recipe is None or recipe.data != "track":
            raise ParameterError(
                f"LearnPaceConfig.controller must learn from laps of the track (rkmpc, rkmpc-paper, "
                f"lmpc-id), got {self.controller!r}"
            )
        check_scale_vehicle(self.scale, self.vehicle)
        car = check_car_config("LearnPaceConfig.car_config", self.car_config, self.vehicle)
        if self.paces is not None:
            paces = check_ladder("LearnPaceConfig.paces", self.paces)
        else:
            paces = pace_ladder(self.vehicle) if car is None else car_ladder(car)
        if len(paces) < 2:
            raise ParameterError("LearnPaceConfig.paces: need a safe pace and at least one faster")
        object.__setattr__(self, "paces", paces)
        for name, minimum in (("seed", 0), ("laps", 1)):
            if not is_integer(getattr(self, name), minimum):
                raise ParameterError(
                    f"LearnPaceConfig.{name} must be an integer >= {minimum}, got {getattr(self, name)!r}"
                )
        for name in ("epochs", "max_iterations"):
            value = getattr(self, name)
            if value is not None and not is_integer(value, 1):
                raise ParameterError(f"LearnPaceConfig.{name} must be None or an integer >= 1, got {value!r}")
        if car is not None:  # the copy kept is the one that runs: these training settings
            training = replace(car.training, epochs=self.epochs, seed=self.seed, data_laps=self.laps)
            object.__setattr__(self, "car_config", replace(car, training=training))

    def study(self) -> PaceStudyConfig:
        """The same settings as a pace-study configuration (scenarios, training)."""
        car = self.car_config
        return PaceStudyConfig(
            tracks=(self.track,),
            controllers=(self.controller,),
            paces=self.paces,
            seed=self.seed,
            scale=self.scale,
            vehicle=self.vehicle,
            laps=self.laps,
            epochs=self.epochs,
            cache_dir=self.cache_dir,
            use_cache=self.use_cache,
            kmpc_samples=PaceStudyConfig.kmpc_samples if car is None else car.training.kmpc_samples,
            car_config=car,
        )


@dataclass(frozen=True)
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


@dataclass(frozen=True)
class LearnPaceResult:
    """What :func:`learn_pace` found: the iterations and why it stopped."""

    config: LearnPaceConfig
    versions: dict[str, str]
    iterations: list[LearnIteration]
    stopped: str

    def to_json(self) -> dict[str, Any]:
        out = {
            "study": "learn-pace",
            "config": settings_json(self.config, self.config.car_config),
            "track": track_label(self.config.track),
            "seed": self.config.seed,
            "versions": self.versions,
            "stopped": self.stopped,
            "iterations": self.iterations,
        }
        return json_object(out)

    def to_markdown(self) -> str:
        cfg = self.config
        intro = (
            f"Learning to race on {track_label(cfg.track)} (seed {cfg.seed}): {cfg.controller} trained on "
            f"every clean lap recorded so far, one pace step faster each iteration; {cfg.laps} laps per "
            f"iteration. Stopped: {self.stopped}.\n\n"
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


def learn_pace(config: LearnPaceConfig, *, say: Callable[[str], None] | None = None) -> LearnPaceResult:
    """Learn to drive faster from one's own clean laps (see the module)."""
    if not isinstance(config, LearnPaceConfig):
        raise ParameterError("learn_pace: config must be a LearnPaceConfig")
    tell = say if say is not None else (lambda _msg: None)
    study = config.study()
    recipe = recipe_for(config.controller)
    if recipe is None:  # pragma: no cover - checked by the configuration
        raise ParameterError(f"learn_pace: {config.controller!r} learns no model")
    cache = ModelCache(config.cache_dir) if config.use_cache else None
    ladder = study.ladder
    last = len(ladder) - 1 if config.max_iterations is None else min(len(ladder) - 1, config.max_iterations)

    def lmpc_lap(pace: Pace) -> tuple[bool, LapMetrics]:
        result, _ = record(study.scenario(config.track, pace), RunSpec("lmpc", laps=1, seed=config.seed))
        return run_verdict(result, 1) is None, lap_metrics(result, laps=1)

    tell(f"iteration 0: LMPC laps at {pace_label(ladder[0])}")
    spec = RunSpec("lmpc", laps=config.laps, seed=config.seed)
    result, data = record(study.scenario(config.track, ladder[0]), spec)
    reason = run_verdict(result, config.laps)
    metrics = lap_metrics(result, laps=config.laps)
    lmpc_clean, lmpc_metrics = lmpc_lap(ladder[0])
    pool: list[tuple[str, Pace, TransitionDataset]] = [("lmpc", ladder[0], data)]
    iterations = [
        LearnIteration(
            0,
            "lmpc",
            ladder[0],
            reason is None,
            reason,
            result.outcome,
            metrics,
            lmpc_clean,
            lmpc_metrics,
            None,
            0,
            len(data),
            None,
        )
    ]
    if reason is not None:
        stopped = f"the LMPC's laps at the first pace {pace_label(ladder[0])} are not clean ({reason})"
        return LearnPaceResult(config, study_versions(), iterations, stopped)
    stopped = "top of the ladder" if last == len(ladder) - 1 else f"after {last} iterations (max_iterations)"
    for i in range(1, last + 1):
        pace = ladder[i]
        scenario = study.scenario(config.track, pace)
        joined = TransitionDataset.concatenate([d for _, _, d in pool]) if len(pool) > 1 else pool[0][2]
        tell(f"iteration {i}: {config.controller} trained on {len(joined)} samples drives {pace_label(pace)}")
        options, model = train_on(
            joined, scenario, recipe, seed=config.seed, cache=cache, epochs=config.epochs
        )
        spec = RunSpec(config.controller, laps=config.laps, seed=config.seed)
        result, data = record(scenario, spec, controller_options=options)
        reason = run_verdict(result, config.laps)
        lmpc_clean, lmpc_metrics = lmpc_lap(pace)
        iterations.append(
            LearnIteration(
                iteration=i,
                controller=config.controller,
                pace=pace,
                clean=reason is None,
                reason=reason,
                outcome=result.outcome,
                metrics=lap_metrics(result, laps=config.laps),
                lmpc_clean=lmpc_clean,
                lmpc_metrics=lmpc_metrics,
                trained_on=[{"recorder": who, "pace": list(at), "samples": len(d)} for who, at, d in pool],
                pool_samples=len(joined),
                recorded_samples=len(data),
                model=model,
            )
        )
        if reason is not None:
            stopped = f"laps at {pace_label(pace)} not clean ({reason})"
            break
        pool.append((config.controller, pace, data))
    return LearnPaceResult(config, study_versions(), iterations, stopped)
