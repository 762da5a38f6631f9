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
    (:class:`~rkmpc.vehicle.plant.ArcWindowFriction`).
``"heavy"`` (:class:`HeavyFault`)
    30 % more mass and yaw inertia with the same centre of gravity, tyres whose
    grip per unit load falls with load, and a drive of fixed force.

Noise and delay wrap any plant. Friction and heavy rebuild the plant, so they
apply to the bare plants of both vehicle presets
(:class:`~rkmpc.vehicle.dynamic.DynamicPlant`, ``"f1tenth"``, and
:class:`~rkmpc.vehicle.fullsize.FullSizePlant`, ``"fullsize"``) and raise
:class:`~rkmpc.errors.ParameterError` naming the fault and the plant for any
other plant (a wrapper included).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass, replace
from typing import Any, ClassVar

import numpy as np

from rkmpc.errors import ParameterError
from rkmpc.scenario import Scenario
from rkmpc.track.path import Path
from rkmpc.track.track import Track
from rkmpc.vehicle.dynamic import DynamicPlant
from rkmpc.vehicle.fullsize import FullSizePlant
from rkmpc.vehicle.params import VehicleParams
from rkmpc.vehicle.plant import ArcWindowFriction, FrictionSchedule, Plant, combine_friction
from rkmpc.vehicle.wrappers import CommandDelay, NoiseStd, ObservationNoise

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

#: Measurement noise used by ``--noise`` and the ``"noise"`` fault (1-sigma):
#: 1 cm, 0.5 deg, 2 cm/s, 0.02 rad/s.
DEFAULT_NOISE = NoiseStd(position=0.01, yaw=0.0087, speed=0.02, yaw_rate=0.02)

# Samples per lap when placing the friction window.
_WINDOW_SAMPLES = 2000


def _finite_positive(owner: str, name: str, value: float) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParameterError(f"{owner}.{name} must be a number, got {value!r}")
    if not (math.isfinite(value) and value > 0.0):
        raise ParameterError(f"{owner}.{name} must be finite and > 0, got {value!r}")


class Fault(ABC):
    """A change of the simulated car that the controllers are not told about.

    Attributes
    ----------
    name : str
        The fault's name in :data:`FAULTS`.
    """

    name: ClassVar[str]

    @abstractmethod
    def apply(self, plant: Plant, scenario: Scenario, seed: int) -> Plant:
        """Return the faulty version of ``plant``; ``plant`` itself is not changed.

        Parameters
        ----------
        plant : Plant
            The nominal plant of ``scenario``.
        scenario : Scenario
            The scenario (track, control period) the plant drives in.
        seed : int
            The run's seed; every random choice of the fault is drawn from it.

        Returns
        -------
        Plant
            A wrapper around ``plant``, or a new plant (reset to the origin) of
            the same kind and options.

        Raises
        ------
        ParameterError
            If the fault cannot apply to this plant or scenario.
        """

    def describe(self) -> dict[str, Any]:
        """JSON-ready record of the fault: ``{"name": ..., "parameters": {...}}``."""
        return {"name": self.name, "parameters": asdict(self)}  # type: ignore[call-overload]


@dataclass(frozen=True)
class NoiseFault(Fault):
    """Seeded Gaussian noise on the observed pose, speed and yaw rate.

    Effect: the controller sees ``observation + std * N(0, 1)`` per component
    (see :class:`~rkmpc.vehicle.wrappers.ObservationNoise`); the car itself,
    the logged true state and the errors measured against it are unchanged.
    The noise sequence is drawn from the run's seed.

    Parameters
    ----------
    std : NoiseStd, optional
        Standard deviations; :data:`DEFAULT_NOISE` by default.
    """

    name: ClassVar[str] = "noise"
    std: NoiseStd = DEFAULT_NOISE

    def __post_init__(self) -> None:
        if not isinstance(self.std, NoiseStd):
            raise ParameterError(f"NoiseFault.std must be a NoiseStd, got {self.std!r}")

    def apply(self, plant: Plant, scenario: Scenario, seed: int) -> Plant:
        return ObservationNoise(plant, self.std, seed=seed)


@dataclass(frozen=True)
class DelayFault(Fault):
    """An extra actuation delay of a whole number of control periods.

    Effect: each command reaches the plant ``delay`` seconds later than it
    would nominally, on top of the plant's own input delay; for the first
    ``delay / dt`` steps the plant keeps the command of its reset (the
    flying-start set-point). Nothing else changes.

    Parameters
    ----------
    delay : float, optional
        Extra delay (s), > 0 and a whole multiple of the scenario's control
        period (checked in :meth:`apply`); 0.05 s, one period at 20 Hz, by default.
    """

    name: ClassVar[str] = "delay"
    delay: float = 0.05

    def __post_init__(self) -> None:
        _finite_positive("DelayFault", "delay", self.delay)

    def steps(self, dt: float) -> int:
        """The delay in control periods of ``dt`` seconds.

        Raises
        ------
        ParameterError
            If ``delay`` is not a whole multiple of ``dt``.
        """
        steps = round(self.delay / dt)
        if steps < 1 or abs(steps * dt - self.delay) > 1e-9 * max(1.0, self.delay):
            raise ParameterError(
                f"DelayFault.delay {self.delay!r} s is not a whole number of control periods (dt = {dt!r} s)"
            )
        return steps

    def apply(self, plant: Plant, scenario: Scenario, seed: int) -> Plant:
        return CommandDelay(plant, self.steps(scenario.dt))


def curviest_window(path: Path, length: float) -> float:
    """Start (m) of the stretch of ``length`` metres with the most turning along ``path``.

    The total absolute curvature ``int |kappa| ds`` over the stretch is
    maximised on a grid of :data:`_WINDOW_SAMPLES` start points per lap; ties
    go to the smallest start, so the result depends only on the geometry.

    Parameters
    ----------
    path : Path
        A closed path.
    length : float
        Length of the stretch (m), ``0 < length <= path.length``.

    Returns
    -------
    float
        Arc length (m) of the start of the stretch, in ``[0, path.length)``.
    """
    n = _WINDOW_SAMPLES
    ds = path.length / n
    s = np.arange(n) * ds
    turning = np.abs(np.asarray(path.curvature(s), dtype=float)) * ds
    m = max(1, min(n, round(length / ds)))
    cumulative = np.concatenate([[0.0], np.cumsum(np.concatenate([turning, turning[: m - 1]]))])
    totals = cumulative[m : m + n] - cumulative[:n]
    return float(s[int(np.argmax(totals))])


@dataclass(frozen=True)
class FrictionFault(Fault):
    """Lower friction over one stretch of the track.

    Effect: the tyre-road friction is multiplied by ``factor`` wherever the car's
    centre of gravity projects onto the track's centre line inside a stretch of
    ``lap_fraction`` of the lap (within twice the track's largest half-width of
    the centre line, so the whole track surface there); elsewhere, and at all
    times, friction is nominal. On the ``f1tenth`` plant this scales the whole
    tyre curve (stiffness and peak); on the ``fullsize`` plant the tyre peak
    factors (see :class:`~rkmpc.vehicle.fullsize.FullSizePlant`). The stretch
    is placed from the geometry alone: where the centre line turns most
    (:func:`curviest_window`), unless ``start_fraction`` fixes it.

    Parameters
    ----------
    factor : float, optional
        Friction multiplier (-) on the stretch, finite and > 0; 0.6 by default.
    lap_fraction : float, optional
        Length of the stretch as a fraction of the centre line, in ``(0, 1]``;
        0.2 by default.
    start_fraction : float or None, optional
        Start of the stretch as a fraction of the lap from the start line, in
        ``[0, 1)``; None (default) for the most curved stretch.
    """

    name: ClassVar[str] = "friction"
    factor: float = 0.6
    lap_fraction: float = 0.2
    start_fraction: float | None = None

    def __post_init__(self) -> None:
        _finite_positive("FrictionFault", "factor", self.factor)
        _finite_positive("FrictionFault", "lap_fraction", self.lap_fraction)
        if self.lap_fraction > 1.0:
            raise ParameterError(f"FrictionFault.lap_fraction must be in (0, 1], got {self.lap_fraction!r}")
        if self.start_fraction is not None and not (
            isinstance(self.start_fraction, int | float)
            and not isinstance(self.start_fraction, bool)
            and 0.0 <= self.start_fraction < 1.0
        ):
            raise ParameterError(
                f"FrictionFault.start_fraction must be None or in [0, 1), got {self.start_fraction!r}"
            )

    def schedule(self, track: Track) -> ArcWindowFriction:
        """The friction schedule of this fault on ``track``."""
        path = track.centerline
        length = self.lap_fraction * path.length
        if self.start_fraction is None:
            start = curviest_window(path, length)
        else:
            start = self.start_fraction * path.length
        s = np.linspace(0.0, path.length, _WINDOW_SAMPLES, endpoint=False)
        half_width = max(float(np.max(track.width_left(s))), float(np.max(track.width_right(s))))
        return ArcWindowFriction(self.factor, path, start, length, max_lateral=2.0 * half_width)

    def apply(self, plant: Plant, scenario: Scenario, seed: int) -> Plant:
        base = _rebuildable(plant, self)
        friction = combine_friction(base.friction, self.schedule(scenario.track))
        return _rebuild(base, friction=friction)


@dataclass(frozen=True)
class HeavyFault(Fault):
    """A heavier car driven with the nominal controller parameters.

    Effect, for a mass multiplier ``k``:

    * mass and yaw inertia are multiplied by ``k`` (same radius of
      gyration) and the centre of gravity stays put, so each axle's static
      load also grows by ``k``;
    * the tyres' grip per unit load (cornering stiffness and peak, i.e. the
      friction coefficient) is multiplied by ``k ** -tyre_load_sensitivity``:
      real tyres gain less force than load, which is why a loaded car
      understeers more;
    * with ``fixed_drive_force`` the speed loop's force is that of the
      nominal car (fixed motor, brake and speed-loop gain), so its time
      constant grows by ``k`` and its acceleration and braking limits shrink
      by ``k``.

    Both tyre models of the plants make tyre force proportional to load, so the
    first item alone leaves the motion unchanged (forces and inertia grow
    alike); the other two are what make the car behave heavier. Steering
    servo, geometry and top speed are unchanged.

    Parameters
    ----------
    mass_factor : float, optional
        Mass multiplier ``k`` (-), finite and > 0; 1.3 by default.
    tyre_load_sensitivity : float, optional
        Exponent of the grip loss, in ``[0, 1]``: 0 for tyres whose force is
        proportional to load, 1 for tyres whose force does not grow with
        load at all. 0.3 by default, an assumed value of the order of
        passenger-car tyres, not identified for either car.
    fixed_drive_force : bool, optional
        Whether the drive keeps its nominal force (True, default) or its
        nominal acceleration (False).
    """

    name: ClassVar[str] = "heavy"
    mass_factor: float = 1.3
    tyre_load_sensitivity: float = 0.3
    fixed_drive_force: bool = True

    def __post_init__(self) -> None:
        _finite_positive("HeavyFault", "mass_factor", self.mass_factor)
        value = self.tyre_load_sensitivity
        if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 <= value <= 1.0:
            raise ParameterError(f"HeavyFault.tyre_load_sensitivity must be in [0, 1], got {value!r}")
        if not isinstance(self.fixed_drive_force, bool):
            raise ParameterError(
                f"HeavyFault.fixed_drive_force must be a bool, got {self.fixed_drive_force!r}"
            )

    @property
    def grip_factor(self) -> float:
        """Multiplier (-) of the tyres' grip per unit load, ``mass_factor ** -tyre_load_sensitivity``."""
        return float(self.mass_factor ** (-self.tyre_load_sensitivity))

    def vehicle(self, params: VehicleParams) -> VehicleParams:
        """The heavy car's parameters from the nominal ones (``mu`` carries the grip loss)."""
        k = self.mass_factor
        heavy = params.with_mass_scaled(k)
        if self.fixed_drive_force:
            drive = heavy.drive
            heavy = replace(
                heavy,
                drive=replace(
                    drive,
                    time_constant=drive.time_constant * k,
                    max_accel=drive.max_accel / k,
                    max_brake=drive.max_brake / k,
                ),
            )
        return replace(heavy, mu=heavy.mu * self.grip_factor)

    def apply(self, plant: Plant, scenario: Scenario, seed: int) -> Plant:
        base = _rebuildable(plant, self)
        return _rebuild(
            base,
            params=self.vehicle(base.params),
            mass_scale=self.mass_factor,
            grip_scale=self.grip_factor,
        )


# --------------------------------------------------------------------------- rebuilding plants

_REBUILDABLE = (DynamicPlant, FullSizePlant)


def _rebuildable(plant: Plant, fault: Fault) -> DynamicPlant | FullSizePlant:
    """``plant`` if a rebuilding fault can apply to it, else a ParameterError naming both."""
    if type(plant) in _REBUILDABLE:
        return plant  # type: ignore[return-value]
    kinds = ", ".join(cls.__name__ for cls in _REBUILDABLE)
    hint = " (apply it before any wrapper)" if hasattr(plant, "unwrapped") else ""
    raise ParameterError(
        f"fault {fault.name!r} cannot apply to plant {type(plant).__name__}{hint}; it changes the "
        f"vehicle model, which only these plants support: {kinds}"
    )


def _rebuild(
    plant: DynamicPlant | FullSizePlant,
    *,
    params: VehicleParams | None = None,
    friction: FrictionSchedule | None = None,
    mass_scale: float = 1.0,
    grip_scale: float = 1.0,
) -> Plant:
    """A fresh plant like ``plant`` with new params, a new friction schedule, scaled chassis/tyres.

    ``friction`` replaces the plant's schedule when given. ``mass_scale`` and
    ``grip_scale`` multiply those of a full-size plant; the dynamic plant
    takes mass and grip from ``params`` alone.
    """
    new_params = plant.params if params is None else params
    new_friction = plant.friction if friction is None else friction
    if isinstance(plant, FullSizePlant):
        return FullSizePlant(
            internal_dt=plant.internal_dt,
            input_delay=plant.input_delay,
            friction=new_friction,
            params=new_params,
            mass_scale=plant.mass_scale * mass_scale,
            grip_scale=plant.grip_scale * grip_scale,
        )
    return DynamicPlant(
        new_params,
        internal_dt=plant.internal_dt,
        input_delay=plant.input_delay,
        friction=new_friction,
    )


# --------------------------------------------------------------------------- registry

#: The named default faults.
FAULTS: dict[str, Fault] = {
    fault.name: fault for fault in (NoiseFault(), DelayFault(), FrictionFault(), HeavyFault())
}


def get_fault(name: str) -> Fault:
    """The registered fault called ``name``.

    Raises
    ------
    ParameterError
        If ``name`` is not a key of :data:`FAULTS`; the message lists them.
    """
    try:
        return FAULTS[name]
    except (KeyError, TypeError):
        known = ", ".join(sorted(FAULTS))
        raise ParameterError(f"unknown fault {name!r}; known faults: {known}") from None


def apply_fault(plant: Plant, fault: Fault | str, scenario: Scenario, seed: int) -> Plant:
    """Apply a fault (or the registered fault of that name) to ``plant``.

    See :meth:`Fault.apply`.
    """
    the_fault = get_fault(fault) if isinstance(fault, str) else fault
    if not isinstance(the_fault, Fault):
        raise ParameterError(f"not a fault: {fault!r}")
    return the_fault.apply(plant, scenario, seed)
