"""What the studies share: settings checks and track lists."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.control.registry import CONTROLLERS
from rkmpc.core.errors import ParameterError
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.experiments.cache import ModelCache
from rkmpc.track.builtin import list_builtin_tracks

__all__ = [
    "MultiTrackConfig",
    "check_car",
    "check_scale",
    "check_track",
    "controller_names",
    "expand_tracks",
    "int_tuple",
    "json_object",
    "str_tuple",
    "track_key",
    "track_label",
    "track_specs",
]


def int_tuple(name: str, values: Any, *, minimum: int) -> tuple[int, ...]:
    """``values`` as a non-empty tuple of distinct integers >= ``minimum``; ParameterError naming ``name``."""
    if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
        raise ParameterError(f"{name} must be a sequence of integers, got {values!r}")
    out = tuple(values)
    if not out:
        raise ParameterError(f"{name} must not be empty")
    for v in out:
        if not is_integer(v) or v < minimum:
            raise ParameterError(f"{name} must hold integers >= {minimum}, got {v!r}")
    if len(set(out)) != len(out):
        raise ParameterError(f"{name} must not repeat values, got {list(out)}")
    return tuple(int(v) for v in out)


def str_tuple(name: str, values: Any) -> tuple[str, ...]:
    """``values`` (or a comma-separated string) as a non-empty tuple of distinct non-empty strings."""
    if isinstance(values, str):
        values = values.split(",")
    if not isinstance(values, Iterable):
        raise ParameterError(f"{name} must be a sequence of strings, got {values!r}")
    out = tuple(values)
    if not out or not all(isinstance(v, str) and v for v in out):
        raise ParameterError(f"{name} must be a non-empty sequence of non-empty strings, got {values!r}")
    if len(set(out)) != len(out):
        raise ParameterError(f"{name} must not repeat values, got {list(out)}")
    return out


@dataclass(frozen=True, kw_only=True)
class MultiTrackConfig:
    """The settings every study over several tracks has (its subclasses add their own).

    Parameters
    ----------
    tracks : sequence of str
        Built-in track names or centre-line CSV paths (see :func:`expand_tracks`).
    car : CarConfig
        The car: its model, plant, sensors, controllers' settings, training and limits.
    controllers : sequence of str
        Registered controller names; a comma-separated string is accepted.
    scale : float or None
        Track scale (default: the car's).
    cache_dir : str or None
        Model cache folder (default when None).
    use_cache : bool
        Read and write trained models in the cache.
    """

    tracks: Sequence[str]
    car: CarConfig = field(default_factory=lambda: load_preset("f1tenth"))
    controllers: Sequence[str] = ()
    scale: float | None = None
    cache_dir: str | None = None
    use_cache: bool = True

    def __post_init__(self) -> None:
        name = type(self).__name__
        object.__setattr__(self, "tracks", track_specs(f"{name}.tracks", self.tracks))
        object.__setattr__(self, "controllers", controller_names(f"{name}.controllers", self.controllers))
        check_car(f"{name}.car", self.car)
        check_scale(f"{name}.scale", self.scale)

    def cache(self) -> ModelCache | None:
        """The model cache to read and write, or None."""
        return ModelCache(self.cache_dir) if self.use_cache else None


def check_track(spec: str) -> None:
    """ParameterError unless ``spec`` is a built-in track or an existing file."""
    if spec in list_builtin_tracks():
        return
    if not Path(spec).is_file():
        raise ParameterError(
            f"track {spec!r} is neither a built-in track ({', '.join(list_builtin_tracks())}) "
            "nor an existing centre-line CSV file"
        )


def track_specs(name: str, tracks: Any) -> tuple[str, ...]:
    """``tracks`` (one spec, or a sequence of names or files) as a checked tuple of track specs."""
    raw = [tracks] if isinstance(tracks, (str, Path)) else tracks
    if not isinstance(raw, Iterable):
        raise ParameterError(f"{name} must be a sequence of tracks, got {raw!r}")
    specs = str_tuple(name, [str(t) for t in raw])
    for spec in specs:
        check_track(spec)
    return specs


def controller_names(name: str, controllers: Any) -> tuple[str, ...]:
    """``controllers`` as a checked tuple of registered controller names."""
    names = str_tuple(name, controllers)
    unknown = [c for c in names if c not in CONTROLLERS]
    if unknown:
        raise ParameterError(f"{name}: unknown {unknown}; known: {sorted(CONTROLLERS)}")
    return names


def check_car(name: str, car: Any) -> CarConfig:
    """``car`` when it is a :class:`CarConfig`; ParameterError naming ``name`` otherwise."""
    if not isinstance(car, CarConfig):
        raise ParameterError(f"{name} must be a CarConfig, got {car!r}")
    return car


def check_scale(name: str, scale: Any) -> None:
    """ParameterError for a scale that is not a positive number (or None)."""
    if scale is not None and not is_positive_number(scale):
        raise ParameterError(f"{name} must be a positive number or None, got {scale!r}")


def track_label(spec: str) -> str:
    """Name of a track spec as results show it (built-in name or file stem)."""
    return Path(spec).stem if spec.lower().endswith(".csv") else spec


def track_key(spec: str) -> str:
    """A track spec as a journal keys it: a CSV file by its absolute path, a built-in name as it is."""
    return str(Path(spec).resolve()) if spec.lower().endswith(".csv") else spec


def expand_tracks(items: Iterable[str | Path]) -> tuple[str, ...]:
    """Track specs from names, CSV files and folders of CSV files (each gives its ``*.csv``, sorted)."""
    out: list[str] = []
    for item in items:
        path = Path(item)
        if path.is_dir():
            found = sorted(str(p) for p in path.glob("*.csv"))
            if not found:
                raise ParameterError(f"track folder {path} holds no *.csv file")
            out.extend(found)
        else:
            out.append(str(item))
    return tuple(out)


def json_object(out: dict[str, Any]) -> dict[str, Any]:
    """A study result's record in plain JSON types (:func:`rkmpc.core.jsonutil.to_json_ready`)."""
    result = to_json_ready(out)
    if not isinstance(result, dict):  # pragma: no cover - to_json_ready keeps mappings
        raise TypeError("a study result must convert to a JSON object")
    return result
