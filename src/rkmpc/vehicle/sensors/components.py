"""The parts of a sensor profile: a localiser, a wheel-speed sensor and a yaw-rate gyro.

Each part is a frozen, validated dataclass (SI units); a bad value raises
:class:`~rkmpc.core.errors.ParameterError` naming the class, the field and the
value. The two simple sensors measure a true value with :meth:`measure`; the
localiser, which keeps state between samples (a jump that is still decaying,
samples in flight), is simulated by :class:`rkmpc.vehicle.sensors.localiser.LocaliserRun`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_finite_real

__all__ = ["Localiser", "WheelSpeedSensor", "YawRateSensor"]


def _check_numbers(obj: object) -> None:
    """Raise :class:`ParameterError` unless every field of ``obj`` is a finite real number (not a bool)."""
    for f in fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        if not is_finite_real(value):
            raise ParameterError(f"{type(obj).__name__}.{f.name} must be a finite number, got {value!r}")


def _check_range(
    obj: object, name: str, low: float, high: float = math.inf, *, open_low: bool = False
) -> None:
    """Raise :class:`ParameterError` unless ``low <= value <= high`` (``low < value`` when ``open_low``)."""
    value = getattr(obj, name)
    if value < low or value > high or (open_low and value == low):
        bracket = "(" if open_low else "["
        raise ParameterError(
            f"{type(obj).__name__}.{name} must be in {bracket}{low:g}, {high:g}], got {value!r}"
        )


@dataclass(frozen=True, kw_only=True)
class Localiser:
    """A pose from a localisation filter (a particle filter on a lidar map): late, irregular, noisy, jumpy.

    Samples are taken at irregular instants on a clock of period ``resolution``
    counted from the reset: each interval to the next sample is a whole number of
    ticks drawn uniformly from those in ``[min_interval, max_interval]``. (The
    clock keeps the steps into which the wrapped plant is split on its own
    integration grid, 1 ms for the simulated cars, so a profile does not change
    how the car moves.) A sample is the true
    pose at its instant plus Gaussian noise along and across the car's heading
    and on the heading, plus a jump offset; it reaches the controller
    ``latency`` seconds after its instant. A jump happens at a sample with
    probability ``jump_probability``: the position is displaced in a uniformly
    random direction by ``jump_min`` plus an exponentially distributed excess of
    mean ``jump_mean_excess``; the displacement then decays with the time
    constant ``jump_recovery`` (0: it affects that one sample only). Jumps move
    the position, not the heading.

    Parameters
    ----------
    along_track_std, cross_track_std : float
        Position noise along and across the true heading (m), >= 0.
    heading_std : float
        Heading noise (rad), >= 0.
    jump_probability : float
        Probability of a jump at each sample, in [0, 1].
    jump_min : float
        Smallest jump (m), >= 0.
    jump_mean_excess : float
        Mean of the exponential part of a jump above ``jump_min`` (m), >= 0.
    jump_recovery : float
        Time constant with which a jump's displacement decays (s), >= 0.
    min_interval, max_interval : float
        Range of the intervals between samples (s), ``0 < min_interval <= max_interval``.
    latency : float
        Time from a sample's instant to its arrival (s), >= 0.
    resolution : float, optional
        Period of the sample clock (s), > 0; at least one tick must lie in
        ``[min_interval, max_interval]``.
    """

    along_track_std: float
    cross_track_std: float
    heading_std: float
    jump_probability: float
    jump_min: float
    jump_mean_excess: float
    jump_recovery: float
    min_interval: float
    max_interval: float
    latency: float
    resolution: float = 0.001

    def __post_init__(self) -> None:
        _check_numbers(self)
        for name in (
            "along_track_std",
            "cross_track_std",
            "heading_std",
            "jump_min",
            "jump_mean_excess",
            "jump_recovery",
            "latency",
        ):
            _check_range(self, name, 0.0)
        _check_range(self, "jump_probability", 0.0, 1.0)
        _check_range(self, "min_interval", 0.0, open_low=True)
        if self.max_interval < self.min_interval:
            raise ParameterError(
                f"Localiser.max_interval must be >= min_interval ({self.min_interval!r}), "
                f"got {self.max_interval!r}"
            )
        _check_range(self, "resolution", 0.0, open_low=True)
        if self.interval_ticks[0] > self.interval_ticks[1]:
            raise ParameterError(
                f"Localiser.resolution {self.resolution!r} puts no tick in [min_interval, max_interval] = "
                f"[{self.min_interval!r}, {self.max_interval!r}]"
            )

    @property
    def interval_ticks(self) -> tuple[int, int]:
        """The shortest and the longest interval between samples, in ticks of :attr:`resolution`."""
        low = math.ceil(self.min_interval / self.resolution - 1e-9)
        high = math.floor(self.max_interval / self.resolution + 1e-9)
        return max(low, 1), high

    @property
    def mean_interval(self) -> float:
        """Mean interval between samples (s)."""
        low, high = self.interval_ticks
        return 0.5 * (low + high) * self.resolution

    @property
    def mean_jump(self) -> float:
        """Mean size of a jump (m)."""
        return self.jump_min + self.jump_mean_excess


@dataclass(frozen=True, kw_only=True)
class WheelSpeedSensor:
    """Speed from the motor controller (a VESC's electrical RPM through a gear ratio and wheel radius).

    Measures ``scale * v + noise``: ``scale`` is the calibration error of the
    RPM-to-speed gain (a wheel radius or gear ratio a few per cent off), the
    noise is Gaussian and drawn afresh at every observation.

    Parameters
    ----------
    scale : float
        Measured over true speed (-), > 0.
    noise_std : float
        Standard deviation of the noise (m/s), >= 0.
    """

    scale: float
    noise_std: float

    def __post_init__(self) -> None:
        _check_numbers(self)
        _check_range(self, "scale", 0.0, open_low=True)
        _check_range(self, "noise_std", 0.0)

    def measure(self, speed: float, rng: np.random.Generator) -> float:
        """The measured speed (m/s) for the true ``speed`` (m/s); draws one standard normal."""
        return self.scale * speed + self.noise_std * float(rng.standard_normal())


@dataclass(frozen=True, kw_only=True)
class YawRateSensor:
    """Yaw rate from a MEMS gyro (an IMU): a constant bias and white noise.

    Parameters
    ----------
    bias : float
        Added to every measurement (rad/s), any sign.
    noise_std : float
        Standard deviation of the noise (rad/s), >= 0.
    """

    bias: float
    noise_std: float

    def __post_init__(self) -> None:
        _check_numbers(self)
        _check_range(self, "noise_std", 0.0)

    def measure(self, yaw_rate: float, rng: np.random.Generator) -> float:
        """The measured yaw rate (rad/s) for the true ``yaw_rate`` (rad/s); draws one standard normal."""
        return yaw_rate + self.bias + self.noise_std * float(rng.standard_normal())
