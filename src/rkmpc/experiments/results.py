"""Typed results of the experiments, each with ``to_json()`` (the layout of ``results.json``).

:class:`TrackResult` is what :func:`rkmpc.experiments.compare.compare` returns
for one track: the lap of every controller (:class:`ControllerRun`), what was
learned (:class:`TrainingRecord`: the on-track data and one :class:`ModelRecord`
per learned controller), the configuration block, and with a fault what it did
(:class:`FaultOutcome`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.learning.identification import IdentifiedModel

__all__ = [
    "NOT_LEARNED",
    "ControllerRun",
    "DataRecord",
    "FaultOutcome",
    "ModelRecord",
    "TrackResult",
    "TrainingRecord",
]

#: The outcome of a learned controller whose data or model were refused: it did not drive.
NOT_LEARNED = "not_learned"


@dataclass(frozen=True)
class ControllerRun:
    """One controller's run: its lap metrics and how the run ended (``completed``, ``off_track``...).

    Parameters
    ----------
    metrics : LapMetrics
        The lap metrics.
    outcome : str
        How the run ended (:data:`rkmpc.sim.closed_loop.OUTCOMES`), or :data:`NOT_LEARNED` for a
        learned controller that was not driven because its data or its model were refused.
    failure : str or None
        The plant's message when ``outcome`` is ``"plant_failure"``, why the data or the model were
        refused when it is :data:`NOT_LEARNED`, else None.
    diagnostics : Mapping[str, float]
        The controller's own counts at the end of the run (``Controller.diagnostics()``: the steps
        a guard, the trust or the slip drift's limit acted on, the estimator's rejections).
    """

    metrics: LapMetrics
    outcome: str
    failure: str | None = None
    diagnostics: Mapping[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            **self.metrics.to_json(),
            "outcome": self.outcome,
            "failure": self.failure,
            "diagnostics": {name: float(value) for name, value in self.diagnostics.items()},
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ControllerRun:
        """A run read back from :meth:`to_json` output (results written before runs kept their
        diagnostics read back with none)."""
        diagnostics = data["diagnostics"] if "diagnostics" in data else {}
        return cls(
            metrics=LapMetrics.from_json(data),
            outcome=str(data["outcome"]),
            failure=data["failure"],
            diagnostics={str(name): float(value) for name, value in diagnostics.items()},
        )


@dataclass(frozen=True)
class DataRecord:
    """The on-track data the learned controllers of a track learn from.

    Parameters
    ----------
    controller : str
        Controller that drove the laps (``lmpc``).
    laps : int
        Laps asked for.
    raw_samples : int
        Transitions recorded.
    outcome : str
        How the collection run ended.
    collect_time_s : float
        Wall time of the collection (s), for reports only.
    data_hash : str
        Content hash of the data set.
    """

    controller: str
    laps: int
    raw_samples: int
    outcome: str
    collect_time_s: float
    data_hash: str

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> DataRecord:
        """A record read back from :meth:`to_json` output."""
        return cls(**{name: data[name] for name in cls.__dataclass_fields__})


@dataclass(frozen=True)
class ModelRecord:
    """Where a learned controller's model came from, and what its training saw.

    A model read from a file records only ``model_file``; an identified model its
    parameters; a trained Koopman model its sample counts, held-out errors, the
    state range it clips to, and whether it came from the cache; a residual model also the
    held-out error of no correction at the horizon's last step (``no_correction_error_last``,
    :class:`~rkmpc.learning.pipeline.TrainReport`). A model used on
    request with another car, period or track scale than it was made with records
    the warnings (``contract_warnings``). A model that could not be learned because its data were
    refused (:func:`rkmpc.learning.data.plausibility.check_learnable`), or that was refused itself
    (:class:`~rkmpc.core.errors.NotLearnedError`), records why (``refused``).
    """

    kind: str | None = None
    model_file: str | None = None
    raw_samples: int | None = None
    augmented_samples: int | None = None
    train_windows: int | None = None
    holdout_windows: int | None = None
    fit_time_s: float | None = None
    heldout_error_step1: float | None = None
    heldout_error_last: float | None = None
    no_correction_error_last: float | None = None
    state_min: list[float] | None = None
    state_max: list[float] | None = None
    collect_time_s: float | None = None
    identified: IdentifiedModel | None = None
    cached: bool | None = None
    cache_key: str | None = None
    contract_warnings: list[str] | None = None
    refused: str | None = None

    #: Fields written even when None (a trained model's held-out errors may be missing).
    _ALWAYS = ("heldout_error_step1", "heldout_error_last", "cache_key")

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        trained = self.augmented_samples is not None
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if value is None and not (trained and name in self._ALWAYS):
                continue
            out[name] = to_json_ready(value) if isinstance(value, IdentifiedModel) else value
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ModelRecord:
        """A record read back from :meth:`to_json` output (the model cache keeps them)."""
        known = {k: data[k] for k in cls.__dataclass_fields__ if k in data}
        if isinstance(known.get("identified"), Mapping):
            known["identified"] = IdentifiedModel(**known["identified"])
        return cls(**known)


@dataclass(frozen=True)
class TrainingRecord:
    """What was learned for one track: the on-track data (when any) and a record per model."""

    data: DataRecord | None = None
    models: dict[str, ModelRecord] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {name: record.to_json() for name, record in self.models.items()}
        if self.data is not None:
            out = {"data": self.data.to_json(), **out}
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TrainingRecord:
        """A record read back from :meth:`to_json` output."""
        models = {name: ModelRecord.from_json(value) for name, value in data.items() if name != "data"}
        return cls(data=DataRecord.from_json(data["data"]) if "data" in data else None, models=models)


@dataclass(frozen=True)
class FaultOutcome:
    """What a fault did: its name, each controller's run with it, and the classification."""

    fault: str
    runs: dict[str, ControllerRun]
    effects: dict[str, str]


@dataclass(frozen=True)
class TrackResult:
    """Every controller on one track (:func:`rkmpc.experiments.compare.compare`).

    Parameters
    ----------
    track : str
        Track name.
    controllers : dict of str to ControllerRun
        The nominal run of each controller, in the order driven.
    training : TrainingRecord
        Data and models learned.
    config : dict
        The configuration block (scenario, runs, seed, settings, versions), plain JSON.
    fault : FaultOutcome or None
        The runs with the fault, when one was asked for.
    """

    track: str
    controllers: dict[str, ControllerRun]
    training: TrainingRecord
    config: dict[str, Any]
    fault: FaultOutcome | None = None

    def metrics(self) -> dict[str, LapMetrics]:
        """Lap metrics by controller (what the tables show)."""
        return {name: run.metrics for name, run in self.controllers.items()}

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "track": self.track,
            "controllers": {name: run.to_json() for name, run in self.controllers.items()},
            "training": self.training.to_json(),
            "config": self.config,
        }
        if self.fault is not None:
            out["fault"] = self.fault.fault
            out["faulted"] = {name: run.to_json() for name, run in self.fault.runs.items()}
            out["fault_effect"] = dict(self.fault.effects)
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TrackResult:
        """A result read back from :meth:`to_json` output (a study's journal keeps them)."""
        fault = None
        if "fault" in data:
            runs = {name: ControllerRun.from_json(run) for name, run in data["faulted"].items()}
            fault = FaultOutcome(str(data["fault"]), runs, dict(data["fault_effect"]))
        return cls(
            track=str(data["track"]),
            controllers={name: ControllerRun.from_json(run) for name, run in data["controllers"].items()},
            training=TrainingRecord.from_json(data["training"]),
            config=dict(data["config"]),
            fault=fault,
        )
