"""One track, every controller: collect LMPC laps, learn, drive, measure.

This is the experiment of the paper's Table I for one track: two laps of LMPC
data train the residual models and identify ``lmpc-id``; the KMPC model is
trained on random-excitation data of the car (it does not depend on the
track, and is cached by content hash so that it is trained once per car and
setting). Every controller then drives one flying lap from the same start; with
a fault, each drives a second lap with the fault and the effect is classified.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import rkmpc
from rkmpc.control.factory import MODEL_KIND
from rkmpc.control.rkmpc import PaperResidualKoopmanMPC, ResidualKoopmanMPC, ResidualMPCConfig
from rkmpc.errors import ParameterError
from rkmpc.experiments.cache import ModelCache
from rkmpc.experiments.runner import DEFAULT_NOISE, RunSpec, run_controller, run_record, versions
from rkmpc.learning.augmentation import AugmentConfig
from rkmpc.learning.collect import collect, collect_excitation
from rkmpc.learning.dataset import TransitionDataset
from rkmpc.learning.identification import identify
from rkmpc.learning.koopman import KoopmanModel
from rkmpc.learning.pipeline import TrainConfig, default_model_options, train_model
from rkmpc.scenario import Scenario, load_scenario, vehicle_preset
from rkmpc.sim.log import StepLog

#: Controllers of the learned comparison, in table order.
LEARNED_CONTROLLERS = ("lmpc", "lmpc-id", "rkmpc-paper", "rkmpc", "kmpc")

#: Every controller of the paper's comparison plus the extra baselines, in table order.
ALL_CONTROLLERS = ("pp", "lmpc", "lmpc-id", "nmpc", "nmpc-dynamic", "kmpc", "rkmpc-paper", "rkmpc")

#: Residual MPC settings of the two RKMPC variants (tuned on builtin, Monza and Budapest, then fixed).
RKMPC_CONFIG = ResidualKoopmanMPC.default_config
RKMPC_PAPER_CONFIG = PaperResidualKoopmanMPC.default_config

#: Conversion ratio of the local-frame augmentation for the random-excitation data of KMPC
#: (the excitation data are long and varied, so a few origins per trajectory suffice).
KMPC_AUGMENT_RATIO = 0.05

#: Relative growth of the mean lateral error above which a fault counts as degrading a controller.
DEGRADE_THRESHOLD = 0.25

# Residual model kinds of the two RKMPC variants.
_RESIDUAL_KINDS = {"rkmpc": "residual", "rkmpc-paper": "paper"}


@dataclass(frozen=True)
class TrackStudy:
    """Settings of :func:`evaluate_track`.

    Parameters
    ----------
    track : str
        Built-in name or centre-line CSV path.
    scale : float or None
        Track scale (default: the vehicle's).
    vehicle : str
        Vehicle preset.
    controllers : sequence of str
        Controllers to drive.
    laps : int
        Laps of LMPC data to learn from.
    seed : int
        Seed of the data collection, training and runs.
    kmpc_model : str or None
        Path of a trained ``koopman`` model for ``kmpc``; when None it is
        trained on ``kmpc_samples`` random-excitation samples (cached).
    rkmpc : ResidualMPCConfig
        Residual MPC settings of ``rkmpc``.
    rkmpc_paper : ResidualMPCConfig
        Residual MPC settings of ``rkmpc-paper``.
    raceline : str or None
        Race-line CSV to track instead of the centre line.
    fault : str or None
        Name of a fault (:data:`rkmpc.experiments.faults.FAULTS`); each
        controller then also drives a lap with it.
    kmpc_samples : int
        Random-excitation samples of the KMPC model.
    cache_dir : str or None
        Model cache folder (:func:`rkmpc.experiments.cache.default_cache_dir` when None).
    use_cache : bool
        Read and write trained models in the cache.
    model_files : tuple of (str, str)
        ``(controller, path)`` pairs of models to use instead of training.
    noise : bool
        Drive every run with the default measurement noise
        (:data:`rkmpc.experiments.runner.DEFAULT_NOISE`), seeded by ``seed``.
    run_laps : int
        Laps each controller drives.
    epochs : int or None
        Training epochs of every learned model (None: the defaults of
        :func:`rkmpc.learning.pipeline.default_model_options`); small values make quick trials.
    """

    track: str
    scale: float | None = None
    vehicle: str = "f1tenth"
    controllers: Sequence[str] = LEARNED_CONTROLLERS
    laps: int = 2
    seed: int = 0
    kmpc_model: str | None = None
    rkmpc: ResidualMPCConfig = field(default_factory=lambda: RKMPC_CONFIG)
    rkmpc_paper: ResidualMPCConfig = field(default_factory=lambda: RKMPC_PAPER_CONFIG)
    raceline: str | None = None
    fault: str | None = None
    kmpc_samples: int = 50_000
    cache_dir: str | None = None
    use_cache: bool = True
    model_files: tuple[tuple[str, str], ...] = ()
    noise: bool = False
    run_laps: int = 1
    epochs: int | None = None

    def __post_init__(self) -> None:
        if isinstance(self.laps, bool) or not isinstance(self.laps, int) or self.laps < 1:
            raise ParameterError(f"TrackStudy.laps must be an integer >= 1, got {self.laps!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ParameterError(f"TrackStudy.seed must be an integer >= 0, got {self.seed!r}")
        if not isinstance(self.kmpc_samples, int) or self.kmpc_samples < 1000:
            raise ParameterError(
                f"TrackStudy.kmpc_samples must be an integer >= 1000, got {self.kmpc_samples!r}"
            )
        if isinstance(self.run_laps, bool) or not isinstance(self.run_laps, int) or self.run_laps < 1:
            raise ParameterError(f"TrackStudy.run_laps must be an integer >= 1, got {self.run_laps!r}")
        if self.epochs is not None and (
            isinstance(self.epochs, bool) or not isinstance(self.epochs, int) or self.epochs < 1
        ):
            raise ParameterError(f"TrackStudy.epochs must be None or an integer >= 1, got {self.epochs!r}")
        if not self.controllers:
            raise ParameterError("TrackStudy.controllers is empty")


def _code_hash() -> str:
    """Hash of the sources that shape training data and models (vehicle and learning packages)."""
    root = Path(rkmpc.__file__).parent
    digest = hashlib.sha256()
    for sub in ("learning", "vehicle"):
        for path in sorted((root / sub).glob("*.py")):
            digest.update(path.name.encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _report_info(report: Any, kind: str, model: KoopmanModel) -> dict[str, Any]:
    info = asdict(report)
    err = info.pop("multi_step_error")
    return {
        "kind": kind,
        "raw_samples": info["raw_count"],
        "augmented_samples": info["augmented_count"],
        "train_windows": info["train_windows"],
        "holdout_windows": info["holdout_windows"],
        "fit_time_s": info["fit_time_s"],
        "heldout_error_step1": err[0] if err else None,
        "heldout_error_last": err[-1] if err else None,
        # The state range the model was trained on; it clips states into it (no extrapolation).
        "state_min": model.x_min_.tolist(),
        "state_max": model.x_max_.tolist(),
    }


def _options(kind: str, seed: int, epochs: int | None) -> dict[str, Any]:
    options = default_model_options(kind, seed=seed)
    if epochs is not None:
        options["epochs"] = epochs
    return options


def train_kmpc(
    scenario: Scenario, *, samples: int, seed: int, cache: ModelCache | None, epochs: int | None = None
) -> tuple[KoopmanModel, dict[str, Any]]:
    """The KMPC model of the scenario's car, from the cache or trained on random excitation.

    Returns
    -------
    model : KoopmanModel
    info : dict
        ``raw_samples``, ``augmented_samples``, ``fit_time_s``,
        ``collect_time_s``, ``cached`` and ``cache_key``.
    """
    augment = AugmentConfig(ratio=KMPC_AUGMENT_RATIO, seed=seed)
    options = _options("koopman", seed, epochs)
    recipe = {
        "name": "kmpc",
        "kind": "koopman",
        "vehicle": scenario.vehicle_name,
        "vehicle_params": asdict(scenario.vehicle),
        "plant": vehicle_preset(scenario.vehicle_name).plant,
        "speed_range": [scenario.limits.min_speed, scenario.limits.max_speed],
        "dt": scenario.dt,
        "samples": samples,
        "seed": seed,
        "augment": asdict(augment),
        "model": options,
        "rkmpc_version": rkmpc.__version__,
        "code": _code_hash(),
    }

    def build() -> tuple[KoopmanModel, dict[str, Any]]:
        t0 = time.perf_counter()
        data = collect_excitation(scenario, n_samples=samples, seed=seed)
        collect_time = time.perf_counter() - t0
        model, report = train_model(
            data, scenario.vehicle.wheelbase, TrainConfig(kind="koopman", augment=augment, model=options)
        )
        return model, {**_report_info(report, "koopman", model), "collect_time_s": collect_time}

    if cache is None:
        model, info = build()
        return model, {**info, "cached": False, "cache_key": None}
    model, hit = cache.get_or_build(recipe, build)
    return model, {**hit.info, "cached": hit.hit, "cache_key": hit.key}


def train_residual(
    data: TransitionDataset,
    scenario: Scenario,
    *,
    kind: str,
    seed: int,
    cache: ModelCache | None,
    epochs: int | None = None,
) -> tuple[KoopmanModel, dict[str, Any]]:
    """A residual model (``residual`` or ``paper``) of on-track data, from the cache or trained now."""
    config = TrainConfig(kind=kind, augment=AugmentConfig(seed=seed), model=_options(kind, seed, epochs))

    def build() -> tuple[KoopmanModel, dict[str, Any]]:
        model, report = train_model(data, scenario.vehicle.wheelbase, config)
        return model, _report_info(report, kind, model)

    if cache is None:
        model, info = build()
        return model, {**info, "cached": False, "cache_key": None}
    recipe = {
        "name": kind,
        "kind": kind,
        "data_hash": data.content_hash(),
        "wheelbase": scenario.vehicle.wheelbase,
        "augment": asdict(config.augment),
        "model": config.model,
        "holdout": config.holdout,
        "rkmpc_version": rkmpc.__version__,
        "code": _code_hash(),
    }
    model, hit = cache.get_or_build(recipe, build)
    return model, {**hit.info, "cached": hit.hit, "cache_key": hit.key}


def prepare_controllers(
    scenario: Scenario, study: TrackStudy, *, say: Callable[[str], None] | None = None
) -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    """Collect data and train (or load) every model the study's controllers need.

    ``say``, when given, is called with a short message before each slow stage.

    Returns
    -------
    options : dict
        Controller options (``model``, ``config``) by controller name.
    training : dict
        What was learned: ``data`` (raw samples, outcome, collection time)
        and, per learned controller, sample counts, training time and
        whether the model came from the cache or a file.
    """
    from rkmpc.learning.model_io import load_model

    tell = say if say is not None else (lambda _msg: None)
    names = list(study.controllers)
    given = dict(study.model_files)
    if study.kmpc_model is not None:
        given.setdefault("kmpc", study.kmpc_model)
    unknown = sorted(set(given) - set(MODEL_KIND))
    if unknown:
        raise ParameterError(
            f"model files given for {unknown}, which take no model; learned: {sorted(MODEL_KIND)}"
        )
    cache = ModelCache(study.cache_dir) if study.use_cache else None
    options: dict[str, dict[str, Any]] = {}
    training: dict[str, Any] = {}
    configs = {"rkmpc": study.rkmpc, "rkmpc-paper": study.rkmpc_paper}
    for name in names:
        if name in given:
            options[name] = {"model": load_model(given[name], MODEL_KIND[name])}
            training[name] = {"model_file": str(given[name])}
    on_track = [n for n in names if n in ("lmpc-id", *_RESIDUAL_KINDS) and n not in given]
    if on_track:
        tell(f"collecting {study.laps} LMPC laps of data")
        t0 = time.perf_counter()
        data = collect(scenario, controller="lmpc", laps=study.laps, seed=study.seed)
        training["data"] = {
            "controller": "lmpc",
            "laps": study.laps,
            "raw_samples": len(data),
            "outcome": data.metadata["outcome"],
            "collect_time_s": time.perf_counter() - t0,
            "data_hash": data.content_hash(),
        }
        for name in on_track:
            if name == "lmpc-id":
                t0 = time.perf_counter()
                ident = identify(data, scenario.vehicle.wheelbase)
                training[name] = {
                    "kind": "identified",
                    "raw_samples": len(data),
                    "fit_time_s": time.perf_counter() - t0,
                    "identified": asdict(ident),
                }
                options[name] = {"model": ident}
            else:
                tell(f"training the {_RESIDUAL_KINDS[name]} model of {name}")
                model, info = train_residual(
                    data,
                    scenario,
                    kind=_RESIDUAL_KINDS[name],
                    seed=study.seed,
                    cache=cache,
                    epochs=study.epochs,
                )
                training[name] = info
                options[name] = {"model": model}
    if "kmpc" in names and "kmpc" not in given:
        tell(f"KMPC model: {study.kmpc_samples} random-excitation samples (trained once, then cached)")
        model, info = train_kmpc(
            scenario, samples=study.kmpc_samples, seed=study.seed, cache=cache, epochs=study.epochs
        )
        training["kmpc"] = info
        options["kmpc"] = {"model": model}
    for name, cfg in configs.items():
        if name in options:
            options[name]["config"] = cfg
    return options, training


def fault_effect(nominal: dict[str, Any], faulted: dict[str, Any], outcome: str) -> str:
    """Classify what a fault did to a controller.

    Returns ``"leaves the track"`` (the faulted run went off track), ``"does
    not finish"`` (timed out or diverged), ``"degrades"`` (finished, but the
    mean lateral error grew by more than :data:`DEGRADE_THRESHOLD`) or
    ``"completes"``.
    """
    if outcome == "off_track":
        return "leaves the track"
    if not faulted["completed"]:
        return "does not finish"
    a, b = faulted["lateral_error_mean_m"], nominal["lateral_error_mean_m"]
    if not nominal["completed"] or a is None or b is None:
        return "completes"
    return "degrades" if a > (1.0 + DEGRADE_THRESHOLD) * b else "completes"


def evaluate_track(
    study: TrackStudy,
    *,
    logs: dict[str, StepLog] | None = None,
    on_run: Callable[[str, Any], None] | None = None,
    say: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Learn on ``study.laps`` LMPC laps of the track and drive every controller one lap.

    Parameters
    ----------
    study : TrackStudy
        What to run.
    logs : dict, optional
        Filled with the step log of each run, by controller name (and
        ``"<name>+<fault>"`` for the faulted runs).
    on_run : callable, optional
        Called as ``on_run(label, result)`` after each run.
    say : callable, optional
        Called with a short message before each slow stage.

    Returns
    -------
    dict
        ``track``, ``controllers`` (metrics per controller, with ``outcome``),
        ``training`` (sample counts, fit times, cache use, identified
        parameters), ``config``, and with a fault ``fault`` (name),
        ``faulted`` (metrics under the fault) and ``fault_effect`` (per controller).
    """
    scenario = load_scenario(study.track, raceline=study.raceline, scale=study.scale, vehicle=study.vehicle)
    if study.fault is not None:
        from rkmpc.experiments.faults import FAULTS

        if study.fault not in FAULTS:
            raise ParameterError(f"unknown fault {study.fault!r}; known: {sorted(FAULTS)}")
    options, training = prepare_controllers(scenario, study, say=say)
    noise = DEFAULT_NOISE if study.noise else None
    names = list(study.controllers)
    results: dict[str, dict[str, Any]] = {}
    faulted: dict[str, dict[str, Any]] = {}
    effects: dict[str, str] = {}
    specs: list[RunSpec] = []
    for name in names:
        if say is not None:
            say(f"driving {name}")
        spec = RunSpec(name, laps=study.run_laps, seed=study.seed, noise=noise)
        specs.append(spec)
        result, metrics = run_controller(scenario, spec, controller_options=options.get(name))
        result.log.metadata.update({"track": scenario.track.name})
        results[name] = {**metrics, "outcome": result.outcome}
        if logs is not None:
            logs[name] = result.log
        if on_run is not None:
            on_run(name, result)
        if study.fault is not None:
            fspec = RunSpec(name, laps=study.run_laps, seed=study.seed, noise=noise, fault=study.fault)
            specs.append(fspec)
            fres, fmetrics = run_controller(scenario, fspec, controller_options=options.get(name))
            faulted[name] = {**fmetrics, "outcome": fres.outcome}
            effects[name] = fault_effect(results[name], fmetrics, fres.outcome)
            if logs is not None:
                logs[f"{name}+{study.fault}"] = fres.log
            if on_run is not None:
                on_run(f"{name}+{study.fault}", fres)
    out: dict[str, Any] = {
        "track": scenario.track.name,
        "controllers": results,
        "training": training,
        "config": {
            **run_record(scenario, specs),
            "seed": study.seed,
            "laps_of_data": study.laps,
            "rkmpc": asdict(study.rkmpc),
            "rkmpc_paper": asdict(study.rkmpc_paper),
            "kmpc_model": study.kmpc_model,
            "kmpc_samples": study.kmpc_samples,
            "fault": study.fault,
            "versions": versions(),
        },
    }
    if study.fault is not None:
        out.update({"fault": study.fault, "faulted": faulted, "fault_effect": effects})
    return out
