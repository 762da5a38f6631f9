"""The pace study's settings and its worker: one controller climbs the pace ladder on one track.

At every pace of the ladder (:mod:`.pace_rules`), a learned controller is first trained on data
recorded *at that pace* (:func:`learn_at_pace`):

- by the LMPC (``laps`` laps) when the LMPC's laps at that pace are clean, or at the ladder's
  first pace whatever they are (as :func:`rkmpc.experiments.compare.compare` does);
- else by the same controller with the model of its last clean pace below, driven ``laps`` laps
  at this pace (its data then reach the new speeds even where its laps end early).

``kmpc`` (random excitation of the car) is trained on excitation within this pace's limits. The
controller then drives ``run_laps`` laps; the climb stops at the first pace whose laps are not
clean (higher paces are not tried). Every step records which data its model learned from.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.core.errors import ParameterError, RkmpcError
from rkmpc.core.validation import is_integer
from rkmpc.experiments.cache import ModelCache
from rkmpc.experiments.models import train_excitation_model, train_track_model
from rkmpc.experiments.runs import run_controller
from rkmpc.experiments.studies.common import (
    check_car_config,
    check_scale_vehicle,
    controller_names,
    track_label,
    track_specs,
)
from rkmpc.experiments.studies.pace_rules import (
    Pace,
    car_ladder,
    check_ladder,
    data_verdict,
    pace_ladder,
    run_verdict,
)
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import identify
from rkmpc.learning.recipes import Recipe, recipe_for
from rkmpc.sim.carfile import CarConfig, TrainingSettings
from rkmpc.sim.collect import record
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import Scenario, load_scenario, vehicle_preset

__all__ = [
    "PACE_CONTROLLERS",
    "DataSource",
    "PaceStep",
    "PaceStudyConfig",
    "learn_at_pace",
    "pace_job",
    "train_on",
]

#: Controllers of the pace study by default (the issue's comparison).
PACE_CONTROLLERS = ("lmpc", "lmpc-id", "rkmpc", "nmpc-dynamic")


@dataclass(frozen=True)
class PaceStudyConfig:
    """Settings of :func:`rkmpc.experiments.studies.pace.study_pace`.

    Parameters
    ----------
    tracks : sequence of str
        Built-in names or centre-line CSV paths; one job per (track, controller).
    controllers : sequence of str
        Controllers that climb the ladder; a comma-separated string is accepted.
    paces : sequence of (float, float) or None
        The ladder, ``(lateral_accel, max_speed)`` increasing; None: the vehicle's default
        (:func:`rkmpc.experiments.studies.pace_rules.pace_ladder`), or with ``car_config`` the
        car's (:func:`~rkmpc.experiments.studies.pace_rules.car_ladder`: from the car's own pace).
    seed : int
        Seed of the data, the training and the runs.
    scale : float or None
        Track scale (default: the vehicle's).
    vehicle : str
        Vehicle preset; its speed limits (or ``car_config``'s) are scaled to each pace.
    laps : int
        Laps of data the learned controllers learn from at each pace.
    run_laps : int
        Laps each controller drives at each pace (all must be clean).
    epochs : int or None
        Training epochs (None: the recipes' defaults).
    kmpc_samples : int
        Random-excitation samples of ``kmpc``'s model.
    cache_dir : str or None
        Model cache folder (default when None).
    use_cache : bool
        Read and write trained models in the cache.
    car_config : CarConfig or None
        The car as a car file set it up (:mod:`rkmpc.sim.carfile`), a car of the ``vehicle``
        preset: its parameters, plant, controllers' settings and limits (scaled to each pace)
        replace the preset's. The fields above stay authoritative (seed, laps, epochs, samples):
        the copy kept here is brought in line with them, and the result records it.
    """

    tracks: Sequence[str]
    controllers: Sequence[str] = PACE_CONTROLLERS
    paces: Sequence[Pace] | None = None
    seed: int = 0
    scale: float | None = None
    vehicle: str = "f1tenth"
    laps: int = 2
    run_laps: int = 1
    epochs: int | None = None
    kmpc_samples: int = 50_000
    cache_dir: str | None = None
    use_cache: bool = True
    car_config: CarConfig | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "tracks", track_specs("PaceStudyConfig.tracks", self.tracks))
        controllers = controller_names("PaceStudyConfig.controllers", self.controllers)
        object.__setattr__(self, "controllers", controllers)
        check_scale_vehicle(self.scale, self.vehicle)
        car = check_car_config("PaceStudyConfig.car_config", self.car_config, self.vehicle)
        if self.paces is not None:
            ladder = check_ladder("PaceStudyConfig.paces", self.paces)
        else:
            ladder = pace_ladder(self.vehicle) if car is None else car_ladder(car)
        object.__setattr__(self, "paces", ladder)
        for name, minimum in (("seed", 0), ("laps", 1), ("run_laps", 1), ("kmpc_samples", 1000)):
            if not is_integer(getattr(self, name), minimum):
                raise ParameterError(
                    f"PaceStudyConfig.{name} must be an integer >= {minimum}, got {getattr(self, name)!r}"
                )
        if self.epochs is not None and not is_integer(self.epochs, 1):
            raise ParameterError(
                f"PaceStudyConfig.epochs must be None or an integer >= 1, got {self.epochs!r}"
            )
        if car is not None:  # the copy kept is the one that runs: the study's training settings
            training = TrainingSettings(
                epochs=self.epochs, seed=self.seed, data_laps=self.laps, kmpc_samples=self.kmpc_samples
            )
            object.__setattr__(self, "car_config", replace(car, training=training))

    @property
    def ladder(self) -> tuple[Pace, ...]:
        """The paces, validated."""
        paces: tuple[Pace, ...] = tuple(self.paces or ())
        return paces

    def scenario(self, track: str, pace: Pace) -> Scenario:
        """The track and car at ``pace``: the car's limits at that lateral limit and top speed.

        The car is the ``vehicle`` preset, or ``car_config``'s (its parameters, plant and
        controllers' settings; its limits are the ones scaled).
        """
        car = self.car_config
        if car is None:
            limits = vehicle_preset(self.vehicle).limits.at_pace(*pace)
            return load_scenario(track, scale=self.scale, vehicle=self.vehicle, limits=limits)
        return car.scenario(track, scale=self.scale, limits=car.limits.at_pace(*pace))


@dataclass(frozen=True)
class DataSource:
    """What a model at one pace learned from.

    ``recorder`` drove the laps (``"lmpc"``, the controller itself with the model of
    ``recorder_pace``, or ``"excitation"`` for random excitation of the car) at ``pace``;
    ``lmpc_clean`` / ``lmpc_reason``: whether the LMPC's laps at this pace were clean (None for
    excitation data). ``clean`` / ``reason`` are the recorded laps' own verdict; ``model`` the
    training record (:class:`rkmpc.experiments.results.ModelRecord` as JSON).
    """

    recorder: str
    pace: Pace
    recorder_pace: Pace | None
    laps: int
    samples: int
    data_hash: str | None
    clean: bool | None
    reason: str | None
    lmpc_clean: bool | None
    lmpc_reason: str | None
    model: dict[str, Any]

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> DataSource:
        """The inverse of the record a result file holds (``dataclasses.asdict``)."""
        fields = dict(data)
        fields["pace"] = _pace(fields["pace"])
        fields["recorder_pace"] = None if fields["recorder_pace"] is None else _pace(fields["recorder_pace"])
        return cls(**fields)


def _pace(value: Sequence[float]) -> Pace:
    lateral, speed = value
    return (float(lateral), float(speed))


@dataclass(frozen=True)
class PaceStep:
    """One controller at one pace: the verdict (``reason`` None when clean), the metrics, the data."""

    index: int
    pace: Pace
    reference_lap_time_s: float
    clean: bool
    reason: str | None
    outcome: str | None
    metrics: LapMetrics | None
    data: DataSource | None

    def to_json(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "lateral_accel": self.pace[0],
            "max_speed": self.pace[1],
            "reference_lap_time_s": self.reference_lap_time_s,
            "clean": self.clean,
            "reason": self.reason,
            "outcome": self.outcome,
            "metrics": None if self.metrics is None else self.metrics.to_json(),
            "data": self.data,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> PaceStep:
        """The step a result file records (:meth:`to_json`, as written to JSON)."""
        return cls(
            index=int(data["index"]),
            pace=_pace((data["lateral_accel"], data["max_speed"])),
            reference_lap_time_s=float(data["reference_lap_time_s"]),
            clean=bool(data["clean"]),
            reason=data["reason"],
            outcome=data["outcome"],
            metrics=None if data["metrics"] is None else LapMetrics.from_json(data["metrics"]),
            data=None if data["data"] is None else DataSource.from_json(data["data"]),
        )


def train_on(
    data: TransitionDataset,
    scenario: Scenario,
    recipe: Recipe,
    *,
    seed: int,
    cache: ModelCache | None,
    epochs: int | None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The controller options (``model``) and the model record of ``recipe`` learned from ``data``."""
    if recipe.learner == "identification":
        ident = identify(data, scenario.vehicle)
        return {"model": ident}, {
            "kind": recipe.kind,
            "raw_samples": len(data),
            "warnings": list(ident.warnings),
        }
    model, rec = train_track_model(data, scenario, recipe, seed=seed, cache=cache, epochs=epochs)
    return {"model": model}, rec.to_json()


def learn_at_pace(
    cfg: PaceStudyConfig,
    scenario: Scenario,
    pace: Pace,
    recipe: Recipe,
    previous: tuple[Pace, dict[str, Any]] | None,
    cache: ModelCache | None,
) -> tuple[dict[str, Any], DataSource]:
    """The model of ``recipe`` at ``pace`` (see the module) and where its data came from.

    ``previous`` is the last clean pace below and the controller's options there, if any.
    """
    if recipe.data == "excitation":
        model, rec = train_excitation_model(
            scenario, recipe, samples=cfg.kmpc_samples, seed=cfg.seed, cache=cache, epochs=cfg.epochs
        )
        source = DataSource(
            "excitation", pace, None, 0, cfg.kmpc_samples, None, None, None, None, None, rec.to_json()
        )
        return {"model": model}, source
    _, lmpc_data = record(scenario, RunSpec("lmpc", laps=cfg.laps, seed=cfg.seed))
    lmpc_reason = data_verdict(lmpc_data.metadata)
    data, recorder, recorder_pace = lmpc_data, "lmpc", None
    if lmpc_reason is not None and previous is not None:
        recorder_pace, own = previous
        _, data = record(
            scenario, RunSpec(recipe.controller, laps=cfg.laps, seed=cfg.seed), controller_options=own
        )
        recorder = recipe.controller
    options, model_record = train_on(data, scenario, recipe, seed=cfg.seed, cache=cache, epochs=cfg.epochs)
    reason = data_verdict(data.metadata)
    source = DataSource(
        recorder=recorder,
        pace=pace,
        recorder_pace=recorder_pace,
        laps=cfg.laps,
        samples=len(data),
        data_hash=data.content_hash(),
        clean=reason is None,
        reason=reason,
        lmpc_clean=lmpc_reason is None,
        lmpc_reason=lmpc_reason,
        model=model_record,
    )
    return options, source


def pace_job(cfg: PaceStudyConfig, track: str, controller: str) -> list[PaceStep]:
    """Worker of the pace study: ``controller`` on ``track`` up the ladder to its first unclean pace.

    A pace whose model cannot be learned (identification or training raises) ends the climb as
    unclean, with the error as its reason.
    """
    recipe = recipe_for(controller)
    cache = ModelCache(cfg.cache_dir) if cfg.use_cache else None
    steps: list[PaceStep] = []
    previous: tuple[Pace, dict[str, Any]] | None = None
    for index, pace in enumerate(cfg.ladder):
        scenario = cfg.scenario(track, pace)
        ref_time = float(scenario.reference.lap_time)
        options: dict[str, Any] | None = None
        source = None
        if recipe is not None:
            try:
                options, source = learn_at_pace(cfg, scenario, pace, recipe, previous, cache)
            except RkmpcError as exc:
                reason = f"no model: {type(exc).__name__}: {exc}"
                steps.append(PaceStep(index, pace, ref_time, False, reason, None, None, None))
                break
        spec = RunSpec(controller, laps=cfg.run_laps, seed=cfg.seed)
        result, metrics = run_controller(scenario, spec, controller_options=options)
        verdict = run_verdict(result, cfg.run_laps)
        steps.append(
            PaceStep(index, pace, ref_time, verdict is None, verdict, result.outcome, metrics, source)
        )
        if verdict is not None:
            break
        if options is not None:
            previous = (pace, options)
    return steps


def job_name(track: str, controller: str) -> str:
    """Name of a pace-study job (progress lines)."""
    return f"{track_label(track)} {controller}"
