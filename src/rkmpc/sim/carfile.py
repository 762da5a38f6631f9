"""A car in one file: its preset, parameters, plant, speed limits, controllers and training (TOML).

Every section and key is optional; what the file leaves out is the vehicle preset's
(:data:`rkmpc.sim.scenario.VEHICLES`). Unknown sections and keys are refused, every value is
checked against its field's type and by the settings' own validation, and every error names the
file and the key (:class:`~rkmpc.core.errors.InputFileError`)::

    [vehicle]
    preset = "f1tenth"          # "f1tenth" or "fullsize": the base of everything below
    mass = 3.74                 # any field of VehicleParams but its name (the controllers' model)
    [vehicle.steering]
    max_angle = 0.41

    [plant]
    car = "gym"                 # drive a zoo car instead of the preset's plant (f1tenth only)

    [limits]                    # SpeedLimits: the pace of the speed profile
    lateral_accel = 6.0
    max_speed = 5.0

    [controllers.lmpc]          # LMPCConfig: lmpc, lmpc-id, kmpc and the baseline of the rkmpcs
    horizon = 30
    [controllers.rkmpc]         # ResidualMPCConfig (also [controllers.rkmpc-paper])
    max_steer_correction = 0.15
    [controllers.pp]            # PurePursuitConfig
    lookahead_gain = 0.8

    [training]
    epochs = 100
    seed = 0
    data_laps = 2
    kmpc_samples = 50000

A section given overrides only the keys it names, on top of the preset's values (the full-size
car's tuned LMPC weights stay unless the file gives them). TOML has no null: leave a key out to keep
the preset's value.
"""

from __future__ import annotations

import functools
import hashlib
import tomllib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from rkmpc.control.learned.residual_config import ResidualMPCConfig
from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.pure_pursuit import PurePursuitConfig
from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.core.settings import build_dataclass, check_keys, check_value
from rkmpc.core.validation import is_integer
from rkmpc.sim.scenario import VEHICLES, Scenario, VehiclePreset, load_scenario, mpc_options, vehicle_preset
from rkmpc.track.speed_profile import SpeedLimits
from rkmpc.vehicle.params import VehicleParams
from rkmpc.vehicle.zoo import get_car

__all__ = ["CarConfig", "ControllerSettings", "TrainingSettings", "load_car_config"]

SECTIONS = ("vehicle", "plant", "limits", "controllers", "training")
#: Controllers a car file may tune, and the settings class of each.
CONTROLLER_SECTIONS = {
    "lmpc": LMPCConfig,
    "rkmpc": ResidualMPCConfig,
    "rkmpc-paper": ResidualMPCConfig,
    "pp": PurePursuitConfig,
}


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
class ControllerSettings:
    """The settings of the controllers a car file tunes (all on the preset's by default).

    Parameters
    ----------
    lmpc : LMPCConfig
        The linear MPC: ``lmpc``, ``lmpc-id``, ``kmpc``, and the baseline of ``rkmpc`` and ``rkmpc-paper``.
    rkmpc, rkmpc_paper : ResidualMPCConfig
        The residual MPC of ``rkmpc`` and of ``rkmpc-paper``.
    pp : PurePursuitConfig
        Pure pursuit.
    """

    lmpc: LMPCConfig
    rkmpc: ResidualMPCConfig
    rkmpc_paper: ResidualMPCConfig
    pp: PurePursuitConfig

    @classmethod
    def of_preset(cls, preset: VehiclePreset) -> ControllerSettings:
        """The preset's tuned settings, the controllers' defaults where it has none."""
        values = {}
        for name, kind in CONTROLLER_SECTIONS.items():
            options = preset.options_for(name)
            values[name.replace("-", "_")] = options["config"] if "config" in options else kind()
        return cls(**values)

    def options(self) -> dict[str, dict[str, Any]]:
        """Options by controller name, as :attr:`VehiclePreset.controller_options` holds them."""
        return {**mpc_options(self.lmpc, self.rkmpc, self.rkmpc_paper), "pp": {"config": self.pp}}

    def to_json(self) -> dict[str, Any]:
        return {
            name: to_json_ready(asdict(getattr(self, name.replace("-", "_")))) for name in CONTROLLER_SECTIONS
        }


def _constant(params: VehicleParams) -> VehicleParams:
    return params


@dataclass(frozen=True)
class CarConfig:
    """A car set up in one file (or a preset as it is), fully resolved.

    Parameters
    ----------
    preset : str
        The vehicle preset it builds on (a key of :data:`rkmpc.sim.scenario.VEHICLES`).
    vehicle : VehicleParams
        The controllers' nominal model of the car.
    car : str or None
        A zoo car driven instead of the preset's plant (:func:`rkmpc.vehicle.zoo.get_car`).
    limits : SpeedLimits
        The speed profile's limits.
    controllers : ControllerSettings
        The controllers' settings.
    training : TrainingSettings
        How the learned controllers learn.
    source : str or None
        The file it was read from (None: the preset itself).
    sha256 : str or None
        SHA-256 of the file's bytes.
    """

    preset: str
    vehicle: VehicleParams
    car: str | None
    limits: SpeedLimits
    controllers: ControllerSettings
    training: TrainingSettings = field(default_factory=TrainingSettings)
    source: str | None = None
    sha256: str | None = None

    @classmethod
    def from_preset(cls, name: str) -> CarConfig:
        """The preset named ``name`` as it is (what a file with only ``preset = name`` gives)."""
        base = vehicle_preset(name)
        return cls(
            preset=name,
            vehicle=base.params(),
            car=None,
            limits=base.limits,
            controllers=ControllerSettings.of_preset(base),
        )

    def vehicle_preset(self) -> VehiclePreset:
        """The preset this car file makes: for :func:`rkmpc.sim.scenario.load_scenario` (``preset=``)."""
        base = vehicle_preset(self.preset)
        return VehiclePreset(
            params=functools.partial(_constant, self.vehicle),
            plant=base.plant,
            limits=self.limits,
            file_scale=base.file_scale,
            controller_options={**base.controller_options, **self.controllers.options()},
        )

    def scenario(
        self,
        track: str | Path,
        *,
        scale: float | None = None,
        raceline: str | Path | None = None,
        limits: SpeedLimits | None = None,
    ) -> Scenario:
        """This car on ``track`` (:func:`rkmpc.sim.scenario.load_scenario`): its preset, plant and limits.

        ``limits`` replaces the car's (a study's pace); ``scale`` and ``raceline`` as for the loader.
        """
        return load_scenario(
            track,
            raceline=raceline,
            scale=scale,
            vehicle=self.preset,
            car=self.car,
            limits=self.limits if limits is None else limits,
            preset=self.vehicle_preset(),
        )

    def at_pace(self, lateral_accel: float | None = None, max_speed: float | None = None) -> CarConfig:
        """This car at another pace (:meth:`SpeedLimits.at_pace`); None keeps a value."""
        if lateral_accel is None and max_speed is None:
            return self
        return replace(self, limits=self.limits.at_pace(lateral_accel, max_speed))

    def to_json(self) -> dict[str, Any]:
        """The effective configuration, for result files: every value, the file and its hash."""
        return {
            "file": self.source,
            "sha256": self.sha256,
            "vehicle": {"preset": self.preset, **to_json_ready(asdict(self.vehicle))},
            "plant": {"car": self.car},
            "limits": asdict(self.limits),
            "controllers": self.controllers.to_json(),
            "training": asdict(self.training),
        }


def load_car_config(path: str | Path) -> CarConfig:
    """Read and validate a car file (TOML); what it leaves out is its preset's.

    Raises
    ------
    InputFileError
        For a missing or unreadable file, invalid TOML (with its line), an unknown section or
        key, a value of the wrong type or out of range, an unknown preset or zoo car; it names
        the file and the key.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputFileError(path, "file not found") from None
    except OSError as exc:
        raise InputFileError(path, f"cannot read the file: {exc}") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputFileError(path, f"not a valid TOML file: {exc}") from None
    check_keys(data, SECTIONS, path, "", " (a section)")
    sections = {name: _section(data, name, path) for name in SECTIONS}
    vehicle = dict(sections["vehicle"])
    preset_name = check_value(str, vehicle.pop("preset", "f1tenth"), path, "vehicle.preset")
    if preset_name not in VEHICLES:
        raise InputFileError(
            path, f"unknown preset {preset_name!r}; known: {sorted(VEHICLES)}", "vehicle.preset"
        )
    base = CarConfig.from_preset(preset_name)
    params_keys = [f.name for f in fields(VehicleParams) if f.name != "name"]
    check_keys(vehicle, ["preset", *params_keys], path, "vehicle.")
    params = build_dataclass(VehicleParams, vehicle, path, "vehicle.", base=base.vehicle)
    return CarConfig(
        preset=preset_name,
        vehicle=params,
        car=_plant_car(sections["plant"], preset_name, path),
        limits=build_dataclass(SpeedLimits, sections["limits"], path, "limits.", base=base.limits),
        controllers=_controllers(sections["controllers"], base.controllers, path),
        training=build_dataclass(TrainingSettings, sections["training"], path, "training."),
        source=str(path.resolve()),
        sha256=hashlib.sha256(raw).hexdigest(),
    )


def _section(data: Mapping[str, Any], name: str, path: Path, prefix: str = "") -> Mapping[str, Any]:
    value = data[name] if name in data else {}
    if not isinstance(value, Mapping):
        raise InputFileError(
            path, f"expected a section ([{prefix}{name}]), got {value!r}", field=f"{prefix}{name}"
        )
    return value


def _plant_car(section: Mapping[str, Any], preset: str, path: Path) -> str | None:
    check_keys(section, ["car"], path, "plant.")
    if "car" not in section:
        return None
    name: str = check_value(str, section["car"], path, "plant.car")
    if preset != "f1tenth":
        raise InputFileError(
            path, f"zoo cars are 1:10 cars: needs preset 'f1tenth', not {preset!r}", "plant.car"
        )
    try:
        get_car(name)
    except ParameterError as exc:
        raise InputFileError(path, str(exc), field="plant.car") from None
    return name


def _controllers(section: Mapping[str, Any], base: ControllerSettings, path: Path) -> ControllerSettings:
    check_keys(section, CONTROLLER_SECTIONS, path, "controllers.")
    values = {}
    for name, kind in CONTROLLER_SECTIONS.items():
        attr = name.replace("-", "_")
        given = _section(section, name, path, "controllers.")
        values[attr] = build_dataclass(kind, given, path, f"controllers.{name}.", base=getattr(base, attr))
    return ControllerSettings(**values)
