"""The settings of ``rkmpc node``: one YAML file per car, overridable by ROS parameters.

The file is a mapping whose keys are the fields of :class:`NodeConfig`; the sections
(``topics``, ``frames``, ``odometry``, ``latency``, ``safety``, ``speed_limits``, ``record``) are nested
mappings. Every key is optional (the defaults are the F1TENTH simulator's conventions and the
paper's 20 Hz) and unknown keys are refused. A ROS parameter overrides a key by its dotted name
(``--ros-args -p safety.odometry_timeout:=1.0``). Relative paths (track, race line, model, bag) are
relative to the file. Errors name the file and the key.

Example (``docs/car.md`` has the full list)::

    track: ../shared/tracks/centerlines/Monza.csv
    scale: 0.1
    controller: rkmpc
    model: residual.rkm
    topics: {odometry: /car_state/odom, drive: /vesc/high_level/ackermann_cmd_mux/input/nav_1}
    latency: {compensate: true, actuation: 0.05}
    safety: {odometry_timeout: 0.3, max_lateral_error: 0.8}

This module needs PyYAML (a dependency of the ``ros`` extra), not ROS.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.settings import build_dataclass
from rkmpc.learning.data.bags.stream import RECORD_STORAGES
from rkmpc.track.speed_profile import SpeedLimits

__all__ = [
    "Frames",
    "LatencySettings",
    "NodeConfig",
    "OdometrySettings",
    "RecordSettings",
    "SafetySettings",
    "SpeedLimitOverrides",
    "Topics",
    "flatten",
    "load_node_config",
]

TRIGGERS = ("timer", "odometry")
POSE_REFERENCES = ("cog", "rear_axle")
RELIABILITIES = ("reliable", "best_effort")


def _positive(obj: object, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if value is not None and not (math.isfinite(value) and value > 0.0):
            raise ParameterError(f"{name} must be finite and > 0, got {value!r}")


def _choice(obj: object, name: str, allowed: tuple[str, ...]) -> None:
    value = getattr(obj, name)
    if value not in allowed:
        raise ParameterError(f"{name} must be one of {list(allowed)}, got {value!r}")


@dataclass(frozen=True)
class Topics:
    """Topic names (the F1TENTH simulator bridge's by default).

    Parameters
    ----------
    odometry : str
        ``nav_msgs/msg/Odometry`` in.
    drive : str
        ``ackermann_msgs/msg/AckermannDriveStamped`` out.
    steering : str or None
        ``std_msgs/msg/Float64``, the measured front wheel angle (rad), where the car has it.
    diagnostics : str
        ``diagnostic_msgs/msg/DiagnosticArray`` out.
    """

    odometry: str = "/ego_racecar/odom"
    drive: str = "/drive"
    steering: str | None = None
    diagnostics: str = "/diagnostics"


@dataclass(frozen=True)
class Frames:
    """Frame ids.

    Parameters
    ----------
    map : str or None
        The frame the odometry's pose must be in (a message in another is ignored, with a
        warning); None accepts any.
    drive : str
        ``header.frame_id`` of the commands.
    """

    map: str | None = "map"
    drive: str = "base_link"


@dataclass(frozen=True)
class OdometrySettings:
    """How the odometry is read.

    Parameters
    ----------
    pose : str
        ``"cog"``: the pose is the centre of gravity's (the F1TENTH simulator's); ``"rear_axle"``:
        the rear axle's, moved forward by the car's ``lr`` (m) to the centre of gravity.
    reliability : str
        QoS of the subscription: ``"reliable"`` or ``"best_effort"`` (which also hears reliable
        publishers; use it for a localisation that publishes best effort).
    """

    pose: str = "cog"
    reliability: str = "reliable"

    def __post_init__(self) -> None:
        _choice(self, "pose", POSE_REFERENCES)
        _choice(self, "reliability", RELIABILITIES)


@dataclass(frozen=True)
class LatencySettings:
    """Latency compensation (:mod:`rkmpc.ros.latency`).

    Parameters
    ----------
    compensate : bool
        Move each observation over the loop's latency with the kinematic model and the commands
        sent in that window before the controller sees it.
    odometry : float
        Age of the odometry when it arrives (s), >= 0 (a localisation filter's delay).
    actuation : float
        Delay from sending a command to the car acting on it (s), >= 0.
    """

    compensate: bool = False
    odometry: float = 0.0
    actuation: float = 0.0

    def __post_init__(self) -> None:
        for name in ("odometry", "actuation"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ParameterError(f"{name} must be finite and >= 0, got {value!r}")


@dataclass(frozen=True)
class SafetySettings:
    """When the node commands a stop (speed 0, the wheel held where it was).

    Parameters
    ----------
    odometry_timeout : float
        No odometry for longer than this (s) stops the car until odometry returns.
    max_lateral_error : float
        Distance from the reference path (m) beyond which the car is stopped.
    max_heading_error : float
        Heading error (rad) beyond which the car is stopped.
    latch : bool
        A stop for a too large error holds until the node is restarted (True), or lifts when the
        error is back within its limit (False).
    max_speed : float or None
        Commanded speeds are clipped to this (m/s); None for no clip beyond the controller's own.
    """

    odometry_timeout: float = 0.5
    max_lateral_error: float = 1.0
    max_heading_error: float = 1.0
    latch: bool = True
    max_speed: float | None = None

    def __post_init__(self) -> None:
        _positive(self, "odometry_timeout", "max_lateral_error", "max_heading_error", "max_speed")


@dataclass(frozen=True)
class RecordSettings:
    """Recording what the node saw and sent to a bag (``rkmpc node --record``).

    Parameters
    ----------
    bag : str or None
        The ROS 2 bag folder to write; it must not exist. ``{time}`` in it becomes the node's
        start time (``20250131-142501``). None records nothing.
    storage : str
        ``"mcap"`` (the ROS 2 default) or ``"sqlite3"``.
    """

    bag: str | None = None
    storage: str = "mcap"

    def __post_init__(self) -> None:
        _choice(self, "storage", RECORD_STORAGES)


@dataclass(frozen=True)
class SpeedLimitOverrides:
    """Fields of the speed profile's :class:`~rkmpc.track.speed_profile.SpeedLimits` to change.

    Each None keeps the vehicle preset's value (m/s, m/s^2, 1/(m s)).
    """

    lateral_accel: float | None = None
    brake_decel: float | None = None
    accel: float | None = None
    max_speed: float | None = None
    min_speed: float | None = None
    curvature_rate: float | None = None

    def applied_to(self, limits: SpeedLimits) -> SpeedLimits:
        """``limits`` with the fields given here replaced."""
        changes = {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}
        return replace(limits, **changes)


@dataclass(frozen=True)
class NodeConfig:
    """Everything ``rkmpc node`` needs to drive one car (SI units).

    Parameters
    ----------
    track : str
        A built-in track name or a TUM centre-line CSV file.
    raceline : str or None
        A TUM race-line CSV to track instead of the centre line.
    scale : float or None
        Scale of track files (None: the vehicle preset's, 0.1 for the 1:10 car).
    vehicle : str
        Vehicle preset (``"f1tenth"``, ``"fullsize"``): the controllers' car and tuned options.
    controller : str
        Controller registry name (:data:`rkmpc.control.registry.CONTROLLERS`).
    model : str or None
        Model file of a learned controller (``rkmpc``, ``rkmpc-paper``, ``kmpc``, ``lmpc-id``).
    allow_mismatch : bool
        Drive with a model made with another car, period or track scale (with a warning).
    rate_hz : float
        Control rate (Hz); the controller's period is its inverse (the paper's 20 Hz: 0.05 s).
    trigger : str
        ``"timer"``: one command per period of a wall-clock timer, from the latest odometry (a
        car). ``"odometry"``: one command per odometry message, stamped with its stamp (the
        simulated car's lock-step mode); a wall-clock watchdog still stops the car.
    steering_estimate : bool
        Without a steering topic, estimate the wheel angle from the commands sent (the vehicle's
        nominal servo, lag and rate limit: :class:`rkmpc.estimation.steering.SteeringModel`), for
        controllers that use it; NaN otherwise.
    """

    track: str = "builtin"
    raceline: str | None = None
    scale: float | None = None
    vehicle: str = "f1tenth"
    controller: str = "lmpc"
    model: str | None = None
    allow_mismatch: bool = False
    rate_hz: float = 20.0
    trigger: str = "timer"
    steering_estimate: bool = False
    speed_limits: SpeedLimitOverrides = field(default_factory=SpeedLimitOverrides)
    topics: Topics = field(default_factory=Topics)
    frames: Frames = field(default_factory=Frames)
    odometry: OdometrySettings = field(default_factory=OdometrySettings)
    latency: LatencySettings = field(default_factory=LatencySettings)
    safety: SafetySettings = field(default_factory=SafetySettings)
    record: RecordSettings = field(default_factory=RecordSettings)

    def __post_init__(self) -> None:
        _positive(self, "rate_hz", "scale")
        _choice(self, "trigger", TRIGGERS)

    @property
    def period(self) -> float:
        """The control period (s)."""
        return 1.0 / self.rate_hz


def flatten(config: Any, prefix: str = "") -> dict[str, Any]:
    """``{dotted key: value}`` of a config (dataclass) or of a mapping, sections flattened."""
    items = (
        {f.name: getattr(config, f.name) for f in fields(config)} if is_dataclass(config) else dict(config)
    )
    out: dict[str, Any] = {}
    for key, value in items.items():
        name = f"{prefix}{key}"
        if is_dataclass(value) or isinstance(value, Mapping):
            out.update(flatten(value, f"{name}."))
        else:
            out[name] = value
    return out


def load_node_config(path: str | Path, overrides: Mapping[str, Any] | None = None) -> NodeConfig:
    """Read a car's node settings from YAML, apply ROS-parameter ``overrides`` (dotted keys), validate.

    Raises
    ------
    InputFileError
        For a missing or unreadable file, invalid YAML, an unknown key (in the file or among the
        overrides), a value of the wrong type or out of range; it names the file and the key.
    """
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise InputFileError(path, "file not found") from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise InputFileError(path, f"not a readable YAML file: {exc}") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise InputFileError(path, f"expected a mapping of settings, got {type(data).__name__}")
    for key, value in (overrides or {}).items():
        _set_dotted(data, key, value, path)
    config = build_dataclass(NodeConfig, data, path, hint=" (in the file or a ROS parameter)")
    base = path.resolve().parent
    return replace(
        config,
        track=_resolve(config.track, base, builtin_ok=True),
        raceline=None if config.raceline is None else _resolve(config.raceline, base),
        model=None if config.model is None else _resolve(config.model, base),
        record=replace(
            config.record, bag=None if config.record.bag is None else _resolve(config.record.bag, base)
        ),
    )


def _resolve(value: str, base: Path, builtin_ok: bool = False) -> str:
    from rkmpc.track.builtin import list_builtin_tracks

    if builtin_ok and value in list_builtin_tracks():
        return value
    candidate = Path(value).expanduser()
    return str(candidate if candidate.is_absolute() else base / candidate)


def _set_dotted(data: dict[str, Any], key: str, value: Any, path: Path) -> None:
    """Put an override into the nested mapping; unknown keys are refused when the tree is built."""
    node = data
    parts = key.split(".")
    for part in parts[:-1]:
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise InputFileError(path, f"ROS parameter {key!r}: {part!r} is not a section", field=key)
        node = child
    node[parts[-1]] = value
