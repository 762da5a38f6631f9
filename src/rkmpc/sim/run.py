"""Drive one controller in a scenario: the plant it meets (faults, noise) and the closed loop."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from rkmpc.core.errors import ParameterError
from rkmpc.core.versions import versions
from rkmpc.learning.contract import CONTRACT_KEY
from rkmpc.sim.build import build_controller
from rkmpc.sim.closed_loop import SimConfig, SimResult, simulate
from rkmpc.sim.faults import DEFAULT_NOISE, NoiseFault, get_fault
from rkmpc.sim.scenario import Scenario
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.wrappers import NoiseStd, ObservationNoise

__all__ = ["DEFAULT_NOISE", "RunSpec", "build_plant", "drive", "run_record"]


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
        Name of a fault in :data:`rkmpc.sim.faults.FAULTS`
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
    """The scenario's plant with the spec's fault applied, wrapped with measurement noise when asked for.

    A fault that changes the car (friction, mass) applies to the car before its sensors, which then
    measure the faulty car; one of the signals (noise, delay) to what the sensors give and the
    controller sends.
    """
    fault = None if spec.fault is None else get_fault(spec.fault)
    car = scenario.make_car_plant(spec.seed)
    if fault is not None and fault.changes_car:
        car = fault.apply(car, scenario, spec.seed)
    plant = scenario.car.sensors.wrap(car, spec.seed)
    if fault is not None and not fault.changes_car:
        plant = fault.apply(plant, scenario, spec.seed)
    if spec.noise is not None:
        plant = ObservationNoise(plant, spec.noise, seed=spec.seed)
    return plant


def drive(
    scenario: Scenario,
    spec: RunSpec,
    *,
    model: object = None,
    allow_mismatch: bool = False,
    on_step: Callable[[float, float], None] | None = None,
) -> SimResult:
    """Drive one controller in the scenario, on the plant the spec asks for.

    The controller is built from the scenario's car (:func:`rkmpc.sim.build.build_controller`),
    with ``model`` for a learned controller. The log's metadata records the controller,
    seed, fault and the scenario's contract (car, period, track scale).
    """
    controller = build_controller(spec.controller, scenario, model, allow_mismatch=allow_mismatch)
    plant = build_plant(scenario, spec)
    result = simulate(
        plant,
        controller,
        scenario.track,
        scenario.reference,
        SimConfig(dt=scenario.dt, laps=spec.laps),
        on_step=on_step,
    )
    result.log.metadata.update(
        {
            "controller": spec.controller,
            "seed": spec.seed,
            "fault": spec.fault,
            # What the run was made with: data made from its log inherit it (TransitionDataset.from_log).
            CONTRACT_KEY: scenario.provenance().to_json(),
        }
    )
    return result


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
