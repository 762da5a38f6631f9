"""A sensor profile (:class:`SensorProfile`) and a plant seen through it (:class:`SensedPlant`).

The localiser takes its samples at their own irregular instants: each
:meth:`SensedPlant.step` advances the wrapped plant in pieces that end at those
instants (as :class:`~rkmpc.vehicle.wrappers.ObservationDelay` does), so a
sample is the pose at its instant, not at a control instant. The observation
is made once, at :meth:`~SensedPlant.reset` and at the end of every step, and
:meth:`~SensedPlant.observe` returns it: calling it twice gives the same
observation and draws nothing.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.core.observation import Command, Observation
from rkmpc.core.validation import is_integer, require_bool
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.sensors.components import Localiser, WheelSpeedSensor, YawRateSensor
from rkmpc.vehicle.sensors.localiser import TIME_EPS, LocaliserRun
from rkmpc.vehicle.wrappers import PlantWrapper

__all__ = ["SensedPlant", "SensorProfile"]

#: The parts of a profile and their types.
_PARTS: dict[str, type] = {
    "localiser": Localiser,
    "wheel_speed": WheelSpeedSensor,
    "yaw_rate": YawRateSensor,
}

#: Whether the profile measures a field of the observation (else it is NaN).
_FLAGS = ("measures_steer_angle", "measures_slip_angle")


@dataclass(frozen=True, kw_only=True)
class SensorProfile:
    """The sensors of a car: which observation fields are measured, and how.

    A part left out (None) reports the true value, exactly as the bare plant
    does; a profile with no parts that measures both angles is *ideal*, and
    :meth:`wrap` then returns the plant itself.

    Parameters
    ----------
    name : str
        Identifier (``"ideal"``, ``"f1tenth-real"``, ...).
    summary : str
        One line on what the profile models.
    localiser : Localiser or None, optional
        Where the pose (``x``, ``y``, ``yaw``) comes from; None: the true pose, now.
    wheel_speed : WheelSpeedSensor or None, optional
        Where ``speed`` comes from; None: the true speed.
    yaw_rate : YawRateSensor or None, optional
        Where ``yaw_rate`` comes from; None: the true yaw rate.
    measures_steer_angle : bool, optional
        Whether the front wheel angle is measured; False makes ``steer_angle`` NaN.
    measures_slip_angle : bool, optional
        Whether the side-slip angle (the lateral velocity) is measured; False makes
        ``slip_angle`` NaN.
    """

    name: str
    summary: str
    localiser: Localiser | None = None
    wheel_speed: WheelSpeedSensor | None = None
    yaw_rate: YawRateSensor | None = None
    measures_steer_angle: bool = True
    measures_slip_angle: bool = True

    def __post_init__(self) -> None:
        for name in ("name", "summary"):
            value = getattr(self, name)
            if not isinstance(value, str) or (name == "name" and not value.strip()):
                raise ParameterError(f"SensorProfile.{name} must be a non-empty string, got {value!r}")
        for name, kind in _PARTS.items():
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise ParameterError(
                    f"SensorProfile.{name} must be a {kind.__name__} or None, got {type(value).__name__}"
                )
        require_bool(self, *_FLAGS)

    @property
    def is_ideal(self) -> bool:
        """True when every field is the true value: :meth:`wrap` returns the plant unchanged."""
        return all(getattr(self, name) is None for name in _PARTS) and all(getattr(self, f) for f in _FLAGS)

    @property
    def pose_latency(self) -> float:
        """How much older (s) than its observation the localiser's pose is; 0 without a localiser."""
        return 0.0 if self.localiser is None else self.localiser.latency

    def wrap(self, plant: Plant, seed: int = 0) -> Plant:
        """The plant seen through these sensors (the plant itself when the profile is ideal).

        Parameters
        ----------
        plant : Plant
            Any plant, a zoo car's included (``get_car(name).make_plant(seed)``).
        seed : int, optional
            Seed of the sensors' random numbers (:class:`SensedPlant`), an integer >= 0.
        """
        if self.is_ideal:
            return plant
        return SensedPlant(plant, self, seed)

    def with_overrides(self, overrides: Mapping[str, Any]) -> SensorProfile:
        """A copy with some settings changed (a car file's ``[sensors]`` section).

        Parameters
        ----------
        overrides : mapping
            ``measures_steer_angle`` / ``measures_slip_angle`` to a bool; ``localiser``,
            ``wheel_speed`` or ``yaw_rate`` to a mapping of that part's fields to new
            values, e.g. ``{"localiser": {"latency": 0.05}, "wheel_speed": {"scale": 1.05}}``.
            The summary of the copy names what was changed.

        Raises
        ------
        ParameterError
            Naming the setting (``sensors.localiser.latency``) when it is unknown, when the
            profile has no such part to change, or when the new value is invalid.
        """
        changes: dict[str, Any] = {}
        changed: list[str] = []
        for key, value in overrides.items():
            if key in _FLAGS:
                changes[key] = value
                changed.append(key)
                continue
            if key not in _PARTS:
                known = ", ".join([*_PARTS, *_FLAGS])
                raise ParameterError(f"sensors.{key}: unknown setting; known: {known}")
            part = getattr(self, key)
            if part is None:
                raise ParameterError(
                    f"sensors.{key}: the profile {self.name!r} has no {key} (it reports the true value); "
                    "start from a profile that has one"
                )
            if not isinstance(value, Mapping):
                raise ParameterError(f"sensors.{key} must be a table of {type(part).__name__} fields")
            names = [f.name for f in fields(part)]
            for field in value:
                if field not in names:
                    raise ParameterError(f"sensors.{key}.{field}: unknown field; known: {', '.join(names)}")
            try:
                changes[key] = replace(part, **value)
            except ParameterError as exc:
                raise ParameterError(f"sensors.{key}: {exc}") from None
            changed.extend(f"{key}.{field}" for field in value)
        if not changed:
            return self
        summary = f"{self.summary} (changed: {', '.join(changed)})"
        return replace(self, summary=summary, **changes)

    def describe(self) -> dict[str, Any]:
        """A JSON-ready description (every part with its type and values, or None), for result files."""

        def part(value: object) -> dict[str, Any] | None:
            if value is None:
                return None
            return {"type": type(value).__name__, **to_json_ready(asdict(value))}  # type: ignore[call-overload]

        return {
            "name": self.name,
            "summary": self.summary,
            **{name: part(getattr(self, name)) for name in _PARTS},
            **{name: getattr(self, name) for name in _FLAGS},
        }


class SensedPlant(PlantWrapper):
    """A plant whose observations come from the sensors of a :class:`SensorProfile`.

    The observation's pose is the newest localiser sample that has arrived
    (taken at least ``latency`` ago), with ``pose_time`` the time its pose was
    true; ``speed`` and ``yaw_rate`` are measured afresh at every observation;
    ``steer_angle`` and ``slip_angle`` are NaN when the profile does not measure
    them. A part the profile leaves out (None) reports the true value, as the
    bare plant does (the pose then with ``pose_time`` NaN).

    Random numbers come from ``numpy.random.default_rng(seed)``, split into one
    independent stream per part (localiser, wheel speed, yaw rate), so changing
    one part's settings does not change another's noise. :meth:`reset` re-seeds:
    an episode started from the same state with the same commands sees the same
    observations. The sample taken at :meth:`reset` (and at construction) counts
    as arrived at once.

    Wrap a plant whose commands act in time (an
    :class:`~rkmpc.vehicle.plants.base.ActuatedPlant`, possibly wrapped), not a
    :class:`~rkmpc.vehicle.wrappers.CommandDelay`, which counts steps: a step is
    split into pieces at the localiser's sample instants. A latency of the
    wrapped plant's own (a zoo car's ``odometry_latency``) adds to the
    localiser's.

    Parameters
    ----------
    plant : Plant
        The plant to wrap.
    profile : SensorProfile
        The sensors.
    seed : int
        Seed of the sensors' random numbers, an integer >= 0.
    """

    def __init__(self, plant: Plant, profile: SensorProfile, seed: int) -> None:
        if not is_integer(seed, 0):
            raise ParameterError(f"SensedPlant.seed must be an integer >= 0, got {seed!r}")
        super().__init__(plant)
        self.profile = profile
        self.seed = int(seed)
        self._restart()

    def _restart(self) -> None:
        """Re-seed, take the first localiser sample now and make the first observation."""
        localiser_rng, speed_rng, yaw_rate_rng = np.random.default_rng(self.seed).spawn(3)
        self._speed_rng = speed_rng
        self._yaw_rate_rng = yaw_rate_rng
        spec = self.profile.localiser
        self._localiser = None if spec is None else LocaliserRun(spec, localiser_rng)
        if self._localiser is not None:
            self._localiser.sample(self.plant.time, self.plant.observe())
        self._observation = self._measure()

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        super().reset(x, y, yaw, speed, steer)
        self._restart()

    def step(self, command: Command, dt: float) -> None:
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0, got {dt!r}")
        plant = self.plant
        end = plant.time + dt
        localiser = self._localiser
        if localiser is not None:
            while localiser.next_instant <= end + TIME_EPS:
                instant = min(localiser.next_instant, end)
                if instant - plant.time > TIME_EPS:
                    plant.step(command, instant - plant.time)
                localiser.sample(plant.time, plant.observe())
        if end - plant.time > TIME_EPS:
            plant.step(command, end - plant.time)
        self._observation = self._measure()

    def observe(self) -> Observation:
        return self._observation

    def _measure(self) -> Observation:
        """The observation at the wrapped plant's current time (draws the speed and yaw-rate noise)."""
        profile = self.profile
        true = self.plant.observe()
        x, y, yaw, pose_time = true.x, true.y, true.yaw, math.nan
        if self._localiser is not None:
            pose = self._localiser.newest_arrived(self.plant.time)
            x, y, yaw, pose_time = pose.x, pose.y, pose.yaw, pose.pose_time
        speed = true.speed
        if profile.wheel_speed is not None:
            speed = profile.wheel_speed.measure(true.speed, self._speed_rng)
        yaw_rate = true.yaw_rate
        if profile.yaw_rate is not None:
            yaw_rate = profile.yaw_rate.measure(true.yaw_rate, self._yaw_rate_rng)
        return Observation(
            x=x,
            y=y,
            yaw=yaw,
            speed=speed,
            yaw_rate=yaw_rate,
            slip_angle=true.slip_angle if profile.measures_slip_angle else math.nan,
            steer_angle=true.steer_angle if profile.measures_steer_angle else math.nan,
            time=true.time,
            pose_time=pose_time,
        )
