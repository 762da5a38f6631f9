"""A scenario: a track, a car and the reference it drives.

:meth:`Scenario.from_car` puts a :class:`~rkmpc.config.car.CarConfig` on a track: the track
file read at the car's scale, the speed profile at the car's limits and the time-indexed
reference. :func:`load_scenario` does the same for a packaged preset by name.
"""

from __future__ import annotations

import difflib
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.learning.contract import Provenance
from rkmpc.track.builtin import builtin_track, list_builtin_tracks
from rkmpc.track.loaders import load_raceline, load_track
from rkmpc.track.reference import Reference
from rkmpc.track.speed_profile import SpeedLimits, speed_profile
from rkmpc.track.track import Track
from rkmpc.vehicle.params import VehicleParams
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.registry import make_plant
from rkmpc.vehicle.zoo import CarSpec, get_car

__all__ = ["BUILTIN_SCALE", "Scenario", "load_scenario"]

#: Scale of the built-in tracks: they are generated at 1:10, for the f1tenth car.
BUILTIN_SCALE = 0.1


def _refuse_unknown_name(track: str | Path) -> None:
    """A bare name that is neither a built-in track nor a file: say so, with the closest names."""
    text = str(track)
    if Path(text).exists() or Path(text).suffix or "/" in text or "\\" in text:
        return  # a path: the loader names what is wrong with it
    names = list_builtin_tracks()
    close = difflib.get_close_matches(text, names, n=3, cutoff=0.5)
    hint = f"did you mean {' or '.join(repr(n) for n in close)}? " if close else ""
    raise ValueError(
        f"unknown track {text!r}: not a built-in track and no such file; {hint}"
        f"built-in tracks: {', '.join(names)}; or give a centre-line CSV file"
    )


def _track(track: str | Path, raceline: str | Path | None, scale: float | None, car: CarConfig) -> Track:
    if str(track) in list_builtin_tracks():
        if car.file_scale != BUILTIN_SCALE:
            warnings.warn(
                f"the built-in track {str(track)!r} is made at 1:10 for the f1tenth car: the "
                f"{car.preset} car will not stay on it; give a track file at full scale (e.g. "
                "../shared/tracks/centerlines/Monza.csv)",
                UserWarning,
                stacklevel=3,
            )
        the_track = builtin_track(str(track))
        if scale is not None and scale != 1.0:
            raise ValueError("built-in tracks are generated at their own scale; --scale applies to files")
        if raceline is not None:
            the_track = the_track.with_raceline(load_raceline(raceline, scale=1.0))
        return the_track
    _refuse_unknown_name(track)
    return load_track(track, raceline, scale=car.file_scale if scale is None else scale)


@dataclass(frozen=True)
class Scenario:
    """Everything a closed-loop run needs besides the controller.

    Parameters
    ----------
    track : Track
        Track geometry and boundaries.
    car : CarConfig
        The car: its nominal model, plant, limits and every controller's settings.
    reference : Reference
        Time-indexed reference along the track's reference path.
    dt : float
        Control period (s).
    """

    track: Track
    car: CarConfig
    reference: Reference
    dt: float

    @classmethod
    def from_car(
        cls,
        car: CarConfig,
        track: str | Path,
        *,
        scale: float | None = None,
        raceline: str | Path | None = None,
        dt: float = 0.05,
    ) -> Scenario:
        """``car`` on ``track``: a built-in name or a TUM centre-line CSV, read at ``scale``
        (default: the car's ``file_scale``; built-in tracks are at their own), optionally tracking
        a race line; the speed profile at the car's limits."""
        the_track = _track(track, raceline, scale, car)
        path = the_track.reference_path
        reference = Reference(path, speed_profile(path, car.limits), car.vehicle.wheelbase)
        return cls(track=the_track, car=car, reference=reference, dt=dt)

    @property
    def vehicle(self) -> VehicleParams:
        """The controllers' nominal model of the car."""
        return self.car.vehicle

    @property
    def vehicle_name(self) -> str:
        """The car's preset name."""
        return self.car.preset

    @property
    def limits(self) -> SpeedLimits:
        """The speed profile's limits."""
        return self.car.limits

    @property
    def zoo_car(self) -> CarSpec | None:
        """The zoo car driven instead of the preset's plant, or None."""
        return None if self.car.plant.car is None else get_car(self.car.plant.car)

    def make_plant(self, seed: int = 0) -> Plant:
        """A fresh plant of the car this scenario drives, seen through its sensors.

        ``seed``: the sensors' noise (and a zoo car's odometry noise, if any).
        """
        return self.car.sensors.wrap(self.make_car_plant(seed), seed)

    def make_car_plant(self, seed: int = 0) -> Plant:
        """A fresh plant of the car itself, before its sensors (:meth:`make_plant` wraps it).

        A fault that changes the car (:attr:`rkmpc.sim.faults.base.Fault.changes_car`) applies here.
        """
        zoo = self.zoo_car
        return zoo.make_plant(seed) if zoo is not None else make_plant(self.car.plant.model)

    def provenance(self) -> Provenance:
        """The conditions of this scenario a data set or a model must have been made with.

        The car (preset name, the plant driven, wheelbase), the control period and the track scale; a model
        or data set used here is checked against them
        (:meth:`rkmpc.learning.contract.Provenance.check`).
        """
        return Provenance(
            vehicle=self.vehicle_name,
            plant=self.car.plant.car or self.car.plant.model,
            dt=self.dt,
            wheelbase=self.vehicle.wheelbase,
            scale=self.track.scale,
        )

    def describe(self) -> dict[str, object]:
        """A JSON-ready description for result files."""
        zoo = self.zoo_car
        return {
            "track": self.track.name,
            "track_source": self.track.source,
            "scale": self.track.scale,
            "track_length_m": self.track.reference_path.length,
            "raceline": self.track.raceline is not None,
            "vehicle": self.vehicle_name,
            "speed_limits": {
                "lateral_accel": self.limits.lateral_accel,
                "brake_decel": self.limits.brake_decel,
                "accel": self.limits.accel,
                "max_speed": self.limits.max_speed,
                "min_speed": self.limits.min_speed,
            },
            "dt": self.dt,
            "car": None if zoo is None else zoo.describe(),
            "sensors": self.car.sensors.describe(),
        }


def load_scenario(
    track: str | Path = "builtin",
    *,
    raceline: str | Path | None = None,
    scale: float | None = None,
    vehicle: str = "f1tenth",
    limits: SpeedLimits | None = None,
    dt: float = 0.05,
    car: str | None = None,
) -> Scenario:
    """A packaged preset on a track: :meth:`Scenario.from_car` of :meth:`CarConfig.from_preset`.

    Parameters
    ----------
    track : str or Path
        A built-in track name (see :func:`rkmpc.track.builtin.list_builtin_tracks`)
        or the path of a TUM-format centre-line CSV file.
    raceline : str or Path, optional
        A TUM-format race-line CSV; when given, the car tracks it instead of the centre line.
    scale : float, optional
        Scale applied to track files; defaults to the preset's (0.1 for the 1:10 car).
    vehicle : str
        Preset name (``"f1tenth"``, ``"fullsize"``).
    limits : SpeedLimits, optional
        Speed-profile limits; defaults to the preset's.
    dt : float
        Control period (s).
    car : str or None
        A zoo car to drive instead of the preset's plant (:func:`rkmpc.vehicle.zoo.get_car`);
        only with the ``f1tenth`` preset, whose nominal parameters the controllers keep.
    """
    config = load_preset(vehicle).with_zoo_car(car)
    if limits is not None:
        config = replace(config, limits=limits)
    return Scenario.from_car(config, track, scale=scale, raceline=raceline, dt=dt)
