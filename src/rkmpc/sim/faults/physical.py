"""Faults of the car itself: a slippery stretch of track, a heavier car with load-sensitive tyres.

Both rebuild the plant, so they apply to the bare plants of both vehicle presets and
raise :class:`~rkmpc.core.errors.ParameterError` for any other plant (a wrapper included).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_positive_value
from rkmpc.sim.faults.base import Fault
from rkmpc.sim.scenario import Scenario
from rkmpc.track.path import Path
from rkmpc.track.track import Track
from rkmpc.vehicle.friction import ArcWindowFriction, FrictionSchedule, combine_friction
from rkmpc.vehicle.params import VehicleParams
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.plants.fullsize import FullSizePlant

# Samples per lap when placing the friction window.
_WINDOW_SAMPLES = 2000


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
    factors (see :class:`~rkmpc.vehicle.plants.fullsize.FullSizePlant`). The stretch
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
    changes_car: ClassVar[bool] = True
    factor: float = 0.6
    lap_fraction: float = 0.2
    start_fraction: float | None = None

    def __post_init__(self) -> None:
        require_positive_value(self.factor, "FrictionFault.factor")
        require_positive_value(self.lap_fraction, "FrictionFault.lap_fraction")
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
    changes_car: ClassVar[bool] = True
    mass_factor: float = 1.3
    tyre_load_sensitivity: float = 0.3
    fixed_drive_force: bool = True

    def __post_init__(self) -> None:
        require_positive_value(self.mass_factor, "HeavyFault.mass_factor")
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
