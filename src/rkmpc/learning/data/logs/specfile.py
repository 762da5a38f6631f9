"""CSV log specs from TOML files, the built-in presets, and a spec written back as TOML.

A spec file (every key checked; errors name the file and the dotted key)::

    name = "my-logger"            # optional; default: the file's name without .toml
    description = "..."           # optional

    [time]                        # time columns of every file (a signal may give its own [x.time])
    seconds = "s"
    nanoseconds = "ns"            # optional; unit = "s" (or "ms", "us", "ns") for the seconds

    [pose]                        # x, y and yaw = "column" OR quaternion = ["qx", "qy", "qz", "qw"]
    file = "pose.csv"
    x = "x"
    y = "y"
    quaternion = ["q.x", "q.y", "q.z", "q.w"]
    unit = "m"                    # optional: m, cm, mm; yaw_unit = "rad" or "deg"; frame = "cog"

    [speed]                       # signed speed along the heading
    file = "odom.csv"
    column = "vx"
    unit = "m/s"                  # m/s, km/h, mm/s; optional scale = 1.0 (a gain or -1)

    [yaw_rate]                    # optional section
    file = "imu.csv"
    column = "wz"
    unit = "deg/s"                # rad/s, deg/s; optional scale

    [command]
    file = "cmd.csv"
    speed = "V"
    steer = "delta"               # optional speed_unit = "m/s", steer_unit = "rad"

    [import]                      # optional: dt, max_gap, command_hold, command_tolerance,
    dt = 0.05                     # jump_distance, jump_yaw, min_samples (CsvLogSpec)
"""

from __future__ import annotations

import json
import re
import tomllib
import typing
from collections.abc import Mapping
from dataclasses import MISSING, fields
from pathlib import Path
from typing import Any

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.settings import check_keys, check_value
from rkmpc.learning.data.logs.presets import PRESETS
from rkmpc.learning.data.logs.spec import CommandSource, CsvLogSpec, PoseSource, TimeColumns, ValueSource

__all__ = ["csv_spec", "load_csv_spec", "spec_toml"]

_SIGNALS: dict[str, type] = {
    "pose": PoseSource,
    "speed": ValueSource,
    "yaw_rate": ValueSource,
    "command": CommandSource,
}
_SETTINGS = (
    "dt",
    "max_gap",
    "command_hold",
    "command_tolerance",
    "jump_distance",
    "jump_yaw",
    "min_samples",
    "speed_command",
)
_TOP = ("name", "description", "time", *_SIGNALS, "import")


def csv_spec(name_or_path: str | Path) -> CsvLogSpec:
    """A preset by name (:data:`~rkmpc.learning.data.logs.presets.PRESETS`) or a spec file's content.

    Raises
    ------
    InputFileError
        For an unreadable or invalid file, naming the key; for a name that is neither a preset
        nor a file (listing the presets).
    """
    text = str(name_or_path)
    if text in PRESETS:
        return PRESETS[text]
    path = Path(name_or_path)
    if not path.is_file():
        raise InputFileError(path, f"no such spec file, nor a preset ({sorted(PRESETS)})")
    return load_csv_spec(path)


def load_csv_spec(path: str | Path) -> CsvLogSpec:
    """The :class:`CsvLogSpec` of a TOML file (module docstring); InputFileError naming the key."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise InputFileError(path, f"cannot read the spec file: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputFileError(path, f"not a valid TOML file: {exc}") from None
    check_keys(data, _TOP, path, "")
    for section in ("pose", "speed", "command"):
        if section not in data:
            raise InputFileError(path, f"missing section [{section}]", field=section)
    default_time = _time(data["time"], path, "time") if "time" in data else None
    values: dict[str, Any] = {
        "name": check_value(str, data["name"], path, "name") if "name" in data else path.stem,
        "description": check_value(str, data["description"], path, "description")
        if "description" in data
        else "",
    }
    for section, kind in _SIGNALS.items():
        values[section] = (
            _signal(kind, data[section], path, section, default_time) if section in data else None
        )
    settings = _mapping(data["import"], path, "import") if "import" in data else {}
    check_keys(settings, _SETTINGS, path, "import.")
    hints = typing.get_type_hints(CsvLogSpec)
    for key, raw in settings.items():
        values[key] = check_value(hints[key], raw, path, f"import.{key}")
    try:
        return CsvLogSpec(**values)
    except ParameterError as exc:
        raise InputFileError(path, str(exc), field=_culprit(str(exc), values, "")) from None


def _mapping(raw: Any, path: Path, key: str) -> Mapping[str, Any]:
    if not isinstance(raw, Mapping):
        raise InputFileError(path, f"expected a section (a table), got {raw!r}", field=key)
    return raw


def _time(raw: Any, path: Path, key: str) -> TimeColumns:
    return typing.cast(TimeColumns, _build(TimeColumns, _mapping(raw, path, key), path, key, None))


def _signal(kind: type, raw: Any, path: Path, key: str, default_time: TimeColumns | None) -> Any:
    section = dict(_mapping(raw, path, key))
    if "time" in section:
        section["time"] = _time(section["time"], path, f"{key}.time")
    elif default_time is not None:
        section["time"] = default_time
    else:
        raise InputFileError(
            path, "no time columns: give a [time] section or this signal's own", f"{key}.time"
        )
    return _build(kind, section, path, key, TimeColumns)


def _build(kind: type, section: Mapping[str, Any], path: Path, key: str, nested: type | None) -> Any:
    """``kind(**section)``, each key checked against its fields and types; errors name ``key.field``."""
    names = [f.name for f in fields(kind)]
    check_keys(section, names, path, f"{key}.")
    hints = typing.get_type_hints(kind)
    values: dict[str, Any] = {}
    for f in fields(kind):
        if f.name not in section:
            if f.default is MISSING and f.default_factory is MISSING:
                raise InputFileError(path, "missing key", field=f"{key}.{f.name}")
            continue
        raw = section[f.name]
        if nested is not None and isinstance(raw, nested):
            values[f.name] = raw
        elif f.name == "quaternion":
            values[f.name] = _columns(raw, 4, path, f"{key}.{f.name}")
        else:
            values[f.name] = check_value(hints[f.name], raw, path, f"{key}.{f.name}")
    try:
        return kind(**values)
    except ParameterError as exc:
        raise InputFileError(path, str(exc), field=_culprit(str(exc), values, f"{key}.")) from None


def _columns(raw: Any, count: int, path: Path, key: str) -> tuple[str, ...]:
    if not (isinstance(raw, list) and len(raw) == count and all(isinstance(c, str) and c for c in raw)):
        raise InputFileError(path, f"expected a list of {count} column names, got {raw!r}", field=key)
    return tuple(raw)


def _culprit(message: str, values: Mapping[str, Any], prefix: str) -> str | None:
    """The dotted key the message is about: the longest field path it names, else the section.

    ``CsvLogSpec.speed.unit must be ...`` is about ``speed.unit``; a setting of ``[import]`` is
    named under it.
    """
    named: list[str] = []
    text = message.replace(f"{_owner(message)}.", "")
    for name in values:
        found = re.search(rf"(?<![\w.]){re.escape(name)}(?:\.\w+)*\b", text)
        if found:
            named.append(found.group(0))
    if not named:
        return prefix.rstrip(".") or None
    key = max(named, key=len)
    return f"{prefix}{'import.' if key in _SETTINGS else ''}{key}"


def _owner(message: str) -> str:
    """The class a validation message starts with (``CsvLogSpec`` of ``CsvLogSpec.dt must ...``)."""
    found = re.match(r"(\w+)[.:]", message)
    return found.group(1) if found else ""


def spec_toml(spec: CsvLogSpec) -> str:
    """The spec as a TOML file :func:`load_csv_spec` reads back to an equal spec."""
    lines = [f"name = {_toml(spec.name)}", f"description = {_toml(spec.description)}", ""]
    for section in _SIGNALS:
        source = getattr(spec, section)
        if source is None:
            continue
        lines.append(f"[{section}]")
        for f in fields(source):
            value = getattr(source, f.name)
            if f.name != "time" and value is not None:
                lines.append(f"{f.name} = {_toml(value)}")
        lines.append(f"[{section}.time]")
        for f in fields(TimeColumns):
            value = getattr(source.time, f.name)
            if value is not None:
                lines.append(f"{f.name} = {_toml(value)}")
        lines.append("")
    lines.append("[import]")
    for name in _SETTINGS:
        value = getattr(spec, name)
        if value is not None:
            lines.append(f"{name} = {_toml(value)}")
    return "\n".join(lines) + "\n"


def _toml(value: Any) -> str:
    """A TOML literal of a str, number or tuple of str."""
    if isinstance(value, str):
        return json.dumps(value)  # a JSON string is a TOML basic string
    if isinstance(value, tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)
