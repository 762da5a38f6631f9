"""Run controllers in a scenario and collect their metrics."""

from __future__ import annotations

import platform
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from importlib.metadata import PackageNotFoundError, version
from typing import Any

from rkmpc.analysis.metrics import lap_metrics
from rkmpc.control.factory import make_controller
from rkmpc.errors import ParameterError
from rkmpc.experiments.faults import DEFAULT_NOISE, NoiseFault, get_fault
from rkmpc.scenario import Scenario, vehicle_preset
from rkmpc.sim.closed_loop import SimConfig, SimResult, simulate
from rkmpc.vehicle.plant import Plant, make_plant
from rkmpc.vehicle.wrappers import NoiseStd, ObservationNoise

__all__ = ["DEFAULT_NOISE", "RunSpec", "build_plant", "run_controller", "run_record", "versions"]


@dataclass(frozen=True)
class RunSpec:
    """What one closed-loop run drives.

    Parameters
    ----------
    controller : str
        Controller registry name.
    laps : int
        Laps to drive.
    seed : int
        Seed of every random choice of the run (measurement noise, faults).
    noise : NoiseStd or None
        Measurement noise, or None for exact observations.
    fault : str or None
        Name of a fault in :data:`rkmpc.experiments.faults.FAULTS`
        (``"noise"``, ``"delay"``, ``"friction"``, ``"heavy"``) applied to the
        plant, or None for the nominal plant. ``"noise"`` and ``noise``
        exclude each other.

    Raises
    ------
    ParameterError
        If ``fault`` is not a registered name, or is ``"noise"`` while
        ``noise`` is given.
    """

    controller: str
    laps: int = 1
    seed: int = 0
    noise: NoiseStd | None = None
    fault: str | None = None

    def __post_init__(self) -> None:
        if self.fault is not None:
            fault = get_fault(self.fault)
            if isinstance(fault, NoiseFault) and self.noise is not None:
                raise ParameterError(
                    f"RunSpec: fault {self.fault!r} adds measurement noise and so does noise={self.noise!r}; "
                    "give one of them"
                )


def build_plant(scenario: Scenario, spec: RunSpec) -> Plant:
    """The scenario's plant with the spec's fault applied, wrapped with measurement noise when asked for."""
    plant = make_plant(vehicle_preset(scenario.vehicle_name).plant)
    if spec.fault is not None:
        plant = get_fault(spec.fault).apply(plant, scenario, spec.seed)
    if spec.noise is not None:
        plant = ObservationNoise(plant, spec.noise, seed=spec.seed)
    return plant


def run_controller(
    scenario: Scenario,
    spec: RunSpec,
    *,
    controller_options: dict[str, Any] | None = None,
    on_step: Callable[[float, float], None] | None = None,
) -> tuple[SimResult, dict[str, Any]]:
    """Drive one controller in the scenario and measure it.

    Returns
    -------
    result : SimResult
        Log and outcome.
    metrics : dict
        :func:`rkmpc.analysis.metrics.lap_metrics` of the run.
    """
    preset = vehicle_preset(scenario.vehicle_name).controller_options.get(spec.controller, {})
    controller_options = {**preset, **(controller_options or {})}
    controller = make_controller(spec.controller, scenario.reference, scenario.vehicle, **controller_options)
    plant = build_plant(scenario, spec)
    result = simulate(
        plant,
        controller,
        scenario.track,
        scenario.reference,
        SimConfig(dt=scenario.dt, laps=spec.laps),
        on_step=on_step,
    )
    result.log.metadata.update({"controller": spec.controller, "seed": spec.seed, "fault": spec.fault})
    return result, lap_metrics(result, laps=spec.laps)


def versions() -> dict[str, str]:
    """Versions of Python and the packages that shape the results."""
    out = {"python": platform.python_version()}
    for name in ("rkmpc", "numpy", "scipy", "daqp", "osqp", "commonroad-vehicle-models"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


def run_record(scenario: Scenario, specs: Sequence[RunSpec]) -> dict[str, Any]:
    """Configuration block written beside results: scenario, runs, seed, versions."""
    return {
        "scenario": scenario.describe(),
        "runs": [
            {
                "controller": s.controller,
                "laps": s.laps,
                "seed": s.seed,
                "noise": None if s.noise is None else asdict(s.noise),
                "fault": None if s.fault is None else get_fault(s.fault).describe(),
            }
            for s in specs
        ],
        "versions": versions(),
    }
