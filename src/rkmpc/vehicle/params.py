"""Vehicle parameter sets: frozen, validated dataclasses in SI units."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace

from rkmpc.core.errors import ParameterError
from rkmpc.core.registry import Registry
from rkmpc.core.validation import require_positive


def _check_finite(obj: object) -> None:
    for f in fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        if isinstance(value, float | int) and not math.isfinite(value):
            raise ParameterError(f"{type(obj).__name__}.{f.name} must be finite, got {value!r}")


@dataclass(frozen=True)
class PacejkaParams:
    """Simplified Pacejka magic-formula coefficients of one axle's tyres.

    Lateral force ``Fy = mu * Fz * D * sin(C * atan(B*a - E*(B*a - atan(B*a))))``
    with slip angle ``a`` (rad) and vertical load ``Fz`` (N).

    Parameters
    ----------
    B : float
        Stiffness factor (1/rad).
    C : float
        Shape factor (-).
    D : float
        Peak factor (-), multiplies ``mu * Fz``.
    E : float
        Curvature factor (-).
    """

    B: float
    C: float
    D: float
    E: float

    def __post_init__(self) -> None:
        _check_finite(self)
        require_positive(self, "B", "C", "D")

    @property
    def cornering_stiffness_per_load(self) -> float:
        """Initial slope dFy/da divided by mu*Fz (1/rad): ``B*C*D``."""
        return self.B * self.C * self.D


@dataclass(frozen=True)
class SteeringParams:
    """Steering servo: first-order lag with rate and angle limits.

    Parameters
    ----------
    time_constant : float
        Servo time constant (s).
    max_angle : float
        Largest front wheel angle magnitude (rad).
    max_rate : float
        Largest wheel angle rate magnitude (rad/s).
    """

    time_constant: float
    max_angle: float
    max_rate: float

    def __post_init__(self) -> None:
        _check_finite(self)
        require_positive(self, "time_constant", "max_angle", "max_rate")


@dataclass(frozen=True)
class DriveParams:
    """Longitudinal speed loop: first-order lag towards the commanded speed.

    Parameters
    ----------
    time_constant : float
        Speed-loop time constant (s).
    max_accel : float
        Largest forward acceleration (m/s^2).
    max_brake : float
        Largest deceleration magnitude (m/s^2).
    max_speed : float
        Top speed (m/s).
    min_speed : float
        Lowest commanded speed (m/s); 0 means the car may stop.
    """

    time_constant: float
    max_accel: float
    max_brake: float
    max_speed: float
    min_speed: float = 0.0

    def __post_init__(self) -> None:
        _check_finite(self)
        require_positive(self, "time_constant", "max_accel", "max_brake", "max_speed")
        if not 0.0 <= self.min_speed < self.max_speed:
            raise ParameterError(
                f"DriveParams.min_speed must satisfy 0 <= min_speed < max_speed, got {self.min_speed!r}"
            )


@dataclass(frozen=True)
class VehicleParams:
    """Parameters of a single-track (bicycle) car with its actuators.

    Parameters
    ----------
    name : str
        Short identifier (``"f1tenth"``, ``"fullsize"``).
    mass : float
        Mass (kg).
    yaw_inertia : float
        Yaw moment of inertia about the centre of gravity (kg m^2).
    lf, lr : float
        Distances from the centre of gravity to the front and rear axle (m).
    h_cg : float
        Height of the centre of gravity (m), for longitudinal load transfer.
    tyre_front, tyre_rear : PacejkaParams
        Magic-formula coefficients of the front and rear axle.
    mu : float
        Tyre-road friction coefficient (-).
    steering : SteeringParams
        Steering servo.
    drive : DriveParams
        Speed loop.
    blend_speed_low, blend_speed_high : float
        Below ``blend_speed_low`` (m/s) the plant is purely kinematic, above
        ``blend_speed_high`` purely dynamic, linearly blended in between.
    """

    name: str
    mass: float
    yaw_inertia: float
    lf: float
    lr: float
    h_cg: float
    tyre_front: PacejkaParams
    tyre_rear: PacejkaParams
    mu: float
    steering: SteeringParams
    drive: DriveParams
    blend_speed_low: float = 0.5
    blend_speed_high: float = 1.0
    gravity: float = field(default=9.81)

    def __post_init__(self) -> None:
        _check_finite(self)
        require_positive(self, "mass", "yaw_inertia", "lf", "lr", "mu", "gravity")
        if self.h_cg < 0.0:
            raise ParameterError(f"VehicleParams.h_cg must be >= 0, got {self.h_cg!r}")
        if not 0.0 <= self.blend_speed_low < self.blend_speed_high:
            raise ParameterError(
                "VehicleParams.blend_speed_low/high must satisfy 0 <= low < high, "
                f"got {self.blend_speed_low!r}, {self.blend_speed_high!r}"
            )

    @property
    def wheelbase(self) -> float:
        """Distance between the axles, ``lf + lr`` (m)."""
        return self.lf + self.lr

    def with_mass_scaled(self, factor: float) -> VehicleParams:
        """The same car loaded to ``factor`` times its mass.

        The yaw inertia is scaled by the same factor (the radius of gyration is
        kept) and the centre of gravity stays where it is, so the static load
        on each axle also grows by ``factor``. Everything else is unchanged.

        Parameters
        ----------
        factor : float
            Mass multiplier (-), finite and > 0.

        Returns
        -------
        VehicleParams
        """
        if not (math.isfinite(factor) and factor > 0.0):
            raise ParameterError(f"mass factor must be finite and > 0, got {factor!r}")
        return replace(self, mass=self.mass * factor, yaw_inertia=self.yaw_inertia * factor)


def f1tenth() -> VehicleParams:
    """A 1:10 F1TENTH car: ForzaETH's identified NUC2 car (mass 3.54 kg).

    Chassis, tyre and servo values are those published by ETH Zurich's ForzaETH
    team for their NUC2 car. The speed-loop values (time constant, acceleration
    and braking limits, top speed) are typical of a VESC-driven 1:10 car.
    """
    return VehicleParams(
        name="f1tenth",
        mass=3.54,
        yaw_inertia=0.05797,
        lf=0.162,
        lr=0.145,
        h_cg=0.014,
        tyre_front=PacejkaParams(B=5.5405, C=0.4182, D=1.8635, E=0.3722),
        tyre_rear=PacejkaParams(B=6.6014, C=0.5624, D=1.7327, E=1.0648),
        mu=1.0,
        steering=SteeringParams(time_constant=0.158, max_angle=0.4189, max_rate=3.2),
        drive=DriveParams(time_constant=0.2, max_accel=4.0, max_brake=4.0, max_speed=8.0, min_speed=0.0),
        blend_speed_low=0.5,
        blend_speed_high=1.0,
    )


def fullsize() -> VehicleParams:
    """A full-size passenger car: CommonRoad vehicle 2, a BMW 320i.

    Mass, yaw inertia, axle distances (``lf = a``, ``lr = b``) and the steering
    limits (angle 1.066 rad, rate 0.4 rad/s) are those of
    ``vehiclemodels.parameters_vehicle2`` (commonroad-vehicle-models 3.0.2;
    Althoff and Wuersching, "CommonRoad: Vehicle Models", 2020, Tab. 6). ``h_cg``
    is the sprung-mass height ``h_s`` = 0.614 m, the height that package's
    single-track drift model uses for load transfer.

    The tyre coefficients reduce the package's Pacejka tyre (ADAMS handbook
    values) to the simplified magic formula at zero camber and pure lateral
    slip, where that reduction is exact: ``B = |p_ky1| / (p_cy1 p_dy1)``,
    ``C = p_cy1``, ``D = p_dy1``, ``E = p_ey1``, the same on both axles.
    Combined slip (longitudinal force reducing the lateral one) is not
    represented. The servo time constant (0.1 s) and the speed-loop values
    (time constant 0.5 s, 3 m/s^2 forward, 6 m/s^2 braking, top speed
    30 m/s) are assumptions typical of a road car, not package values.
    """
    tyre = PacejkaParams(B=21.92 / (1.3507 * 1.0489), C=1.3507, D=1.0489, E=-0.0074722)
    return VehicleParams(
        name="fullsize",
        mass=1093.2952334674046,
        yaw_inertia=1791.5995300122856,
        lf=1.1561957064,
        lr=1.4227170936,
        h_cg=0.61373004,
        tyre_front=tyre,
        tyre_rear=tyre,
        mu=1.0,
        steering=SteeringParams(time_constant=0.1, max_angle=1.066, max_rate=0.4),
        drive=DriveParams(time_constant=0.5, max_accel=3.0, max_brake=6.0, max_speed=30.0, min_speed=0.0),
        blend_speed_low=0.1,
        blend_speed_high=0.35,
    )


#: Nominal parameter sets by name (a car preset's ``[vehicle] params``).
PARAMS: Registry[Callable[[], VehicleParams]] = Registry(
    "vehicle", {"f1tenth": f1tenth, "fullsize": fullsize}
)
