"""A zoo of 1:10 cars: documented ways a real car differs from the one the controllers assume.

Every controller is built with the nominal car, :func:`rkmpc.vehicle.params.f1tenth`
(ForzaETH's NUC2). A :class:`CarSpec` is the car that is actually driven: a
composition of a chassis (:class:`~rkmpc.vehicle.params.VehicleParams`), a
steering actuator and a speed loop (:mod:`rkmpc.vehicle.actuators`), two tyre
models (:mod:`rkmpc.vehicle.tyres`), and the odometry's latency and noise. The
point is model mismatch: nothing here is told to the controllers.

Named variants (:data:`ZOO`, :func:`get_car`) and their sources:

``home``
    The nominal car itself, composed of parts: ForzaETH NUC2 chassis and Pacejka
    tyres, first-order servo (0.158 s, 3.2 rad/s), first-order speed loop. Its
    motion matches :class:`~rkmpc.vehicle.plants.dynamic.DynamicPlant` closely.
``gym``
    The F1TENTH gym's car (f1tenth_gym vehicle parameters, after CommonRoad's
    single-track model): 3.74 kg, ``lf`` 0.15875 m, ``lr`` 0.17145 m (wheelbase
    0.330 m against the nominal 0.307 m), ``h`` 0.074 m, ``Iz`` 0.04712, linear
    tyres with load scaling and no saturation (``C_Sf`` 4.718, ``C_Sr`` 5.4562,
    ``mu`` 1.0489). Steering: a 20 ms pure delay, then a wheel moving at
    ±3.2 rad/s (the gym's steering-velocity limit) with a direction chosen every
    10 ms, so it limit-cycles 0.032 rad around the command. Speed: a P loop that
    accelerates with gain 2/s and brakes with 4/s. The car of the issue's probe.
``overshoot``
    NUC2 chassis behind a stiff, under-damped steering linkage: second-order
    servo, ``wn`` 25 rad/s, ``zeta`` 0.45 (20 % overshoot), 5 rad/s.
``cheap-servo``
    NUC2 chassis with an analogue hobby servo: slower lag (0.25 s, 2.0 rad/s;
    a standard servo turns 60 degrees in about 0.2 s at the horn, less at the
    wheel through the linkage) and a position resolution of 0.01 rad.
``low-grip``
    NUC2 on a dusty floor: Pacejka tyres at ``mu`` 0.7 (the front axle's peak
    lateral acceleration, ``mu D sin(C pi / 2) g``, falls from about 11 m/s² to
    7.8 m/s², against the 4 m/s² of the speed profile), speed loop with a lower
    acceleration cap (2.5 m/s²: wheel spin). At ``mu`` 0.6 the LMPC, the
    baseline every learned controller is judged against, leaves every track
    (its transient lateral acceleration reaches the rear axle's grip), so
    nothing could be compared; at ``mu`` 0.4 no controller completes the
    built-in track.
``heavy-long``
    Mass +30 %, wheelbase +10 %, centre of gravity 10 % of the wheelbase
    further back (a second battery on a longer chassis); yaw inertia scaled
    with mass and wheelbase squared.
``light-short``
    Mass -30 %, wheelbase -10 %, centre of gravity 10 % of the wheelbase
    further forward.
``laggy-odom``
    The nominal car whose odometry (a particle filter at 40 Hz) arrives 40 ms
    late with noise: position 0.02 m, heading 0.01 rad, speed 0.05 m/s, yaw
    rate 0.02 rad/s.

``random-<seed>`` (:func:`random_car`) draws a car over ranges spanning the
variants above (domain randomisation), reproducibly from the seed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.core.registry import Registry, UnknownNameError
from rkmpc.core.validation import require_nonnegative
from rkmpc.vehicle.actuators import (
    AsymmetricSpeedLoop,
    DelayedRateServo,
    FirstOrderServo,
    LagSpeedLoop,
    QuantisedServo,
    SecondOrderServo,
    SpeedLoopSpec,
    SteeringSpec,
)
from rkmpc.vehicle.friction import FrictionSchedule
from rkmpc.vehicle.params import VehicleParams, f1tenth
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.plants.composed import ComposedPlant
from rkmpc.vehicle.tyres import LinearTyre, PacejkaTyre, TyreModel
from rkmpc.vehicle.wrappers import NoiseStd, ObservationDelay, ObservationNoise

__all__ = ["ZOO", "CarSpec", "get_car", "random_car", "zoo_names"]


@dataclass(frozen=True)
class CarSpec:
    """A simulated car built from parts, with its odometry.

    Parameters
    ----------
    name : str
        Identifier (``"gym"``, ``"random-3"``, ...).
    summary : str
        One line on how the car differs from the nominal one.
    params : VehicleParams
        True chassis and command limits (see :class:`ComposedPlant`).
    steering : SteeringSpec
        Steering actuator.
    speed_loop : SpeedLoopSpec
        Speed loop.
    tyre_front, tyre_rear : TyreModel
        Tyre models of the axles.
    odometry_latency : float, optional
        Age of every observation (s), >= 0; a multiple of 5 ms is exact.
    odometry_noise : NoiseStd or None, optional
        Gaussian odometry noise, seeded per run.
    """

    name: str
    summary: str
    params: VehicleParams
    steering: SteeringSpec
    speed_loop: SpeedLoopSpec
    tyre_front: TyreModel
    tyre_rear: TyreModel
    odometry_latency: float = 0.0
    odometry_noise: NoiseStd | None = None

    def __post_init__(self) -> None:
        require_nonnegative(self, "odometry_latency")

    def make_plant(
        self,
        seed: int = 0,
        *,
        internal_dt: float = 1e-3,
        input_delay: float = 0.0,
        friction: FrictionSchedule | None = None,
    ) -> Plant:
        """The car as a plant: the composed car, then its odometry latency, then its noise (seeded)."""
        plant: Plant = ComposedPlant(
            self.params,
            steering=self.steering,
            speed_loop=self.speed_loop,
            tyre_front=self.tyre_front,
            tyre_rear=self.tyre_rear,
            internal_dt=internal_dt,
            input_delay=input_delay,
            friction=friction,
        )
        if self.odometry_latency > 0.0:
            plant = ObservationDelay(plant, self.odometry_latency)
        if self.odometry_noise is not None:
            plant = ObservationNoise(plant, self.odometry_noise, seed=seed)
        return plant

    def describe(self) -> dict[str, Any]:
        """A JSON-ready description (every part with its type and values), for result files."""

        def part(value: object) -> dict[str, Any]:
            return {"type": type(value).__name__, **to_json_ready(asdict(value))}  # type: ignore[call-overload]

        return {
            "name": self.name,
            "summary": self.summary,
            "params": to_json_ready(asdict(self.params)),
            "steering": part(self.steering),
            "speed_loop": part(self.speed_loop),
            "tyre_front": part(self.tyre_front),
            "tyre_rear": part(self.tyre_rear),
            "odometry_latency": self.odometry_latency,
            "odometry_noise": None if self.odometry_noise is None else asdict(self.odometry_noise),
        }


def _reshaped(base: VehicleParams, mass: float, wheelbase: float, cog_shift: float) -> VehicleParams:
    """``base`` with mass and wheelbase scaled and the centre of gravity moved back by ``cog_shift``.

    ``cog_shift`` is a fraction of the new wheelbase (positive: towards the
    rear axle). The yaw inertia scales with the mass and the wheelbase squared.
    """
    length = base.wheelbase * wheelbase
    lf = base.lf * wheelbase + cog_shift * length
    if not 0.0 < lf < length:
        raise ParameterError(f"centre-of-gravity shift {cog_shift!r} moves it off the wheelbase")
    return replace(
        base,
        mass=base.mass * mass,
        yaw_inertia=base.yaw_inertia * mass * wheelbase**2,
        lf=lf,
        lr=length - lf,
    )


def _nominal(name: str, summary: str, **changes: Any) -> CarSpec:
    """The nominal car's parts, with ``changes``."""
    p = f1tenth()
    parts: dict[str, Any] = {
        "params": p,
        "steering": FirstOrderServo(p.steering.time_constant, p.steering.max_rate),
        "speed_loop": LagSpeedLoop(p.drive.time_constant, p.drive.max_accel, p.drive.max_brake),
        "tyre_front": PacejkaTyre(p.tyre_front),
        "tyre_rear": PacejkaTyre(p.tyre_rear),
    }
    parts.update(changes)
    return CarSpec(name=name, summary=summary, **parts)


def _gym() -> CarSpec:
    nominal = f1tenth()
    params = replace(
        nominal,
        name="f1tenth-gym",
        mass=3.74,
        yaw_inertia=0.04712,
        lf=0.15875,
        lr=0.17145,
        h_cg=0.074,
        mu=1.0489,
    )
    return CarSpec(
        name="gym",
        summary="F1TENTH gym car: linear tyres, delay + bang-bang servo, asymmetric P speed loop, L 0.330 m",
        params=params,
        steering=DelayedRateServo(delay=0.02, max_rate=3.2, update_period=0.01),
        speed_loop=AsymmetricSpeedLoop(accel_gain=2.0, brake_gain=4.0, max_accel=5.0, max_brake=8.0),
        tyre_front=LinearTyre(4.718),
        tyre_rear=LinearTyre(5.4562),
    )


#: Zoo variants by name.
ZOO: Registry[Callable[[], CarSpec]] = Registry(
    "zoo car",
    {
        "home": lambda: _nominal("home", "the nominal car, composed of parts"),
        "gym": _gym,
        "overshoot": lambda: _nominal(
            "overshoot",
            "second-order servo with 20 % overshoot",
            steering=SecondOrderServo(natural_frequency=25.0, damping=0.45, max_rate=5.0),
        ),
        "cheap-servo": lambda: _nominal(
            "cheap-servo",
            "slow analogue servo with 0.01 rad resolution",
            steering=QuantisedServo(FirstOrderServo(0.25, 2.0), step=0.01),
        ),
        "low-grip": lambda: _nominal(
            "low-grip",
            "dusty floor: mu 0.7, acceleration capped at 2.5 m/s^2",
            params=replace(f1tenth(), mu=0.7),
            speed_loop=LagSpeedLoop(0.2, 2.5, 4.0),
        ),
        "heavy-long": lambda: _nominal(
            "heavy-long",
            "mass +30 %, wheelbase +10 %, centre of gravity 10 % further back",
            params=_reshaped(f1tenth(), mass=1.3, wheelbase=1.1, cog_shift=0.1),
        ),
        "light-short": lambda: _nominal(
            "light-short",
            "mass -30 %, wheelbase -10 %, centre of gravity 10 % further forward",
            params=_reshaped(f1tenth(), mass=0.7, wheelbase=0.9, cog_shift=-0.1),
        ),
        "laggy-odom": lambda: _nominal(
            "laggy-odom",
            "odometry 40 ms late, with noise",
            odometry_latency=0.04,
            odometry_noise=NoiseStd(position=0.02, yaw=0.01, speed=0.05, yaw_rate=0.02),
        ),
    },
)

_RANDOM_PREFIX = "random-"


def zoo_names() -> list[str]:
    """The named variants, in the order of :data:`ZOO`."""
    return list(ZOO)


def get_car(name: str) -> CarSpec:
    """The variant ``name``: a key of :data:`ZOO` or ``"random-<seed>"`` (:func:`random_car`)."""
    if name in ZOO:
        return ZOO[name]()
    if name.startswith(_RANDOM_PREFIX):
        seed = name[len(_RANDOM_PREFIX) :]
        if seed.isdigit():
            return random_car(int(seed))
    raise UnknownNameError("zoo car", name, [*ZOO, f"{_RANDOM_PREFIX}<seed>"])


#: Draws of a steering actuator, one of which :func:`random_car` picks uniformly.
_STEERING_DRAWS: tuple[Callable[[np.random.Generator], SteeringSpec], ...] = (
    lambda rng: FirstOrderServo(rng.uniform(0.08, 0.3), rng.uniform(2.0, 5.0)),
    lambda rng: DelayedRateServo(delay=0.005 * int(rng.integers(0, 9)), max_rate=rng.uniform(2.5, 4.0)),
    lambda rng: SecondOrderServo(
        natural_frequency=rng.uniform(15.0, 35.0), damping=rng.uniform(0.35, 0.9), max_rate=5.0
    ),
)


def random_car(seed: int) -> CarSpec:
    """A car drawn uniformly over ranges that span the named variants (domain randomisation).

    Draws, in this order, from ``numpy.random.default_rng(seed)``: mass factor
    [0.7, 1.3], wheelbase factor [0.9, 1.1], centre-of-gravity shift
    [-0.1, 0.1] of the wheelbase, friction [0.5, 1.05], linear tyres with
    probability 0.3 (stiffness per load [4, 6] front and rear), the steering
    actuator (lag 0.08-0.3 s at 2-5 rad/s; delay 0-40 ms with a bang-bang rate
    2.5-4 rad/s; second order ``wn`` 15-35 rad/s, ``zeta`` 0.35-0.9; each with
    probability 1/3, then quantised to 0.005-0.015 rad with probability 0.3),
    the speed loop (gains 2-8 /s up and down, caps 2.5-6 m/s^2), and odometry
    latency 0-40 ms in steps of 5 ms.

    Parameters
    ----------
    seed : int
        Seed of the draw; the car's name is ``"random-<seed>"``.
    """
    rng = np.random.default_rng(seed)
    u = rng.uniform
    nominal = f1tenth()
    params = _reshaped(nominal, mass=u(0.7, 1.3), wheelbase=u(0.9, 1.1), cog_shift=u(-0.1, 0.1))
    params = replace(params, mu=u(0.5, 1.05))
    front: TyreModel
    rear: TyreModel
    if rng.random() < 0.3:
        front, rear = LinearTyre(u(4.0, 6.0)), LinearTyre(u(4.0, 6.0))
    else:
        front, rear = PacejkaTyre(params.tyre_front), PacejkaTyre(params.tyre_rear)
    steering = _STEERING_DRAWS[int(rng.integers(len(_STEERING_DRAWS)))](rng)
    if rng.random() < 0.3:
        steering = QuantisedServo(steering, step=u(0.005, 0.015))
    speed_loop = AsymmetricSpeedLoop(u(2.0, 8.0), u(2.0, 8.0), u(2.5, 6.0), u(2.5, 6.0))
    latency = 0.005 * int(rng.integers(0, 9))
    return CarSpec(
        name=f"{_RANDOM_PREFIX}{seed}",
        summary="random draw",
        params=params,
        steering=steering,
        speed_loop=speed_loop,
        tyre_front=front,
        tyre_rear=rear,
        odometry_latency=latency,
    )
