"""The one loader of car files: the packaged presets and a user's file (TOML, or YAML for ROS users).

A user's car file names the preset it builds on and overrides what it gives::

    [vehicle]
    preset = "f1tenth"          # a packaged preset (rkmpc/config/presets/*.toml): the base
    mass = 3.74                 # any field of VehicleParams but its name (the controllers' model)
    [vehicle.steering]
    max_angle = 0.41

    [plant]
    car = "gym"                 # drive a zoo car instead of the preset's plant (f1tenth only)

    [limits]                    # SpeedLimits: the pace of the speed profile
    lateral_accel = 6.0

    [controllers.lmpc]          # LMPCConfig: lmpc, lmpc-id, kmpc and the baseline of the rkmpcs
    horizon = 30
    [controllers.rkmpc]         # RKMPCConfig; [controllers.rkmpc-paper] ResidualMPCConfig
    max_steer_correction = 0.15
    [controllers.pp]            # PurePursuitConfig; [controllers.nmpc] NMPCConfig

    [training]
    epochs = 100

    [sensors]                   # what the simulated car measures (rkmpc.vehicle.sensors)
    profile = "f1tenth-real"    # "ideal" (default), "no-steer", "f1tenth-real"
    [sensors.localiser]
    latency = 0.05
    [estimator]                 # EstimatorConfig: the state estimator used with such sensors
    position_std = 0.1

    [ros]                       # RosSettings: rkmpc node
    rate_hz = 20.0
    [ros.topics]
    odometry = "/car_state/odom"

A section given overrides only the keys it names, on top of the preset's values. Unknown
sections and keys are refused, every value is checked against its field's type and by the
settings' own validation, and every error names the file and the key
(:class:`~rkmpc.core.errors.InputFileError`). A preset file (package data) has no ``preset`` but
``params`` (a name of :data:`rkmpc.vehicle.params.PARAMS`), ``file_scale`` and ``[plant] model``.
"""

from __future__ import annotations

import functools
import hashlib
import tomllib
from collections.abc import Mapping
from dataclasses import fields, replace
from importlib import resources
from pathlib import Path
from typing import Any

from rkmpc.config.car import CarConfig, PlantSettings, TrainingSettings
from rkmpc.config.ros import RosSettings
from rkmpc.control.settings import SECTIONS as CONTROLLER_SECTIONS
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.reading import check_regular_file
from rkmpc.core.registry import Registry
from rkmpc.core.settings import build_dataclass, check_keys, check_value
from rkmpc.core.validation import is_positive_number
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.track.speed_profile import SpeedLimits
from rkmpc.vehicle.params import PARAMS, VehicleParams
from rkmpc.vehicle.sensors import SensorProfile, get_sensor_profile

__all__ = ["MAX_FILE_BYTES", "PRESETS", "load_car_config", "load_preset", "read_settings_file"]

SECTIONS = ("vehicle", "plant", "limits", "controllers", "training", "sensors", "estimator", "ros")
#: The packaged presets by name: their file in ``rkmpc/config/presets``.
PRESETS: Registry[str] = Registry("car preset", {"f1tenth": "f1tenth.toml", "fullsize": "fullsize.toml"})
#: The largest settings file read (bytes): a car file is a few kilobytes.
MAX_FILE_BYTES = 1 << 20
_YAML_SUFFIXES = (".yaml", ".yml")


def read_settings_file(path: Path) -> tuple[dict[str, Any], bytes]:
    """A TOML (or, by its suffix, YAML) settings file as a mapping, and its bytes.

    Only a regular file of at most :data:`MAX_FILE_BYTES` is read (a FIFO or a device would block
    or never end).
    """
    size = check_regular_file(path)
    if size > MAX_FILE_BYTES:
        raise InputFileError(path, f"{size} bytes; a settings file is at most {MAX_FILE_BYTES}")
    try:
        raw = path.read_bytes()[: MAX_FILE_BYTES + 1]
        text = raw.decode("utf-8")
    except OSError as exc:
        raise InputFileError(path, f"cannot read the file: {exc}") from None
    except UnicodeDecodeError as exc:
        raise InputFileError(path, f"not UTF-8 text: {exc}") from None
    if path.suffix.lower() in _YAML_SUFFIXES:
        return _yaml(text, path), raw
    try:
        return tomllib.loads(text), raw
    except tomllib.TOMLDecodeError as exc:
        raise InputFileError(path, f"not a valid TOML file: {exc}") from None


def _yaml(text: str, path: Path) -> dict[str, Any]:
    try:
        import yaml
    except ImportError:  # pragma: no cover - the ros extra brings PyYAML
        raise InputFileError(
            path, "reading YAML needs PyYAML (pip install 'rkmpc[ros]'), or give TOML"
        ) from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise InputFileError(path, f"not a valid YAML file: {exc}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise InputFileError(path, f"expected a mapping of sections, got {type(data).__name__}")
    return data


@functools.cache
def load_preset(name: str) -> CarConfig:
    """The packaged preset ``name`` (:data:`PRESETS`), read once."""
    filename = PRESETS[name]
    with resources.as_file(resources.files("rkmpc.config") / "presets" / filename) as path:
        data, _ = read_settings_file(path)
        return _build(data, path, base=None, name=name)


def load_car_config(path: str | Path, overrides: Mapping[str, Any] | None = None) -> CarConfig:
    """Read and validate a car file; what it leaves out is its preset's.

    Parameters
    ----------
    path : str or Path
        A TOML file (or YAML, by its suffix ``.yaml``/``.yml``).
    overrides : mapping, optional
        Dotted keys set over the file's (``"ros.safety.odometry_timeout"``: a ROS parameter).

    Raises
    ------
    InputFileError
        For a missing, special or oversized file, invalid TOML/YAML, an unknown section or key, a
        value of the wrong type or out of range, an unknown preset or zoo car; it names the file
        and the key.
    """
    path = Path(path)
    data, raw = read_settings_file(path)
    for key, value in (overrides or {}).items():
        _set_dotted(data, key, value, path)
    vehicle = _section(data, "vehicle", path)
    if "params" in vehicle:
        raise InputFileError(
            path, "only a packaged preset sets params; name one with preset", "vehicle.params"
        )
    preset = check_value(str, vehicle["preset"] if "preset" in vehicle else "f1tenth", path, "vehicle.preset")
    if preset not in PRESETS:
        raise InputFileError(path, _unknown_preset(preset), "vehicle.preset")
    config = _build(data, path, base=load_preset(preset), name=preset)
    ros = config.ros
    if ros.record.bag is not None and not Path(ros.record.bag).expanduser().is_absolute():
        bag = str(path.resolve().parent / ros.record.bag)
        ros = replace(ros, record=replace(ros.record, bag=bag))
    return replace(config, ros=ros, source=str(path.resolve()), sha256=hashlib.sha256(raw).hexdigest())


def _unknown_preset(name: str) -> str:
    try:
        PRESETS.check(name)
    except ParameterError as exc:
        return str(exc)
    return ""  # pragma: no cover


def _build(data: Mapping[str, Any], path: Path, *, base: CarConfig | None, name: str) -> CarConfig:
    check_keys(data, SECTIONS, path, "", " (a section)")
    sections = {section: _section(data, section, path) for section in SECTIONS}
    vehicle = dict(sections["vehicle"])
    root = base is None
    own = ("params", "file_scale") if root else ("preset", "file_scale")
    check_keys(
        vehicle, [*own, *(f.name for f in fields(VehicleParams) if f.name != "name")], path, "vehicle."
    )
    for key in own:
        vehicle.pop(key, None)
    if base is None:
        params_name = check_value(str, sections["vehicle"]["params"], path, "vehicle.params")
        try:
            params = PARAMS[params_name]()
        except ParameterError as exc:
            raise InputFileError(path, str(exc), "vehicle.params") from None
        defaults = CarConfig(preset=name, vehicle=params, file_scale=sections["vehicle"]["file_scale"])
    else:
        defaults = base
    scale = sections["vehicle"]["file_scale"] if "file_scale" in sections["vehicle"] else defaults.file_scale
    if not is_positive_number(check_value(float, scale, path, "vehicle.file_scale")):
        raise InputFileError(path, f"file_scale must be finite and > 0, got {scale!r}", "vehicle.file_scale")
    try:
        return CarConfig(
            preset=name,
            vehicle=build_dataclass(VehicleParams, vehicle, path, "vehicle.", base=defaults.vehicle),
            file_scale=check_value(float, scale, path, "vehicle.file_scale"),
            plant=build_dataclass(PlantSettings, sections["plant"], path, "plant.", base=defaults.plant),
            limits=build_dataclass(SpeedLimits, sections["limits"], path, "limits.", base=defaults.limits),
            controllers=_controllers(sections["controllers"], defaults.controllers, path),
            training=build_dataclass(
                TrainingSettings, sections["training"], path, "training.", base=defaults.training
            ),
            sensors=_sensors(sections["sensors"], defaults.sensors, path),
            estimator=build_dataclass(
                EstimatorConfig, sections["estimator"], path, "estimator.", base=defaults.estimator
            ),
            ros=build_dataclass(RosSettings, sections["ros"], path, "ros.", base=defaults.ros),
        )
    except ParameterError as exc:
        if isinstance(exc, InputFileError):
            raise
        raise InputFileError(path, str(exc)) from None


def _sensors(section: Mapping[str, Any], base: SensorProfile, path: Path) -> SensorProfile:
    """``[sensors]``: ``profile = NAME`` (else the base's), then overrides of its parts' fields."""
    overrides = dict(section)
    profile = base
    if "profile" in overrides:
        name = check_value(str, overrides.pop("profile"), path, "sensors.profile")
        try:
            profile = get_sensor_profile(name)
        except ParameterError as exc:
            raise InputFileError(path, str(exc), "sensors.profile") from None
    try:
        return profile.with_overrides(overrides)
    except ParameterError as exc:
        message = str(exc)
        key = message.split(":", 1)[0] if message.startswith("sensors.") else "sensors"
        raise InputFileError(path, message.split(": ", 1)[-1], key) from None


def _section(data: Mapping[str, Any], name: str, path: Path, prefix: str = "") -> Mapping[str, Any]:
    value = data[name] if name in data else {}
    if not isinstance(value, Mapping):
        raise InputFileError(
            path, f"expected a section ([{prefix}{name}]), got {value!r}", field=f"{prefix}{name}"
        )
    return value


def _controllers(section: Mapping[str, Any], base: ControllerSettings, path: Path) -> ControllerSettings:
    check_keys(section, CONTROLLER_SECTIONS, path, "controllers.")
    values = {}
    for name, (attr, kind) in CONTROLLER_SECTIONS.items():
        given = _section(section, name, path, "controllers.")
        values[attr] = build_dataclass(kind, given, path, f"controllers.{name}.", base=getattr(base, attr))
    return ControllerSettings(**values)


def _set_dotted(data: dict[str, Any], key: str, value: Any, path: Path) -> None:
    """Put an override into the nested mapping; unknown keys are refused when the tree is built."""
    node = data
    parts = key.split(".")
    for part in parts[:-1]:
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise InputFileError(path, f"override {key!r}: {part!r} is not a section", field=key)
        node = child
    node[parts[-1]] = value
