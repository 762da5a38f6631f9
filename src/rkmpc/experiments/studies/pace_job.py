"""The pace study's settings and its worker: one controller climbs the pace ladder on one track.

At every pace of the ladder (:mod:`.pace_rules`), a learned controller is first trained on data
recorded *at that pace* (:func:`learn_at_pace`):

- by the LMPC (``laps`` laps) when the LMPC's laps at that pace are clean, or at the ladder's
  first pace whatever they are (as :func:`rkmpc.experiments.compare.compare` does);
- else by the same controller with the model of its last clean pace below, driven ``laps`` laps
  at this pace (its data then reach the new speeds even where its laps end early).

``kmpc`` (random excitation of the car) is trained on excitation within this pace's limits.
The car's training settings give the seed, the laps of data and the epochs. The
controller then drives ``run_laps`` laps; the climb stops at the first pace whose laps are not
clean (higher paces are not tried). Every step records which data its model learned from.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.core.errors import ParameterError, RkmpcError
from rkmpc.core.validation import is_integer
from rkmpc.experiments.cache import ModelCache
from rkmpc.experiments.models import excitation_model, make_model
from rkmpc.experiments.runs import run_controller
from rkmpc.experiments.studies.common import (
    MultiTrackConfig,
    json_object,
    track_label,
)
from rkmpc.experiments.studies.pace_rules import Pace, car_ladder, check_ladder, data_verdict, run_verdict
from rkmpc.learning.recipes import DataSource, Recipe, recipe_for
from rkmpc.sim.collect import record
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import Scenario

__all__ = [
    "PACE_CONTROLLERS",
    "PaceData",
    "PaceStep",
    "PaceStudyConfig",
    "learn_at_pace",
    "pace_job",
]

#: Controllers of the pace study by default (the issue's comparison).
PACE_CONTROLLERS = ("lmpc", "lmpc-id", "rkmpc", "nmpc-dynamic")


@dataclass(frozen=True, kw_only=True)
class PaceStudyConfig(MultiTrackConfig):
    """Settings of the pace study: :class:`MultiTrackConfig`'s (one job per track and controller;
    the car's training settings say the laps of data learned from at each pace, and its limits are
    scaled to each pace of the ladder) and:

    Parameters
    ----------
    paces : sequence of (float, float) or None
        The ladder, ``(lateral_accel, max_speed)`` increasing; None: the car's
        (:func:`~rkmpc.experiments.studies.pace_rules.car_ladder`: from the car's own pace).
    run_laps : int
        Laps each controller drives at each pace (all must be clean).
    """

    controllers: Sequence[str] = PACE_CONTROLLERS
    paces: Sequence[Pace] | None = None
    run_laps: int = 1

    def __post_init__(self) -> None:
        super().__post_init__()
        paces = (
            check_ladder("PaceStudyConfig.paces", self.paces)
            if self.paces is not None
            else car_ladder(self.car)
        )
        object.__setattr__(self, "paces", paces)
        if not is_integer(self.run_laps, 1):
            raise ParameterError(f"PaceStudyConfig.run_laps must be an integer >= 1, got {self.run_laps!r}")

    @property
    def ladder(self) -> tuple[Pace, ...]:
        """The paces, validated."""
        paces: tuple[Pace, ...] = tuple(self.paces or ())
        return paces

    @property
    def seed(self) -> int:
        """The seed of the data, the training and the runs (the car's)."""
        return self.car.training.seed

    def scenario(self, track: str, pace: Pace) -> Scenario:
        """The track and car at ``pace``: the car's limits at that lateral limit and top speed."""
        return Scenario.from_car(self.car.at_pace(*pace), track, scale=self.scale)

    def to_json(self) -> dict[str, Any]:
        """The settings, the car written out whole."""
        return json_object(
            {
                "tracks": list(self.tracks),
                "controllers": list(self.controllers),
                "paces": [list(p) for p in self.ladder],
                "scale": self.scale,
                "run_laps": self.run_laps,
                "cache_dir": self.cache_dir,
                "use_cache": self.use_cache,
                "car": self.car.to_json(),
            }
        )


@dataclass(frozen=True, kw_only=True)
class PaceData:
    """What a model at one pace learned from.

    ``recorder`` drove the laps (``"lmpc"``, the controller itself with the model of
    ``recorder_pace``, or ``"excitation"`` for random excitation of the car) at ``pace``;
    ``lmpc_clean`` / ``lmpc_reason``: whether the LMPC's laps at this pace were clean (None for
    excitation data). ``clean`` / ``reason`` are the recorded laps' own verdict; ``model`` the
    training record (:class:`rkmpc.experiments.results.ModelRecord` as JSON).
    """

    recorder: str
    pace: Pace
    recorder_pace: Pace | None = None
    laps: int = 0
    samples: int
    data_hash: str | None = None
    clean: bool | None = None
    reason: str | None = None
    lmpc_clean: bool | None = None
    lmpc_reason: str | None = None
    model: dict[str, Any]

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> PaceData:
        """The inverse of the record a result file holds (``dataclasses.asdict``)."""
        fields = dict(data)
        fields["pace"] = _pace(fields["pace"])
        fields["recorder_pace"] = None if fields["recorder_pace"] is None else _pace(fields["recorder_pace"])
        return cls(**fields)


def _pace(value: Sequence[float]) -> Pace:
    lateral, speed = value
    return (float(lateral), float(speed))


@dataclass(frozen=True, kw_only=True)
class PaceStep:
    """One controller at one pace: the verdict (``reason`` None when clean), the metrics, the data."""

    index: int
    pace: Pace
    reference_lap_time_s: float
    clean: bool
    reason: str | None
    outcome: str | None
    metrics: LapMetrics | None
    data: PaceData | None

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
            "data": None if self.data is None else asdict(self.data),
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
            data=None if data["data"] is None else PaceData.from_json(data["data"]),
        )


def learn_at_pace(
    cfg: PaceStudyConfig,
    scenario: Scenario,
    pace: Pace,
    recipe: Recipe,
    previous: tuple[Pace, object] | None,
    cache: ModelCache | None,
) -> tuple[object, PaceData]:
    """The model of ``recipe`` at ``pace`` (see the module) and where its data came from.

    ``previous`` is the last clean pace below and the controller's model there, if any.
    """
    training = cfg.car.training
    seed, epochs, laps = training.seed, training.epochs, training.data_laps
    if recipe.data is DataSource.EXCITATION:
        samples = training.kmpc_samples
        model, rec = excitation_model(
            scenario, recipe, samples=samples, seed=seed, cache=cache, epochs=epochs
        )
        return model, PaceData(recorder="excitation", pace=pace, samples=samples, model=rec.to_json())
    _, lmpc_data = record(scenario, RunSpec("lmpc", laps=laps, seed=seed))
    lmpc_reason = data_verdict(lmpc_data.metadata)
    data, recorder, recorder_pace = lmpc_data, "lmpc", None
    if lmpc_reason is not None and previous is not None:
        recorder_pace, own = previous
        _, data = record(scenario, RunSpec(recipe.controller, laps=laps, seed=seed), model=own)
        recorder = recipe.controller
    key = {"data_hash": data.content_hash()}
    model, model_record = make_model(
        recipe, scenario, lambda: data, key, seed=seed, epochs=epochs, cache=cache
    )
    reason = data_verdict(data.metadata)
    source = PaceData(
        recorder=recorder,
        pace=pace,
        recorder_pace=recorder_pace,
        laps=laps,
        samples=len(data),
        data_hash=key["data_hash"],
        clean=reason is None,
        reason=reason,
        lmpc_clean=lmpc_reason is None,
        lmpc_reason=lmpc_reason,
        model=model_record.to_json(),
    )
    return model, source


def pace_job(cfg: PaceStudyConfig, track: str, controller: str) -> list[PaceStep]:
    """Worker of the pace study: ``controller`` on ``track`` up the ladder to its first unclean pace.

    A pace whose model cannot be learned (identification or training raises) ends the climb as
    unclean, with the error as its reason.
    """
    recipe = recipe_for(controller)
    cache = cfg.cache()
    steps: list[PaceStep] = []
    previous: tuple[Pace, object] | None = None
    for index, pace in enumerate(cfg.ladder):
        scenario = cfg.scenario(track, pace)
        ref_time = float(scenario.reference.lap_time)
        model: object = None
        source = None
        if recipe is not None:
            try:
                model, source = learn_at_pace(cfg, scenario, pace, recipe, previous, cache)
            except RkmpcError as exc:
                reason = f"no model: {type(exc).__name__}: {exc}"
                steps.append(_unclean(index, pace, ref_time, reason))
                break
        spec = RunSpec(controller, laps=cfg.run_laps, seed=cfg.seed)
        result, metrics = run_controller(scenario, spec, model=model)
        verdict = run_verdict(result, cfg.run_laps)
        steps.append(
            PaceStep(
                index=index,
                pace=pace,
                reference_lap_time_s=ref_time,
                clean=verdict is None,
                reason=verdict,
                outcome=result.outcome,
                metrics=metrics,
                data=source,
            )
        )
        if verdict is not None:
            break
        if model is not None:
            previous = (pace, model)
    return steps


def _unclean(index: int, pace: Pace, ref_time: float, reason: str) -> PaceStep:
    return PaceStep(
        index=index,
        pace=pace,
        reference_lap_time_s=ref_time,
        clean=False,
        reason=reason,
        outcome=None,
        metrics=None,
        data=None,
    )


def job_name(track: str, controller: str) -> str:
    """Name of a pace-study job (progress lines)."""
    return f"{track_label(track)} {controller}"
