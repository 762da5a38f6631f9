"""Named faults a run can be given, to measure robustness instead of claiming it.

A :class:`Fault` is a frozen, validated dataclass of its parameters that turns
the nominal plant of a scenario into a faulty one with :meth:`Fault.apply`
(or :func:`apply_fault`). The controllers are never told: they keep the
nominal vehicle parameters and see the faulty plant only through its
observations. The named defaults are in :data:`FAULTS`:

``"noise"`` (:class:`NoiseFault`)
    Seeded Gaussian measurement noise on the observations
    (:class:`~rkmpc.vehicle.wrappers.ObservationNoise`, :data:`DEFAULT_NOISE`).
``"delay"`` (:class:`DelayFault`)
    Every command reaches the plant one control period (0.05 s) later, on
    top of the plant's own input delay
    (:class:`~rkmpc.vehicle.wrappers.CommandDelay`).
``"friction"`` (:class:`FrictionFault`)
    Friction drops to 0.6 of nominal over 20 % of the lap, placed on the most
    curved stretch of the centre line
    (:class:`~rkmpc.vehicle.plants.base.ArcWindowFriction`).
``"heavy"`` (:class:`HeavyFault`)
    30 % more mass and yaw inertia with the same centre of gravity, tyres whose
    grip per unit load falls with load, and a drive of fixed force.

Noise and delay wrap any plant. Friction and heavy rebuild the plant, so they
apply to the bare plants of both vehicle presets
(:class:`~rkmpc.vehicle.plants.dynamic.DynamicPlant`, ``"f1tenth"``, and
:class:`~rkmpc.vehicle.plants.fullsize.FullSizePlant`, ``"fullsize"``) and raise
:class:`~rkmpc.core.errors.ParameterError` naming the fault and the plant for any
other plant (a wrapper included).
"""

from __future__ import annotations

from rkmpc.core.errors import ParameterError
from rkmpc.core.registry import Registry
from rkmpc.sim.faults.base import Fault
from rkmpc.sim.faults.physical import FrictionFault, HeavyFault, curviest_window
from rkmpc.sim.faults.signals import DEFAULT_NOISE, DelayFault, NoiseFault
from rkmpc.sim.scenario import Scenario
from rkmpc.vehicle.plants.base import Plant

__all__ = [
    "DEFAULT_NOISE",
    "FAULTS",
    "DelayFault",
    "Fault",
    "FrictionFault",
    "HeavyFault",
    "NoiseFault",
    "apply_fault",
    "curviest_window",
    "get_fault",
]


#: The named default faults.
FAULTS: Registry[Fault] = Registry(
    "fault", {fault.name: fault for fault in (NoiseFault(), DelayFault(), FrictionFault(), HeavyFault())}
)


def get_fault(name: str) -> Fault:
    """The registered fault called ``name``.

    Raises
    ------
    UnknownNameError
        If ``name`` is not a key of :data:`FAULTS`; the message lists them.
    """
    return FAULTS[name]


def apply_fault(plant: Plant, fault: Fault | str, scenario: Scenario, seed: int) -> Plant:
    """Apply a fault (or the registered fault of that name) to ``plant``.

    See :meth:`Fault.apply`.
    """
    the_fault = get_fault(fault) if isinstance(fault, str) else fault
    if not isinstance(the_fault, Fault):
        raise ParameterError(f"not a fault: {fault!r}")
    return the_fault.apply(plant, scenario, seed)
