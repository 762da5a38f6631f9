"""How one agent's :class:`~rkmpc.core.observation.Observation` is read from an F1TENTH-style observation.

Environments with the F1TENTH gym's conventions hand out their observation in one of two shapes:

* **flat** (:class:`FlatLayout`): a dict of arrays with one value per agent, ``poses_x``,
  ``poses_y``, ``poses_theta``, ``linear_vels_x``, ``linear_vels_y``, ``ang_vels_z``, ... The F1TENTH
  gym's default observation (type ``None`` or ``"original"``, which also carries the lidar
  ``scans``) and :class:`rkmpc.envs.f1tenth.F1TenthTrackEnv` (no ``scans``, plus
  ``steering_angles``) have it;
* **per agent** (:class:`AgentFeaturesLayout`): a dict ``{"agent_0": {...}, "agent_1": ...}`` of
  one dict of scalars per agent, the F1TENTH gym's ``"features"`` observations, among them
  ``"kinematic_state"`` (``pose_x``, ``pose_y``, ``delta``, ``linear_vel_x``, ``pose_theta``) and
  ``"dynamic_state"`` (those and ``ang_vel_z``, ``beta``).

A value the environment does not measure is NaN in the :class:`Observation`, never 0: the F1TENTH
gym's default observation has ``linear_vels_y`` fixed at 0 (its dynamic model's lateral velocity is
not given), so :data:`F1TENTH_GYM` reads no side-slip angle and, having no wheel angle either,
leaves both NaN. Every layout takes ``unmeasured``, observation fields it reports as NaN even where
the environment gives a value: the F1TENTH gym's kinematic model fills its yaw rate and slip with a
placeholder 0, and a user who wants what a real car measures drops the wheel angle of
``"dynamic_state"``.

Nothing here needs ``gymnasium``.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from rkmpc.control.base import OPTIONAL_FIELDS
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation

__all__ = [
    "F1TENTH_GYM",
    "GYM_FEATURES",
    "LAYOUTS",
    "RKMPC_ENV",
    "AgentFeaturesLayout",
    "FlatLayout",
    "ObservationLayout",
    "detect_layout",
]

#: Keys a flat observation must hold: pose (m, m, rad), speed and lateral velocity (m/s), yaw rate (rad/s).
REQUIRED_KEYS = ("poses_x", "poses_y", "poses_theta", "linear_vels_x", "linear_vels_y", "ang_vels_z")
#: Features an agent's observation must hold (pose and speed along the heading).
REQUIRED_FEATURES = ("pose_x", "pose_y", "pose_theta", "linear_vel_x")


@dataclass(frozen=True)
class ObservationLayout(ABC):
    """How to read one agent's :class:`Observation` from an environment's observation.

    Parameters
    ----------
    name : str
        Name of the layout, for messages.
    unmeasured : tuple of str
        Optional observation fields (``yaw_rate``, ``slip_angle``, ``steer_angle``) reported as
        NaN whatever the environment gives.
    """

    name: str
    unmeasured: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        wrong = [f for f in self.unmeasured if f not in OPTIONAL_FIELDS]
        if wrong:
            raise ParameterError(
                f"{type(self).__name__}.unmeasured may name only {OPTIONAL_FIELDS}, got {list(wrong)}"
            )

    @property
    def never_measured(self) -> tuple[str, ...]:
        """Optional fields this layout never reads (NaN at every step, whatever the environment)."""
        return self.unmeasured

    @abstractmethod
    def matches(self, observation: Mapping[str, Any]) -> bool:
        """Whether ``observation`` has this layout's shape (:func:`detect_layout`)."""

    @abstractmethod
    def agents(self, observation: Mapping[str, Any]) -> int:
        """Number of agents in ``observation``."""

    @abstractmethod
    def values(self, observation: Mapping[str, Any], agent: int) -> dict[str, float]:
        """``x, y, yaw, speed, yaw_rate, slip_angle, steer_angle`` of ``agent``, NaN where not given."""

    def read(self, observation: Mapping[str, Any], *, agent: int = 0, time: float = 0.0) -> Observation:
        """The :class:`Observation` of ``agent`` at ``time`` (s), its :attr:`unmeasured` fields NaN.

        Raises
        ------
        ParameterError
            When a key is missing, the agent does not exist, or the pose or speed is not finite.
        """
        values = self.values(observation, agent)
        for name in self.unmeasured:
            values[name] = math.nan
        pose = (values["x"], values["y"], values["yaw"], values["speed"])
        if not all(math.isfinite(v) for v in pose):
            raise ParameterError(
                f"agent {agent}'s pose and speed must be finite, got x={pose[0]}, y={pose[1]}, "
                f"yaw={pose[2]}, vx={pose[3]}"
            )
        return Observation(**values, time=time)

    def without(self, *fields: str) -> ObservationLayout:
        """This layout with ``fields`` reported as NaN too (what a real car does not measure)."""
        return replace(self, unmeasured=tuple(dict.fromkeys((*self.unmeasured, *fields))))


def _agent_value(values: Any, key: str, agent: int) -> float:
    array = np.asarray(values, dtype=np.float64).reshape(-1)
    if agent >= array.size:
        raise ParameterError(f"the observation's {key!r} has {array.size} agent(s); agent {agent} asked for")
    return float(array[agent])


@dataclass(frozen=True)
class FlatLayout(ObservationLayout):
    """A dict of arrays with one value per agent (the F1TENTH gym's default observation).

    ``x, y, yaw`` are ``poses_x, poses_y, poses_theta``; ``speed`` is ``linear_vels_x``; the yaw rate
    ``ang_vels_z``; the side-slip angle ``atan2(linear_vels_y, linear_vels_x)`` when
    :attr:`lateral_velocity` (else NaN); the wheel angle the :attr:`steering_key` array when given
    and present (else NaN).

    Parameters
    ----------
    name, unmeasured
        See :class:`ObservationLayout`.
    lateral_velocity : bool
        Whether ``linear_vels_y`` is a measurement (False: the F1TENTH gym's fixed 0).
    steering_key : str or None
        Key of the measured front wheel angles (rad), or None when there are none.
    marker : str or None
        A key only this layout's observations have (:meth:`matches`), or None.
    """

    lateral_velocity: bool = True
    steering_key: str | None = None
    marker: str | None = None

    @property
    def never_measured(self) -> tuple[str, ...]:
        absent = {"slip_angle": not self.lateral_velocity, "steer_angle": self.steering_key is None}
        return tuple(dict.fromkeys((*self.unmeasured, *(name for name, gone in absent.items() if gone))))

    def matches(self, observation: Mapping[str, Any]) -> bool:
        return "poses_x" in observation and (self.marker is None or self.marker in observation)

    def agents(self, observation: Mapping[str, Any]) -> int:
        return int(np.asarray(observation["poses_x"]).size) if "poses_x" in observation else 0

    def values(self, observation: Mapping[str, Any], agent: int) -> dict[str, float]:
        missing = [key for key in REQUIRED_KEYS if key not in observation]
        if missing:
            raise ParameterError(
                f"the observation lacks the F1TENTH keys {missing}; it has {sorted(observation)}"
            )
        x, y, yaw, vx, vy, r = (_agent_value(observation[key], key, agent) for key in REQUIRED_KEYS)
        slip = math.atan2(vy, vx) if self.lateral_velocity and math.isfinite(vy) else math.nan
        key = self.steering_key
        given = key is not None and key in observation
        steer = _agent_value(observation[key], key, agent) if key is not None and given else math.nan
        return {
            "x": x,
            "y": y,
            "yaw": yaw,
            "speed": vx,
            "yaw_rate": r,
            "slip_angle": slip,
            "steer_angle": steer,
        }


@dataclass(frozen=True)
class AgentFeaturesLayout(ObservationLayout):
    """One dict of features per agent, ``{"agent_0": {...}, ...}`` (the F1TENTH gym's ``"features"``).

    ``x, y, yaw`` are ``pose_x, pose_y, pose_theta``; ``speed`` is ``linear_vel_x`` (along the
    heading); the yaw rate ``ang_vel_z``; the side-slip angle ``beta``, else
    ``atan2(linear_vel_y, linear_vel_x)``; the wheel angle ``delta``. A feature the observation does
    not carry is NaN.
    """

    prefix: str = "agent_"

    def matches(self, observation: Mapping[str, Any]) -> bool:
        return f"{self.prefix}0" in observation and isinstance(observation[f"{self.prefix}0"], Mapping)

    def agents(self, observation: Mapping[str, Any]) -> int:
        return sum(1 for key in observation if str(key).startswith(self.prefix))

    def values(self, observation: Mapping[str, Any], agent: int) -> dict[str, float]:
        key = f"{self.prefix}{agent}"
        if key not in observation:
            raise ParameterError(
                f"the observation has {self.agents(observation)} agent(s) {sorted(map(str, observation))}; "
                f"agent {agent} ({key!r}) asked for"
            )
        features = observation[key]
        missing = [name for name in REQUIRED_FEATURES if name not in features]
        if missing:
            raise ParameterError(
                f"the observation of {key!r} lacks the features {missing}; it has {sorted(features)}"
            )

        def feature(name: str) -> float:
            return float(np.asarray(features[name], dtype=np.float64)) if name in features else math.nan

        vx = feature("linear_vel_x")
        slip = feature("beta")
        if not math.isfinite(slip) and "linear_vel_y" in features:
            slip = math.atan2(feature("linear_vel_y"), vx)
        return {
            "x": feature("pose_x"),
            "y": feature("pose_y"),
            "yaw": feature("pose_theta"),
            "speed": vx,
            "yaw_rate": feature("ang_vel_z"),
            "slip_angle": slip,
            "steer_angle": feature("delta"),
        }


#: The F1TENTH gym's default observation: ``linear_vels_y`` is its fixed 0 and there is no wheel
#: angle, so the side-slip and wheel angles are NaN. Recognised by its lidar ``scans``.
F1TENTH_GYM = FlatLayout(name="f1tenth-gym", lateral_velocity=False, marker="scans")
#: The F1TENTH gym's per-agent ``"features"`` observations (``"dynamic_state"``, ...).
GYM_FEATURES = AgentFeaturesLayout(name="f1tenth-gym-features")
#: :class:`rkmpc.envs.f1tenth.F1TenthTrackEnv`: a measured lateral velocity and ``steering_angles``.
RKMPC_ENV = FlatLayout(name="rkmpc-env", lateral_velocity=True, steering_key="steering_angles")
#: The layouts :func:`detect_layout` tries, most specific first.
LAYOUTS: tuple[ObservationLayout, ...] = (GYM_FEATURES, F1TENTH_GYM, RKMPC_ENV)


def detect_layout(observation: Mapping[str, Any]) -> ObservationLayout:
    """The first of :data:`LAYOUTS` whose shape ``observation`` has.

    The F1TENTH gym's per-agent features give :data:`GYM_FEATURES`; its default observation (with
    ``scans``) :data:`F1TENTH_GYM`; any other flat one :data:`RKMPC_ENV`.

    Raises
    ------
    ParameterError
        When the observation has neither shape.
    """
    for layout in LAYOUTS:
        if layout.matches(observation):
            return layout
    raise ParameterError(
        "the observation is neither the F1TENTH gym's flat dict (poses_x, ...) nor its per-agent "
        f"features (agent_0, ...); it has the keys {sorted(map(str, observation))}"
    )
