"""The models of a comparison: collect the data, train or identify, through the cache.

Every learned controller is made by its recipe (:mod:`rkmpc.learning.recipes`):
recipes whose data are ``"track"`` learn from LMPC laps of the track
(collected once for all of them), ``"excitation"`` recipes from random
excitation of the car (which does not depend on the track). Trained models
are cached by content hash (:mod:`rkmpc.experiments.cache`).
"""

from __future__ import annotations

import functools
import hashlib
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import rkmpc.core
from rkmpc.core.errors import ParameterError
from rkmpc.core.progress import EpochProgress
from rkmpc.core.versions import RKMPC_VERSION
from rkmpc.experiments.cache import ModelCache
from rkmpc.experiments.results import DataRecord, ModelRecord, TrainingRecord
from rkmpc.learning.contract import contract_of
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import identify
from rkmpc.learning.io import load_model
from rkmpc.learning.koopman.lifting import MLPLifting
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.pipeline import TrainConfig, TrainReport, train_model
from rkmpc.learning.recipes import RECIPES, Recipe, recipe_for
from rkmpc.sim.collect import collect, collect_excitation, excitation_lateral_accel
from rkmpc.sim.scenario import Scenario

__all__ = ["ModelPlan", "learn_models", "train_excitation_model", "train_track_model"]


@functools.cache
def _code_hash() -> str:
    """Hash of the sources that shape training data and models (vehicle and learning packages)."""
    root = Path(rkmpc.core.__file__).parent.parent
    digest = hashlib.sha256()
    for sub in ("learning", "vehicle"):
        for path in sorted((root / sub).rglob("*.py")):
            digest.update(str(path.relative_to(root / sub)).encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _record(report: TrainReport, kind: str, model: KoopmanModel, **extra: Any) -> ModelRecord:
    err = report.multi_step_error
    return ModelRecord(
        kind=kind,
        raw_samples=report.raw_count,
        augmented_samples=report.augmented_count,
        train_windows=report.train_windows,
        holdout_windows=report.holdout_windows,
        fit_time_s=report.fit_time_s,
        heldout_error_step1=err[0] if err else None,
        heldout_error_last=err[-1] if err else None,
        # The state range the model was trained on; it clips states into it (no extrapolation).
        state_min=model.x_min_.tolist(),
        state_max=model.x_max_.tolist(),
        **extra,
    )


def _train(
    data: TransitionDataset,
    scenario: Scenario,
    recipe: Recipe,
    config: TrainConfig,
    say: Callable[[str], None] | None,
) -> tuple[KoopmanModel, TrainReport]:
    """Train ``config``'s model for the scenario's car; ``say``, when given, hears its progress."""
    on_epoch = None
    lifting = config.unfitted_model().lifting
    if say is not None and isinstance(lifting, MLPLifting) and lifting.training is not None:
        what = f"training the {recipe.kind} model of {recipe.controller}"
        on_epoch = EpochProgress(say, what, lifting.training.epochs)
    return train_model(
        data, scenario.vehicle.wheelbase, config, vehicle=scenario.vehicle_name, on_epoch=on_epoch
    )


def _through_cache(
    cache: ModelCache | None, spec: Mapping[str, Any], build: Callable[[], tuple[KoopmanModel, ModelRecord]]
) -> tuple[KoopmanModel, ModelRecord]:
    """``build()``, or the cached model of ``spec``; the record says which."""
    if cache is None:
        model, record = build()
        return model, replace(record, cached=False, cache_key=None)

    def build_json() -> tuple[KoopmanModel, dict[str, Any]]:
        model, record = build()
        return model, record.to_json()

    model, hit = cache.get_or_build(spec, build_json)
    return model, replace(ModelRecord.from_json(hit.info), cached=hit.hit, cache_key=hit.key)


def train_excitation_model(
    scenario: Scenario,
    recipe: Recipe,
    *,
    samples: int,
    seed: int,
    cache: ModelCache | None,
    epochs: int | None = None,
    say: Callable[[str], None] | None = None,
) -> tuple[KoopmanModel, ModelRecord]:
    """The model of an ``"excitation"`` recipe (KMPC) of the scenario's car, from the cache or trained.

    ``say``, when given, hears the training's progress (:class:`rkmpc.core.progress.EpochProgress`).
    """
    augment = recipe.augment(seed)
    model = recipe.default_model(seed, epochs)
    spec = {
        "name": recipe.controller,
        "kind": recipe.kind,
        "vehicle": scenario.vehicle_name,
        "vehicle_params": asdict(scenario.vehicle),
        "plant": scenario.vehicle_preset.plant,
        "speed_range": [scenario.limits.min_speed, scenario.limits.max_speed],
        "lateral_accel": excitation_lateral_accel(scenario),
        "dt": scenario.dt,
        "samples": samples,
        "seed": seed,
        "augment": asdict(augment),
        "model": model.get_params(),
        "rkmpc_version": RKMPC_VERSION,
        "code": _code_hash(),
    }
    if scenario.car is not None:  # keys of the presets' own plants stay as they were
        spec["car"] = scenario.car.describe()

    def build() -> tuple[KoopmanModel, ModelRecord]:
        t0 = time.perf_counter()
        data = collect_excitation(scenario, n_samples=samples, seed=seed)
        collect_time = time.perf_counter() - t0
        config = TrainConfig(kind=recipe.kind, augment=augment, model=model)
        fitted, report = _train(data, scenario, recipe, config, say)
        return fitted, _record(report, recipe.kind, fitted, collect_time_s=collect_time)

    return _through_cache(cache, spec, build)


def train_track_model(
    data: TransitionDataset,
    scenario: Scenario,
    recipe: Recipe,
    *,
    seed: int,
    cache: ModelCache | None,
    epochs: int | None = None,
    say: Callable[[str], None] | None = None,
) -> tuple[KoopmanModel, ModelRecord]:
    """The model of a ``"track"`` recipe (``residual``, ``paper``) of on-track data, cached or trained.

    ``say``, when given, hears the training's progress (:class:`rkmpc.core.progress.EpochProgress`).
    """
    config = TrainConfig(
        kind=recipe.kind, augment=recipe.augment(seed), model=recipe.default_model(seed, epochs)
    )
    spec = {
        "name": recipe.kind,
        "kind": recipe.kind,
        "data_hash": data.content_hash(),
        "wheelbase": scenario.vehicle.wheelbase,
        "augment": asdict(config.augment),
        "model": config.unfitted_model().get_params(),
        "holdout": config.holdout,
        "rkmpc_version": RKMPC_VERSION,
        "code": _code_hash(),
    }

    def build() -> tuple[KoopmanModel, ModelRecord]:
        model, report = _train(data, scenario, recipe, config, say)
        return model, _record(report, recipe.kind, model)

    return _through_cache(cache, spec, build)


@dataclass(frozen=True)
class ModelPlan:
    """What to learn for a comparison, and how.

    Parameters
    ----------
    controllers : sequence of str
        The controllers of the comparison; those with a recipe get a model.
    laps : int
        LMPC laps of on-track data.
    seed : int
        Seed of the data collection and the training.
    excitation_samples : int
        Random-excitation samples of ``"excitation"`` recipes.
    model_files : mapping of str to str
        Model files to use instead of learning, by controller.
    cache_dir : str or None
        Model cache folder (default when None).
    use_cache : bool
        Read and write trained models in the cache.
    epochs : int or None
        Training epochs of every model (None: the recipes' defaults).
    allow_mismatch : bool
        Use model files made with another car, period or track scale than the scenario's, with a
        warning kept in the model's record, instead of refusing them.
    """

    controllers: Sequence[str]
    laps: int = 2
    seed: int = 0
    excitation_samples: int = 50_000
    model_files: Mapping[str, str] = field(default_factory=dict)
    cache_dir: str | None = None
    use_cache: bool = True
    epochs: int | None = None
    allow_mismatch: bool = False

    def __post_init__(self) -> None:
        files = dict(self.model_files)
        unknown = sorted(name for name in files if recipe_for(name) is None)
        if unknown:
            learned = sorted(r.controller for r in RECIPES)
            raise ParameterError(f"model files given for {unknown}, which take no model; learned: {learned}")
        object.__setattr__(self, "model_files", files)


def learn_models(
    scenario: Scenario, plan: ModelPlan, *, say: Callable[[str], None] | None = None
) -> tuple[dict[str, dict[str, Any]], TrainingRecord]:
    """Collect data and train (or load) the model of every learned controller of the plan.

    ``say``, when given, is called with a short message before each slow stage.

    Every model file is checked against the scenario (car, wheelbase, period, track scale:
    :meth:`rkmpc.learning.contract.Provenance.check`) as it is read, before anything is collected,
    trained or driven; the models trained here are made for the scenario.

    Returns
    -------
    options : dict
        Controller options (``model``, ``allow_mismatch``) by controller name.
    training : TrainingRecord
        The data and a record per model (with the contract warnings of a model used on request
        with another car or period).

    Raises
    ------
    ContractError
        When a model file was made with another car, period or scale, unless ``plan.allow_mismatch``.
    """
    tell = say if say is not None else (lambda _msg: None)
    cache = ModelCache(plan.cache_dir) if plan.use_cache else None
    options: dict[str, dict[str, Any]] = {}
    records: dict[str, ModelRecord] = {}
    wanted = [(name, r) for name in plan.controllers if (r := recipe_for(name)) is not None]
    for name, recipe in wanted:
        if name in plan.model_files:
            path = str(plan.model_files[name])
            model = load_model(path, recipe.kind)
            warned: tuple[str, ...] = ()
            if isinstance(model, KoopmanModel):  # identified models are not checked when read
                warned = contract_of(model.metadata_).check(
                    scenario.provenance(), source=path, made="trained", allow_mismatch=plan.allow_mismatch
                )
            options[name] = {"model": model}
            records[name] = ModelRecord(model_file=path, contract_warnings=list(warned) or None)
    on_track = [(n, r) for n, r in wanted if r.data == "track" and n not in plan.model_files]
    data_record = None
    if on_track:
        tell(f"collecting {plan.laps} LMPC laps of data")
        t0 = time.perf_counter()
        data = collect(scenario, controller="lmpc", laps=plan.laps, seed=plan.seed)
        data_record = DataRecord(
            controller="lmpc",
            laps=plan.laps,
            raw_samples=len(data),
            outcome=data.metadata["outcome"],
            collect_time_s=time.perf_counter() - t0,
            data_hash=data.content_hash(),
        )
        for name, recipe in on_track:
            if recipe.learner == "identification":
                t0 = time.perf_counter()
                ident = identify(data, scenario.vehicle)
                for warning in ident.warnings:
                    tell(f"{name}: identification warning: {warning}")
                records[name] = ModelRecord(
                    kind=recipe.kind,
                    raw_samples=len(data),
                    fit_time_s=time.perf_counter() - t0,
                    identified=ident,
                )
                options[name] = {"model": ident}
                continue
            tell(f"training the {recipe.kind} model of {name}")
            model, record = train_track_model(
                data, scenario, recipe, seed=plan.seed, cache=cache, epochs=plan.epochs, say=say
            )
            records[name] = record
            options[name] = {"model": model}
    for name, recipe in wanted:
        if recipe.data == "excitation" and name not in plan.model_files:
            tell(f"{name} model: {plan.excitation_samples} random-excitation samples (trained once, cached)")
            model, record = train_excitation_model(
                scenario,
                recipe,
                samples=plan.excitation_samples,
                seed=plan.seed,
                cache=cache,
                epochs=plan.epochs,
                say=say,
            )
            records[name] = record
            options[name] = {"model": model}
    for option in options.values():
        option["allow_mismatch"] = plan.allow_mismatch
    ordered = {name: records[name] for name in plan.controllers if name in records}
    return options, TrainingRecord(data=data_record, models=ordered)
