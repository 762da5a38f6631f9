"""The data study's settings, and its worker: collect data for one size, train, drive one lap."""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.experiments.runs import run_controller
from rkmpc.experiments.studies.common import (
    check_car,
    check_scale,
    check_track,
    int_tuple,
    json_object,
    str_tuple,
)
from rkmpc.learning.data.augmentation import AugmentConfig, valid_origins
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.learn import learn
from rkmpc.learning.recipes import DataSource, KoopmanLearner, recipe_for
from rkmpc.sim.collect import collect, collect_excitation
from rkmpc.sim.run import RunSpec
from rkmpc.sim.scenario import Scenario

__all__ = ["DATA_CONTROLLERS", "DEFAULT_SIZES", "DataRun", "DataStudyConfig", "data_job"]


#: Training-sample targets of the data study (augmented transitions, the paper's M = N x N_p).
DEFAULT_SIZES = (1000, 2000, 4000, 8000, 16000, 32000, 50000)

#: Controllers the data study can train (learned from data by a Koopman recipe).
DATA_CONTROLLERS = ("rkmpc", "kmpc")


@dataclass(frozen=True, kw_only=True)
class DataStudyConfig:
    """Settings of the data study.

    Parameters
    ----------
    track : str
        Built-in track name or centre-line CSV path the laps are driven on.
    car : CarConfig
        The car (its training epochs are the study's; it sizes its own data and takes ``seeds``).
    scale : float or None
        Track scale (default: the car's).
    sizes : sequence of int
        Targets for the number of training samples: local-frame transitions after augmentation
        (``TrainReport.augmented_count``, the paper's ``M = N x N_p``). Each is met to within
        ``n_points / 2``.
    seeds : sequence of int
        Seeds (>= 0) of the data, the augmentation, the training and the lap.
    controllers : sequence of str
        Any of ``"rkmpc"`` (trained on LMPC laps of the track) and ``"kmpc"`` (on random excitation).
    n_points : int
        ``N_p``, transitions per augmentation window.
    rkmpc_max_ratio : float
        Largest conversion ratio for track data: LMPC laps are added until the target can be met at
        a ratio at most this (then the ratio is set to meet it). 0.3 is the ratio of the main results.
    kmpc_max_ratio : float
        Same for random-excitation samples (0.05 as in the main results).
    min_laps, max_laps : int
        Range of the LMPC laps collected.
    """

    track: str = "builtin"
    car: CarConfig = field(default_factory=lambda: load_preset("f1tenth"))
    scale: float | None = None
    sizes: Sequence[int] = DEFAULT_SIZES
    seeds: Sequence[int] = (0, 1, 2)
    controllers: Sequence[str] = DATA_CONTROLLERS
    n_points: int = 35
    rkmpc_max_ratio: float = 0.3
    kmpc_max_ratio: float = 0.05
    min_laps: int = 1
    max_laps: int = 40

    def __post_init__(self) -> None:
        check_track(str(self.track))
        object.__setattr__(self, "track", str(self.track))
        check_scale("DataStudyConfig.scale", self.scale)
        check_car("DataStudyConfig.car", self.car)
        object.__setattr__(self, "sizes", int_tuple("DataStudyConfig.sizes", self.sizes, minimum=1))
        object.__setattr__(self, "seeds", int_tuple("DataStudyConfig.seeds", self.seeds, minimum=0))
        controllers = str_tuple("DataStudyConfig.controllers", self.controllers)
        bad = [c for c in controllers if c not in DATA_CONTROLLERS]
        if bad:
            raise ParameterError(f"DataStudyConfig.controllers: {bad}; allowed: {sorted(DATA_CONTROLLERS)}")
        object.__setattr__(self, "controllers", controllers)
        if not is_integer(self.n_points) or self.n_points < 1:
            raise ParameterError(f"DataStudyConfig.n_points must be an integer >= 1, got {self.n_points!r}")
        for name in ("rkmpc_max_ratio", "kmpc_max_ratio"):
            if not is_positive_number(getattr(self, name), 1.0):
                raise ParameterError(f"DataStudyConfig.{name} must be in (0, 1], got {getattr(self, name)!r}")
        if not (
            is_integer(self.min_laps) and is_integer(self.max_laps) and 1 <= self.min_laps <= self.max_laps
        ):
            raise ParameterError(
                "DataStudyConfig: need integers 1 <= min_laps <= max_laps, "
                f"got {self.min_laps!r}, {self.max_laps!r}"
            )
        for size in self.sizes:
            if size < self.n_points:
                raise ParameterError(
                    f"DataStudyConfig.sizes: {size} is below one window of n_points = {self.n_points}"
                )

    def scenario(self) -> Scenario:
        """The track and the car."""
        return Scenario.from_car(self.car, self.track, scale=self.scale)

    def to_json(self) -> dict[str, Any]:
        """The settings, the car written out whole."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "car"}
        return {**json_object(out), "car": self.car.to_json()}


@dataclass(frozen=True, kw_only=True)
class DataRun:
    """What one (controller, size, seed) job of the data study made and drove.

    ``source`` says where the data came from (``{"kind": "lmpc_laps", "laps", "outcome",
    "completed"}`` or ``{"kind": "excitation", "n_samples"}``); the counts are the training's
    (:class:`~rkmpc.learning.pipeline.TrainReport`); times are wall seconds, for reports only.
    """

    controller: str
    size: int
    seed: int
    source: dict[str, Any]
    raw_count: int
    augmented_count: int
    valid_origins: int
    windows: int
    ratio: float
    target_met: bool
    model_options: dict[str, Any]
    train_report: dict[str, Any]
    data_s: float
    train_s: float
    fit_s: float
    lap_s: float
    metrics: LapMetrics

    def to_json(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "metrics"}
        return {**json_object(out), "metrics": self.metrics.to_json()}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> DataRun:
        values = {f.name: data[f.name] for f in fields(cls) if f.name != "metrics"}
        return cls(**values, metrics=LapMetrics.from_json(data["metrics"]))


def _lmpc_data(
    scenario: Scenario, windows: int, cfg: DataStudyConfig, seed: int
) -> tuple[TransitionDataset, int, int]:
    """LMPC laps holding at least ``windows / max_ratio`` window origins -> (data, laps, origins)."""
    steps_per_lap = max(1.0, scenario.reference.lap_time / scenario.dt)
    need = windows / cfg.rkmpc_max_ratio
    laps = max(cfg.min_laps, math.ceil((need + cfg.n_points - 1) / steps_per_lap))
    laps = min(laps, cfg.max_laps)
    while True:
        data = collect(scenario, controller="lmpc", laps=laps, seed=seed)
        k = int(valid_origins(data, cfg.n_points).size)
        if k >= need or laps >= cfg.max_laps or not data.metadata["completed"]:
            return data, laps, k
        laps += 1


def _excitation_data(
    scenario: Scenario, windows: int, cfg: DataStudyConfig, seed: int
) -> tuple[TransitionDataset, int, int]:
    """Random excitation with at least ``windows / max_ratio`` origins -> (data, samples, origins)."""
    need = windows / cfg.kmpc_max_ratio
    n = math.ceil(need * 1.25) + cfg.n_points
    for _ in range(8):
        data = collect_excitation(scenario, n_samples=n, seed=seed)
        k = int(valid_origins(data, cfg.n_points).size)
        if k >= need:
            return data, n, k
        n = math.ceil(n * need / max(k, 1) * 1.05) + cfg.n_points
    return data, n, k


def data_job(cfg: DataStudyConfig, controller: str, size: int, seed: int) -> DataRun:
    """Worker of the data study: data, training and one lap for one (controller, size, seed)."""
    recipe = recipe_for(controller)
    if recipe is None or not isinstance(recipe.learner, KoopmanLearner):
        raise ParameterError(f"the data study trains Koopman recipes only, not {controller!r}")
    t0 = time.perf_counter()
    scenario = cfg.scenario()
    windows = max(1, round(size / cfg.n_points))
    source: dict[str, Any]
    if recipe.data is DataSource.TRACK:
        data, laps, origins = _lmpc_data(scenario, windows, cfg, seed)
        meta = data.metadata
        source = {
            "kind": "lmpc_laps",
            "laps": laps,
            "outcome": meta["outcome"],
            "completed": meta["completed"],
        }
    else:
        data, n_samples, origins = _excitation_data(scenario, windows, cfg, seed)
        source = {"kind": "excitation", "n_samples": n_samples}
    t_data = time.perf_counter() - t0
    ratio = min(1.0, windows / origins) if origins else 1.0
    model = recipe.learner.default_model(seed, cfg.car.training.epochs)
    augment = AugmentConfig(ratio=ratio, n_points=cfg.n_points, seed=seed)
    t1 = time.perf_counter()
    learned = learn(
        recipe,
        data,
        made_for=replace(scenario.provenance(), scale=None),
        vehicle=scenario.vehicle,
        seed=seed,
        model=model,
        augment=augment,
    )
    report = learned.report
    if report is None:  # pragma: no cover - a Koopman learner reports its training
        raise ParameterError(f"no training report for {controller!r}")
    t_train = time.perf_counter() - t1
    t2 = time.perf_counter()
    _, metrics = run_controller(scenario, RunSpec(controller, seed=seed), model=learned.model)
    return DataRun(
        controller=controller,
        size=size,
        seed=seed,
        source=source,
        raw_count=report.raw_count,
        augmented_count=report.augmented_count,
        valid_origins=origins,
        windows=report.train_windows + report.holdout_windows,
        ratio=ratio,
        target_met=abs(report.augmented_count - size) <= cfg.n_points / 2 + 1e-9,
        model_options=model.get_params(),
        train_report=asdict(report),
        data_s=t_data,
        train_s=t_train,
        fit_s=report.fit_time_s,
        lap_s=time.perf_counter() - t2,
        metrics=metrics,
    )
