"""The models of an experiment: collect the data, learn, through the cache.

Every learned controller is made by its recipe (:mod:`rkmpc.learning.recipes`) in one place,
:func:`make_model` (which calls :func:`rkmpc.learning.learn.learn` for the scenario's car, through
the model cache for the learners whose models are worth caching). Recipes whose data are
``"track"`` learn from LMPC laps of the track (collected once for all of them, :func:`learn_models`),
``"excitation"`` recipes from random excitation of the car, which does not depend on the track
(:func:`excitation_model`).
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
from rkmpc.core.errors import InputFileError, NotLearnedError, ParameterError
from rkmpc.core.progress import EpochProgress
from rkmpc.core.versions import RKMPC_VERSION
from rkmpc.experiments.cache import ModelCache
from rkmpc.experiments.results import DataRecord, ModelRecord, TrainingRecord
from rkmpc.experiments.training import data_fell_short, estimated_for
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.io import load_model
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.learn import Learned, learn
from rkmpc.learning.pipeline import TrainConfig
from rkmpc.learning.recipes import RECIPES, DataSource, KoopmanLearner, Recipe, recipe_for
from rkmpc.sim.build import check_model
from rkmpc.sim.collect import collect, collect_excitation, excitation_lateral_accel
from rkmpc.sim.scenario import Scenario

__all__ = ["ModelPlan", "excitation_model", "learn_models", "make_model", "source_hash"]

Say = Callable[[str], None]


def source_hash(root: Path) -> str:
    """Hash (16 hex digits) of every Python source under ``root``, by relative path and content."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


@functools.cache
def _code_hash() -> str:
    """Hash of the package's sources: a model depends on the data collection (the plant, the
    controllers that drive the laps, the estimator) and the training, most of the package, so any
    change of the code trains again rather than reuse a model another code made."""
    return source_hash(Path(rkmpc.core.__file__).parent.parent)


def _record(learned: Learned, **extra: Any) -> ModelRecord:
    """The record of a model just learned."""
    model, report = learned.model, learned.report
    if not isinstance(model, KoopmanModel) or report is None:
        return ModelRecord(kind=learned.recipe.kind, identified=model, **extra)  # type: ignore[arg-type]
    err = report.multi_step_error
    return ModelRecord(
        kind=learned.recipe.kind,
        raw_samples=report.raw_count,
        augmented_samples=report.augmented_count,
        train_windows=report.train_windows,
        holdout_windows=report.holdout_windows,
        fit_time_s=report.fit_time_s,
        heldout_error_step1=err[0] if err else None,
        heldout_error_last=err[-1] if err else None,
        no_correction_error_last=report.no_correction_error[-1] if report.no_correction_error else None,
        # The state range the model was trained on; it clips states into it (no extrapolation).
        state_min=model.x_min_.tolist(),
        state_max=model.x_max_.tolist(),
        **extra,
    )


def make_model(
    recipe: Recipe,
    scenario: Scenario,
    data: Callable[[], TransitionDataset],
    data_key: Mapping[str, Any],
    *,
    seed: int,
    epochs: int | None = None,
    cache: ModelCache | None = None,
    say: Say | None = None,
) -> tuple[object, ModelRecord]:
    """The model of ``recipe`` learned from ``data()`` for the scenario's car, and its record.

    A Koopman model comes from ``cache`` when it holds one for the same data (``data_key``: the data
    set's content hash, or what makes the data when they are made on demand) and settings; the data
    are asked for only when the model is learned. ``say``, when given, hears the training's progress
    (:class:`rkmpc.core.progress.EpochProgress`).
    """
    learner = recipe.learner
    on_epoch = None
    if say is not None and isinstance(learner, KoopmanLearner):
        what = f"training the {recipe.kind} model of {recipe.controller}"
        on_epoch = EpochProgress(say, what, 100 if epochs is None else epochs)

    def build() -> tuple[object, ModelRecord]:
        t0 = time.perf_counter()
        made = data()
        collected = time.perf_counter() - t0
        learned = learn(
            recipe,
            estimated_for(recipe, made, scenario.vehicle, scenario.car.estimator),
            made_for=replace(scenario.provenance(), scale=None),
            vehicle=scenario.vehicle,
            seed=seed,
            epochs=epochs,
            on_epoch=on_epoch,
        )
        if isinstance(learned.model, KoopmanModel):
            return learned.model, _record(learned, collect_time_s=collected if collected > 0.5 else None)
        for warning in learned.model.every_warning:
            if say is not None:
                say(f"{recipe.controller}: identification warning: {warning}")
        record = ModelRecord(
            kind=recipe.kind,
            raw_samples=len(made),
            fit_time_s=time.perf_counter() - t0 - collected,
            identified=learned.model,
        )
        return learned.model, record

    if cache is None or not isinstance(learner, KoopmanLearner):
        model, record = build()
        return model, replace(record, cached=False, cache_key=None) if cache is None else record
    spec = {
        "kind": recipe.kind,
        **data_key,
        "wheelbase": scenario.vehicle.wheelbase,
        "augment": asdict(learner.augment(seed)),
        "model": learner.default_model(seed, epochs).get_params(),
        "holdout": TrainConfig().holdout,
        "estimator": asdict(scenario.car.estimator),
        "rkmpc_version": RKMPC_VERSION,
        "code": _code_hash(),
    }

    def build_json() -> tuple[KoopmanModel, dict[str, Any]]:
        model, record = build()
        return model, record.to_json()  # type: ignore[return-value]

    model, hit = cache.get_or_build(spec, build_json)
    return model, replace(ModelRecord.from_json(hit.info), cached=hit.hit, cache_key=hit.key)


def excitation_model(
    scenario: Scenario,
    recipe: Recipe,
    *,
    samples: int,
    seed: int,
    cache: ModelCache | None,
    epochs: int | None = None,
    say: Say | None = None,
) -> tuple[object, ModelRecord]:
    """The model of an ``"excitation"`` recipe (KMPC) of the scenario's car, from the cache or learned.

    Its data (random excitation of the car, which does not depend on the track) are collected only
    when the cache does not hold the model.
    """
    key: dict[str, Any] = {
        "excitation_of": scenario.vehicle_name,
        "vehicle_params": asdict(scenario.vehicle),
        "plant": scenario.car.plant.model,
        "speed_range": [scenario.limits.min_speed, scenario.limits.max_speed],
        "lateral_accel": excitation_lateral_accel(scenario),
        "dt": scenario.dt,
        "samples": samples,
        "seed": seed,
    }
    zoo = scenario.zoo_car
    if zoo is not None:
        key["car"] = zoo.describe()

    def data() -> TransitionDataset:
        return collect_excitation(scenario, n_samples=samples, seed=seed)

    return make_model(recipe, scenario, data, key, seed=seed, epochs=epochs, cache=cache, say=say)


@dataclass(frozen=True, kw_only=True)
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

    def cache(self) -> ModelCache | None:
        """The model cache to read and write, or None."""
        return ModelCache(self.cache_dir) if self.use_cache else None


def learn_models(
    scenario: Scenario, plan: ModelPlan, *, say: Say | None = None
) -> tuple[dict[str, object], TrainingRecord]:
    """Collect data and learn (or load) the model of every learned controller of the plan.

    ``say``, when given, is called with a short message before each slow stage. Every model file
    is checked against the scenario (:func:`rkmpc.sim.build.check_model`) as it is read, before
    anything is collected, trained or driven; the models learned here are made for the scenario.

    Returns
    -------
    models : dict
        The model of each learned controller, by controller name; none for a controller whose
        on-track data were refused (:class:`~rkmpc.core.errors.InputFileError` of the checks of
        the data) or whose model was (:class:`~rkmpc.core.errors.NotLearnedError`: it predicts the
        held-out laps worse than no correction), whose record then says why (``refused``).
    training : TrainingRecord
        The data and a record per model (with the contract warnings of a model file used on
        request with another car or period).

    Raises
    ------
    ContractError
        When a model file was made with another car, period or scale, unless ``plan.allow_mismatch``.
    """
    tell = say if say is not None else (lambda _msg: None)
    cache = plan.cache()
    models: dict[str, object] = {}
    records: dict[str, ModelRecord] = {}
    wanted = [(name, r) for name in plan.controllers if (r := recipe_for(name)) is not None]
    for name, recipe in wanted:
        if name in plan.model_files:
            path = str(plan.model_files[name])
            models[name] = model = load_model(path, recipe.kind)
            warned = check_model(model, scenario, source=path, allow_mismatch=plan.allow_mismatch)
            records[name] = ModelRecord(model_file=path, contract_warnings=list(warned) or None)
    to_learn = [(n, r) for n, r in wanted if n not in plan.model_files]
    on_track = [(n, r) for n, r in to_learn if r.data is DataSource.TRACK]
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
        short = data_fell_short(data)
        if short is not None:
            tell(f"warning: {short}")
        key = {"data_hash": data_record.data_hash}
        for name, recipe in on_track:
            tell(f"learning the {recipe.kind} model of {name}")
            try:
                models[name], records[name] = make_model(
                    recipe,
                    scenario,
                    lambda: data,
                    key,
                    seed=plan.seed,
                    epochs=plan.epochs,
                    cache=cache,
                    say=say,
                )
            except (InputFileError, NotLearnedError) as exc:
                # Laps no model should be learned from (the LMPC spun in them, say), or a model that
                # predicts them worse than no correction: this controller has no model and does not
                # drive; the others still do, and the record says why.
                records[name] = ModelRecord(kind=recipe.kind, refused=str(exc))
                what = (
                    "its model was refused" if isinstance(exc, NotLearnedError) else "its data were refused"
                )
                tell(f"warning: {name} not learned, {what}: {exc}")
    for name, recipe in to_learn:
        if recipe.data is DataSource.EXCITATION:
            tell(f"{name} model: {plan.excitation_samples} random-excitation samples (learned once, cached)")
            models[name], records[name] = excitation_model(
                scenario,
                recipe,
                samples=plan.excitation_samples,
                seed=plan.seed,
                cache=cache,
                epochs=plan.epochs,
                say=say,
            )
    ordered = {name: records[name] for name in plan.controllers if name in records}
    return models, TrainingRecord(data=data_record, models=ordered)
