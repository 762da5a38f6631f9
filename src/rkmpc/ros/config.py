"""What ``rkmpc node`` drives: the car file every command reads, and the task given on its command line.

The node reads the same car file as ``rkmpc run --config`` (:func:`rkmpc.config.loader.load_car_config`:
TOML, or YAML by its suffix): the car, its controllers' settings and its ``[ros]`` section
(:class:`rkmpc.config.ros.RosSettings`: topics, frames, rate, safety, latency, recording). A ROS
parameter overrides a key of that section by its dotted name (``--ros-args -p
safety.odometry_timeout:=1.0``). What it drives there (the track, the controller and its model) is
the :class:`NodeTask`, from the command line.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_car_config
from rkmpc.config.ros import RosSettings
from rkmpc.core.errors import ParameterError
from rkmpc.core.settings import build_dataclass
from rkmpc.core.validation import is_positive_number

__all__ = ["NodeTask", "flatten", "load_node_car"]


@dataclass(frozen=True, kw_only=True)
class NodeTask:
    """What the node drives (SI units).

    Parameters
    ----------
    track : str
        A built-in track name or a TUM centre-line CSV file.
    raceline : str or None
        A TUM race-line CSV to track instead of the centre line.
    scale : float or None
        Scale of track files (None: the car's).
    controller : str
        Controller registry name (:data:`rkmpc.control.registry.CONTROLLERS`).
    model : str or None
        Model file of a learned controller (``rkmpc``, ``rkmpc-paper``, ``kmpc``, ``lmpc-id``).
    allow_mismatch : bool
        Drive with a model made with another car, period or track scale (with a warning).
    """

    track: str = "builtin"
    raceline: str | None = None
    scale: float | None = None
    controller: str = "lmpc"
    model: str | None = None
    allow_mismatch: bool = False

    def __post_init__(self) -> None:
        if self.scale is not None and not is_positive_number(self.scale):
            raise ParameterError(f"NodeTask.scale must be finite and > 0, got {self.scale!r}")


def load_node_car(car: CarConfig | str | Path, overrides: Mapping[str, Any] | None = None) -> CarConfig:
    """The car (or the car file at a path) with ROS-parameter ``overrides`` of its ``[ros]`` keys.

    ``overrides`` are dotted names within the section (``"safety.odometry_timeout"``).

    Raises
    ------
    InputFileError
        As :func:`rkmpc.config.loader.load_car_config`; an unknown parameter is an unknown key of
        the ``[ros]`` section.
    """
    given = {f"ros.{key}": value for key, value in (overrides or {}).items()}
    if not isinstance(car, CarConfig):
        return load_car_config(car, given)
    if not given:
        return car
    nested: dict[str, Any] = {}
    for key, value in (overrides or {}).items():
        node = nested
        *sections, last = key.split(".")
        for section in sections:
            node = node.setdefault(section, {})
        node[last] = value
    source = Path(car.source) if car.source is not None else Path("<ROS parameters>")
    ros = build_dataclass(RosSettings, nested, source, "ros.", base=car.ros, hint=" (a ROS parameter)")
    return replace(car, ros=ros)


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
