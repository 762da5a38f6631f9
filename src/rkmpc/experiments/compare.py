"""One track, every controller: collect LMPC laps, learn, drive, measure (the paper's Table I).

Two laps of LMPC data train the residual models and identify ``lmpc-id``; the
KMPC model is trained on random-excitation data of the car (it does not depend
on the track, and is cached by content hash so that it is trained once per car
and setting); see :mod:`rkmpc.experiments.models`. Every controller then
drives one flying lap from the same start; with a fault, each drives a second
lap with the fault and the effect is classified (:func:`fault_effect`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

from rkmpc.analysis.metrics import LapMetrics
from rkmpc.control.learned.residual_config import ResidualMPCConfig
from rkmpc.control.learned.rkmpc import PaperResidualKoopmanMPC, ResidualKoopmanMPC
from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer
from rkmpc.core.versions import versions
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.experiments.results import ControllerRun, FaultOutcome, TrackResult
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.carfile import CarConfig, TrainingSettings
from rkmpc.sim.closed_loop import SimResult
from rkmpc.sim.faults import DEFAULT_NOISE, get_fault
from rkmpc.sim.log import StepLog
from rkmpc.sim.run import RunSpec, run_record
from rkmpc.sim.scenario import Scenario, VehiclePreset, load_scenario, vehicle_preset
from rkmpc.track.speed_profile import SpeedLimits
from rkmpc.vehicle.zoo import get_car

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
ALL_CONTROLLERS = ("pp", "lmpc", "lmpc-id", "nmpc", "nmpc-dynamic", "kmpc", "rkmpc-paper", "rkmpc")

#: Residual MPC settings of the two RKMPC variants for the 1:10 car (tuned on builtin, Monza and
#: Budapest, then fixed); other cars take theirs from their preset (:data:`rkmpc.sim.scenario.VEHICLES`).
RKMPC_CONFIG = ResidualKoopmanMPC.default_config
RKMPC_PAPER_CONFIG = PaperResidualKoopmanMPC.default_config

#: Relative growth of the mean lateral error above which a fault counts as degrading a controller.
DEGRADE_THRESHOLD = 0.25


@dataclass(frozen=True)
class CompareConfig:
    """Settings of :func:`compare`.

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
    rkmpc : ResidualMPCConfig or None
        Residual MPC settings of ``rkmpc``; None for the vehicle preset's.
    rkmpc_paper : ResidualMPCConfig or None
        Residual MPC settings of ``rkmpc-paper``; None for the vehicle preset's.
    raceline : str or None
        Race-line CSV to track instead of the centre line.
    fault : str or None
        Name of a fault (:data:`rkmpc.sim.faults.FAULTS`); each controller then also drives a lap with it.
    kmpc_samples : int
        Random-excitation samples of the KMPC model.
    cache_dir : str or None
        Model cache folder (:func:`rkmpc.experiments.cache.default_cache_dir` when None).
    use_cache : bool
        Read and write trained models in the cache.
    model_files : tuple of (str, str)
        ``(controller, path)`` pairs of models to use instead of training.
    noise : bool
        Drive every run with the default measurement noise (:data:`rkmpc.sim.faults.DEFAULT_NOISE`),
        seeded by ``seed``.
    run_laps : int
        Laps each controller drives.
    epochs : int or None
        Training epochs of every learned model (None: the recipes' defaults); small values make
        quick trials.
    car : str or None
        A car of the zoo (:func:`rkmpc.vehicle.zoo.get_car`) to drive instead of the vehicle
        preset's plant; the data are recorded on it and every controller keeps the preset's
        nominal parameters.
    allow_mismatch : bool
        Drive with model files made with another car, period or track scale than the track's
        scenario (refused otherwise); the warnings go to the result and to the runs' logs.
    limits : SpeedLimits or None
        Speed-profile limits (the pace; :meth:`rkmpc.track.speed_profile.SpeedLimits.at_pace`);
        None: the vehicle preset's.
    car_config : CarConfig or None
        The car as a car file set it up (:mod:`rkmpc.sim.carfile`): its parameters and the
        controllers' settings replace the ``vehicle`` preset's, whose name it must have. The
        fields above stay authoritative (car, limits, seed, laps, samples, epochs): the copy kept
        here is brought in line with them, and the results record it as the effective configuration.
    """

    track: str
    scale: float | None = None
    vehicle: str = "f1tenth"
    controllers: Sequence[str] = LEARNED_CONTROLLERS
    laps: int = 2
    seed: int = 0
    kmpc_model: str | None = None
    rkmpc: ResidualMPCConfig | None = None
    rkmpc_paper: ResidualMPCConfig | None = None
    raceline: str | None = None
    fault: str | None = None
    kmpc_samples: int = 50_000
    cache_dir: str | None = None
    use_cache: bool = True
    model_files: tuple[tuple[str, str], ...] = ()
    noise: bool = False
    run_laps: int = 1
    epochs: int | None = None
    car: str | None = None
    allow_mismatch: bool = False
    limits: SpeedLimits | None = None
    car_config: CarConfig | None = None

    def __post_init__(self) -> None:
        if self.limits is not None and not isinstance(self.limits, SpeedLimits):
            raise ParameterError(f"CompareConfig.limits must be SpeedLimits or None, got {self.limits!r}")
        for name, minimum in (("laps", 1), ("seed", 0), ("run_laps", 1), ("kmpc_samples", 1000)):
            value = getattr(self, name)
            if not is_integer(value, minimum):
                raise ParameterError(f"CompareConfig.{name} must be an integer >= {minimum}, got {value!r}")
        if self.epochs is not None and not is_integer(self.epochs, 1):
            raise ParameterError(f"CompareConfig.epochs must be None or an integer >= 1, got {self.epochs!r}")
        if not self.controllers:
            raise ParameterError("CompareConfig.controllers is empty")
        if self.fault is not None:
            get_fault(self.fault)
        if self.car is not None:
            get_car(self.car)
        if self.car_config is not None:
            self._align_car_config(self.car_config)

    def _align_car_config(self, car: CarConfig) -> None:
        if not isinstance(car, CarConfig):
            raise ParameterError(f"CompareConfig.car_config must be a CarConfig or None, got {car!r}")
        if car.preset != self.vehicle:
            raise ParameterError(
                f"CompareConfig: car_config is a {car.preset!r} car but vehicle is {self.vehicle!r}"
            )
        training = TrainingSettings(
            epochs=self.epochs, seed=self.seed, data_laps=self.laps, kmpc_samples=self.kmpc_samples
        )
        limits = self.limits if self.limits is not None else car.limits
        controllers = car.controllers
        if self.rkmpc is not None:
            controllers = replace(controllers, rkmpc=self.rkmpc)
        if self.rkmpc_paper is not None:
            controllers = replace(controllers, rkmpc_paper=self.rkmpc_paper)
        aligned = replace(car, car=self.car, limits=limits, training=training, controllers=controllers)
        object.__setattr__(self, "car_config", aligned)

    def plan(self) -> ModelPlan:
        """What to learn for the comparison."""
        files = dict(self.model_files)
        if self.kmpc_model is not None:
            files.setdefault("kmpc", self.kmpc_model)
        return ModelPlan(
            controllers=tuple(self.controllers),
            laps=self.laps,
            seed=self.seed,
            excitation_samples=self.kmpc_samples,
            model_files=files,
            cache_dir=self.cache_dir,
            use_cache=self.use_cache,
            epochs=self.epochs,
            allow_mismatch=self.allow_mismatch,
        )

    def residual_config(self, controller: str) -> ResidualMPCConfig:
        """The residual MPC settings of ``rkmpc`` or ``rkmpc-paper``: given here, else the preset's."""
        given, default = {
            "rkmpc": (self.rkmpc, RKMPC_CONFIG),
            "rkmpc-paper": (self.rkmpc_paper, RKMPC_PAPER_CONFIG),
        }[controller]
        if given is not None:
            return given
        preset = self.vehicle_preset().options_for(controller)
        tuned: ResidualMPCConfig = preset["config"] if "config" in preset else default
        return tuned

    def vehicle_preset(self) -> VehiclePreset:
        """The car's preset: the car file's when given, else the ``vehicle`` preset."""
        return vehicle_preset(self.vehicle) if self.car_config is None else self.car_config.vehicle_preset()

    def scenario(self) -> Scenario:
        """The track, car and reference of the comparison."""
        return load_scenario(
            self.track,
            raceline=self.raceline,
            scale=self.scale,
            vehicle=self.vehicle,
            car=self.car,
            limits=self.limits,
            preset=None if self.car_config is None else self.car_config.vehicle_preset(),
        )


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
    options, training = learn_models(scenario, config.plan(), say=say)
    residual = {name: config.residual_config(name) for name in ("rkmpc", "rkmpc-paper")}
    for name, cfg in residual.items():
        if name in options:
            options[name]["config"] = cfg
    noise = DEFAULT_NOISE if config.noise else None
    runs: dict[str, ControllerRun] = {}
    faulted: dict[str, ControllerRun] = {}
    effects: dict[str, str] = {}
    specs: list[RunSpec] = []

    def drive(label: str, spec: RunSpec) -> tuple[ControllerRun, LapMetrics]:
        specs.append(spec)
        own = options[spec.controller] if spec.controller in options else None
        result, metrics = run_controller(scenario, spec, controller_options=own)
        result.log.metadata.update({"track": scenario.track.name})
        record = training.models[spec.controller] if spec.controller in training.models else None
        if record is not None and record.contract_warnings:
            result.log.metadata["contract_warnings"] = record.contract_warnings
        if logs is not None:
            logs[label] = result.log
        if on_run is not None:
            on_run(label, result)
        return ControllerRun(metrics=metrics, outcome=result.outcome, failure=result.failure), metrics

    for name in config.controllers:
        if say is not None:
            say(f"driving {name}")
        runs[name], nominal = drive(name, RunSpec(name, laps=config.run_laps, seed=config.seed, noise=noise))
        if config.fault is not None:
            spec = RunSpec(name, laps=config.run_laps, seed=config.seed, noise=noise, fault=config.fault)
            faulted[name], metrics = drive(f"{name}+{config.fault}", spec)
            effects[name] = fault_effect(nominal, metrics, faulted[name].outcome)
    record: dict[str, Any] = {
        **run_record(scenario, specs),
        "seed": config.seed,
        "laps_of_data": config.laps,
        "rkmpc": asdict(residual["rkmpc"]),
        "rkmpc_paper": asdict(residual["rkmpc-paper"]),
        "kmpc_model": config.kmpc_model,
        "kmpc_samples": config.kmpc_samples,
        "fault": config.fault,
        "allow_mismatch": config.allow_mismatch,
        "car_config": None if config.car_config is None else config.car_config.to_json(),
        "versions": versions(),
    }
    fault = None if config.fault is None else FaultOutcome(config.fault, faulted, effects)
    return TrackResult(
        track=scenario.track.name, controllers=runs, training=training, config=record, fault=fault
    )
