"""One track, every controller: collect LMPC laps, learn, drive, measure (the paper's Table I).

Two laps of LMPC data train the residual models and identify ``lmpc-id``; the
KMPC model is trained on random-excitation data of the car (it does not depend
on the track, and is cached by content hash so that it is trained once per car
and setting); see :mod:`rkmpc.experiments.models`. Every controller then
drives one flying lap from the same start; with a fault, each drives a second
lap with the fault and the effect is classified (:func:`fault_effect`). A learned controller whose
laps of data were refused (the LMPC spun in them) does not drive: its run is
:data:`~rkmpc.experiments.results.NOT_LEARNED` with the reason, and the others' figures stand.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.control.registry import CONTROLLERS
from rkmpc.core.errors import ParameterError
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.core.versions import versions
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.experiments.results import NOT_LEARNED, ControllerRun, FaultOutcome, TrackResult
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.closed_loop import SimResult
from rkmpc.sim.faults import DEFAULT_NOISE, get_fault
from rkmpc.sim.log import StepLog
from rkmpc.sim.run import RunSpec, build_plant, run_record
from rkmpc.sim.scenario import Scenario

__all__ = [
    "ALL_CONTROLLERS",
    "DEGRADE_THRESHOLD",
    "LEARNED_CONTROLLERS",
    "CompareConfig",
    "compare",
    "fault_effect",
]

#: Controllers of the learned comparison, in table order.
LEARNED_CONTROLLERS = ("lmpc", "lmpc-id", "rkmpc-paper", "rkmpc", "kmpc")

#: Every controller of the paper's comparison plus the extra baselines, in table order.
ALL_CONTROLLERS = ("pp", "lmpc", "lmpc-id", "nmpc", "nmpc-dynamic", "nmpc-id", "kmpc", "rkmpc-paper", "rkmpc")

#: Relative growth of the mean lateral error above which a fault counts as degrading a controller.
DEGRADE_THRESHOLD = 0.25


@dataclass(frozen=True, kw_only=True)
class CompareConfig:
    """Settings of :func:`compare`.

    Parameters
    ----------
    track : str
        Built-in name or centre-line CSV path.
    car : CarConfig
        The car: its nominal model, plant (a zoo car), limits (the pace), every controller's
        settings and how the learned controllers learn (seed, laps of data, epochs, samples).
    controllers : sequence of str
        Controllers to drive.
    scale : float or None
        Track scale (default: the car's ``file_scale``).
    raceline : str or None
        Race-line CSV to track instead of the centre line.
    run_laps : int
        Laps each controller drives.
    noise : bool
        Drive every run with the default measurement noise (:data:`rkmpc.sim.faults.DEFAULT_NOISE`),
        seeded by the car's training seed.
    fault : str or None
        Name of a fault (:data:`rkmpc.sim.faults.FAULTS`); each controller then also drives a lap with it.
    model_files : tuple of (str, str)
        ``(controller, path)`` pairs of models to use instead of learning.
    allow_mismatch : bool
        Drive with model files made with another car, period or track scale than the track's
        scenario (refused otherwise); the warnings go to the result and to the runs' logs.
    cache_dir : str or None
        Model cache folder (:func:`rkmpc.experiments.cache.default_cache_dir` when None).
    use_cache : bool
        Read and write trained models in the cache.
    """

    track: str
    car: CarConfig = field(default_factory=lambda: load_preset("f1tenth"))
    controllers: Sequence[str] = LEARNED_CONTROLLERS
    scale: float | None = None
    raceline: str | None = None
    run_laps: int = 1
    noise: bool = False
    fault: str | None = None
    model_files: tuple[tuple[str, str], ...] = ()
    allow_mismatch: bool = False
    cache_dir: str | None = None
    use_cache: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.car, CarConfig):
            raise ParameterError(f"CompareConfig.car must be a CarConfig, got {self.car!r}")
        if self.scale is not None and not is_positive_number(self.scale):
            raise ParameterError(f"CompareConfig.scale must be a positive number or None, got {self.scale!r}")
        if not is_integer(self.run_laps, 1):
            raise ParameterError(f"CompareConfig.run_laps must be an integer >= 1, got {self.run_laps!r}")
        if not self.controllers:
            raise ParameterError("CompareConfig.controllers is empty")
        object.__setattr__(self, "controllers", tuple(CONTROLLERS.check(n) for n in self.controllers))
        object.__setattr__(self, "model_files", tuple((str(n), str(p)) for n, p in self.model_files))
        if self.fault is not None:
            get_fault(self.fault)

    @property
    def seed(self) -> int:
        """The seed of the data collection, training and runs (the car's training seed)."""
        return self.car.training.seed

    def plan(self) -> ModelPlan:
        """What to learn for the comparison."""
        training = self.car.training
        return ModelPlan(
            controllers=tuple(self.controllers),
            laps=training.data_laps,
            seed=training.seed,
            excitation_samples=training.kmpc_samples,
            model_files=dict(self.model_files),
            cache_dir=self.cache_dir,
            use_cache=self.use_cache,
            epochs=training.epochs,
            allow_mismatch=self.allow_mismatch,
        )

    def scenario(self) -> Scenario:
        """The track, car and reference of the comparison."""
        return Scenario.from_car(self.car, self.track, scale=self.scale, raceline=self.raceline)

    def check_fault(self, scenario: Scenario) -> None:
        """Refuse a fault that cannot apply to this car before anything is learned or driven.

        Raises
        ------
        ParameterError
            Naming the fault and the plant (a fault of the car on a zoo car, say).
        """
        if self.fault is not None:
            build_plant(scenario, RunSpec(self.controllers[0], seed=self.seed, fault=self.fault))

    def to_json(self) -> dict[str, Any]:
        """Every setting, the car written out whole (:meth:`CarConfig.to_json`)."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "car"}
        return {**to_json_ready(out), "car": self.car.to_json()}


def fault_effect(nominal: Mapping[str, Any], faulted: Mapping[str, Any], outcome: str) -> str:
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


def compare(
    config: CompareConfig,
    *,
    logs: dict[str, StepLog] | None = None,
    on_run: Callable[[str, SimResult], None] | None = None,
    say: Callable[[str], None] | None = None,
) -> TrackResult:
    """Learn on ``config.laps`` LMPC laps of the track and drive every controller.

    Parameters
    ----------
    config : CompareConfig
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
    TrackResult
    """
    scenario = config.scenario()
    config.check_fault(scenario)
    models, training = learn_models(scenario, config.plan(), say=say)
    seed = config.seed
    noise = DEFAULT_NOISE if config.noise else None
    runs: dict[str, ControllerRun] = {}
    faulted: dict[str, ControllerRun] = {}
    effects: dict[str, str] = {}
    specs: list[RunSpec] = []

    def drive(label: str, spec: RunSpec) -> tuple[ControllerRun, LapMetrics]:
        specs.append(spec)
        model = models[spec.controller] if spec.controller in models else None
        result, metrics = run_controller(scenario, spec, model=model, allow_mismatch=config.allow_mismatch)
        result.log.metadata.update({"track": scenario.track.name})
        record = training.models[spec.controller] if spec.controller in training.models else None
        if record is not None and record.contract_warnings:
            result.log.metadata["contract_warnings"] = record.contract_warnings
        if logs is not None:
            logs[label] = result.log
        if on_run is not None:
            on_run(label, result)
        run = ControllerRun(
            metrics=metrics, outcome=result.outcome, failure=result.failure, diagnostics=result.diagnostics
        )
        return run, metrics

    for name in config.controllers:
        refused = training.models[name].refused if name in training.models else None
        if refused is not None:
            runs[name] = ControllerRun(metrics=LapMetrics.not_driven(), outcome=NOT_LEARNED, failure=refused)
            if config.fault is not None:
                faulted[name], effects[name] = runs[name], "not learned"
            continue
        if say is not None:
            say(f"driving {name}")
        runs[name], nominal = drive(name, RunSpec(name, laps=config.run_laps, seed=seed, noise=noise))
        if config.fault is not None:
            spec = RunSpec(name, laps=config.run_laps, seed=seed, noise=noise, fault=config.fault)
            faulted[name], metrics = drive(f"{name}+{config.fault}", spec)
            effects[name] = fault_effect(nominal, metrics, faulted[name].outcome)
    controllers = scenario.car.controllers
    record: dict[str, Any] = {
        **run_record(scenario, specs),
        "seed": seed,
        "laps_of_data": scenario.car.training.data_laps,
        "rkmpc": asdict(controllers.rkmpc),
        "rkmpc_paper": asdict(controllers.rkmpc_paper),
        "kmpc_samples": scenario.car.training.kmpc_samples,
        "fault": config.fault,
        "allow_mismatch": config.allow_mismatch,
        "model_files": dict(config.model_files),
        "car_config": scenario.car.to_json(),
        "versions": versions(),
    }
    fault = None if config.fault is None else FaultOutcome(config.fault, faulted, effects)
    return TrackResult(
        track=scenario.track.name, controllers=runs, training=training, config=record, fault=fault
    )
