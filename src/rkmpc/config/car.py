"""A car, described once: :class:`CarConfig` (vehicle, plant, limits, controllers, training, ROS).

Every command that drives, learns or studies a car takes one :class:`CarConfig` and reads each
setting from it, typed: the nominal model the controllers plan with (:class:`VehicleParams`), the
plant that is driven (the preset's own, or a car of the zoo), the speed profile's limits, every
controller's settings (:class:`~rkmpc.control.settings.ControllerSettings`), how the learned
controllers learn (:class:`TrainingSettings`) and how ``rkmpc node`` talks to the car over ROS
(:class:`~rkmpc.config.ros.RosSettings`). The presets are car files shipped with the package
(``rkmpc/config/presets/*.toml``) and read by the one loader (:mod:`rkmpc.config.loader`):
:func:`rkmpc.config.loader.load_preset` gives a preset as it is.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

from rkmpc.config.ros import RosSettings
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import ParameterError
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.track.speed_profile import SpeedLimits
from rkmpc.vehicle.params import VehicleParams
from rkmpc.vehicle.registry import PLANTS
from rkmpc.vehicle.sensors import SensorProfile, get_sensor_profile
from rkmpc.vehicle.zoo import get_car

__all__ = ["CarConfig", "PlantSettings", "TrainingSettings", "tyre_grip"]


def tyre_grip(vehicle: VehicleParams) -> float:
    """The largest steady lateral acceleration the car's tyres hold (m/s^2), about.

    ``mu g`` times the smaller axle's peak of the magic formula per unit load: ``D`` for a shape
    factor ``C >= 1``, ``D sin(C pi / 2)`` below (the formula's limit at large slip). About
    11.3 m/s^2 for the 1:10 car, 10.3 for the full-size one; load transfer lowers it further.
    """

    def peak(C: float, D: float) -> float:
        return D if C >= 1.0 else D * math.sin(0.5 * math.pi * C)

    axles = (vehicle.tyre_front, vehicle.tyre_rear)
    return vehicle.mu * vehicle.gravity * min(peak(t.C, t.D) for t in axles)


@dataclass(frozen=True)
class TrainingSettings:
    """How the learned controllers learn.

    Parameters
    ----------
    epochs : int or None
        Training epochs of every learned model (>= 1); None for the recipes' defaults.
    seed : int
        Seed of the data collection, training and runs (>= 0).
    data_laps : int
        LMPC laps of on-track data (>= 1).
    kmpc_samples : int
        Random-excitation samples of the KMPC model (>= 1000).
    """

    epochs: int | None = None
    seed: int = 0
    data_laps: int = 2
    kmpc_samples: int = 50_000

    def __post_init__(self) -> None:
        for name, minimum in (("epochs", 1), ("seed", 0), ("data_laps", 1), ("kmpc_samples", 1000)):
            value = getattr(self, name)
            if not (value is None and name == "epochs") and not is_integer(value, minimum):
                raise ParameterError(
                    f"TrainingSettings.{name} must be an integer >= {minimum}, got {value!r}"
                )


@dataclass(frozen=True)
class PlantSettings:
    """The car that is driven in simulation.

    Parameters
    ----------
    model : str
        The preset's own plant, a name of :data:`rkmpc.vehicle.registry.PLANTS`.
    car : str or None
        A car of the zoo driven instead (:func:`rkmpc.vehicle.zoo.get_car`: a variant name or
        ``"random-<seed>"``; 1:10 cars, so only on the ``f1tenth`` plant). The controllers keep
        the nominal model.
    """

    model: str = "f1tenth"
    car: str | None = None

    def __post_init__(self) -> None:
        PLANTS.check(self.model)
        if self.car is not None:
            get_car(self.car)
            if self.model != "f1tenth":
                raise ParameterError(f"zoo cars are 1:10 cars: car {self.car!r} needs the f1tenth plant")


@dataclass(frozen=True, kw_only=True)
class CarConfig:
    """A car set up in one file (or a preset as it is), fully resolved.

    Parameters
    ----------
    preset : str
        The packaged preset it builds on (``"f1tenth"``, ``"fullsize"``).
    vehicle : VehicleParams
        The controllers' nominal model of the car.
    file_scale : float
        Scale track files are read at for this car (the TUM tracks are full size), > 0.
    plant : PlantSettings
        The plant driven in simulation.
    limits : SpeedLimits
        The speed profile's limits (the pace).
    controllers : ControllerSettings
        Every controller's settings.
    training : TrainingSettings
        How the learned controllers learn.
    sensors : SensorProfile
        What the simulated car's sensors measure, and how (:mod:`rkmpc.vehicle.sensors`):
        ``ideal`` (every field true and current) or a real car's profile (``f1tenth-real``: no
        wheel angle, no side-slip, a late, noisy localiser).
    estimator : EstimatorConfig
        The state estimator that turns what a car's sensors measure into the state the controllers
        need (:mod:`rkmpc.estimation`), used where the sensors are not ideal; its control period is
        the run's.
    ros : RosSettings
        How ``rkmpc node`` talks to the car.
    source : str or None
        The file it was read from (None: a preset as it is).
    sha256 : str or None
        SHA-256 of that file's bytes.
    """

    preset: str
    vehicle: VehicleParams
    file_scale: float
    plant: PlantSettings = field(default_factory=PlantSettings)
    limits: SpeedLimits = field(default_factory=SpeedLimits)
    controllers: ControllerSettings = field(default_factory=ControllerSettings)
    training: TrainingSettings = field(default_factory=TrainingSettings)
    sensors: SensorProfile = field(default_factory=lambda: get_sensor_profile("ideal"))
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    ros: RosSettings = field(default_factory=RosSettings)
    source: str | None = None
    sha256: str | None = None

    def __post_init__(self) -> None:
        checks = (
            ("vehicle", VehicleParams),
            ("plant", PlantSettings),
            ("limits", SpeedLimits),
            ("controllers", ControllerSettings),
            ("training", TrainingSettings),
            ("sensors", SensorProfile),
            ("estimator", EstimatorConfig),
            ("ros", RosSettings),
        )
        for name, kind in checks:
            if not isinstance(getattr(self, name), kind):
                raise ParameterError(
                    f"CarConfig.{name} must be a {kind.__name__}, got {getattr(self, name)!r}"
                )
        if not is_positive_number(self.file_scale):
            raise ParameterError(f"CarConfig.file_scale must be finite and > 0, got {self.file_scale!r}")
        top = self.vehicle.drive.max_speed
        if self.limits.max_speed > top:
            raise ParameterError(
                f"the pace's top speed ([limits] max_speed or --max-speed: {self.limits.max_speed:g} m/s) is "
                f"beyond what the car's drive reaches ([vehicle.drive] max_speed: {top:g} m/s): the "
                "reference would ask for speeds the car cannot reach and it would leave the track; "
                "lower the pace or give the car's drive its true top speed"
            )

    def check_limits(self) -> list[str]:
        """What is doubtful in this car's pace, one line each (empty when nothing is).

        A lateral-acceleration limit beyond the tyres' grip (:func:`tyre_grip`): the speed profile
        asks for corners the car cannot take, and it slides off the track. Allowed (the pace
        study climbs past the grip on purpose); a command line says it.
        """
        grip = tyre_grip(self.vehicle)
        if self.limits.lateral_accel <= grip:
            return []
        return [
            "the pace's lateral acceleration ([limits] lateral_accel or --lateral-accel: "
            f"{self.limits.lateral_accel:g} m/s^2) is beyond the tyres' grip, about {grip:.1f} m/s^2 "
            "for this car: expect it to slide off the track in corners"
        ]

    # ------------------------------------------------------------------ variants
    def at_pace(self, lateral_accel: float | None = None, max_speed: float | None = None) -> CarConfig:
        """This car at another pace (:meth:`SpeedLimits.at_pace`); None keeps a value."""
        if lateral_accel is None and max_speed is None:
            return self
        return replace(self, limits=self.limits.at_pace(lateral_accel, max_speed))

    def with_zoo_car(self, car: str | None) -> CarConfig:
        """This car driving the zoo car ``car`` (None: the preset's own plant)."""
        return self if car == self.plant.car else replace(self, plant=replace(self.plant, car=car))

    def with_sensors(self, profile: str | SensorProfile | None) -> CarConfig:
        """This car with another sensor profile (a name of :data:`rkmpc.vehicle.sensors.SENSOR_PROFILES`);
        None, or the name of the car's own profile, keeps the car's (with its file's overrides)."""
        if profile is None or (isinstance(profile, str) and profile == self.sensors.name):
            return self
        sensors = get_sensor_profile(profile) if isinstance(profile, str) else profile
        return self if sensors == self.sensors else replace(self, sensors=sensors)

    def with_training(self, **changes: Any) -> CarConfig:
        """This car with some :class:`TrainingSettings` fields replaced (``seed=1``, ``epochs=5``)."""
        return replace(self, training=replace(self.training, **changes)) if changes else self

    # ------------------------------------------------------------------ records
    def to_json(self) -> dict[str, Any]:
        """The effective configuration, for result files: every value, the file and its hash."""
        return {
            "file": self.source,
            "sha256": self.sha256,
            "vehicle": {
                "preset": self.preset,
                "file_scale": self.file_scale,
                **to_json_ready(asdict(self.vehicle)),
            },
            "plant": asdict(self.plant),
            "limits": asdict(self.limits),
            "controllers": self.controllers.to_json(),
            "training": asdict(self.training),
            "sensors": self.sensors.describe(),
            "estimator": asdict(self.estimator),
            "ros": to_json_ready(asdict(self.ros)),
        }
