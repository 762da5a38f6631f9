"""The tuning of the state estimator: noise, process model, gates and limits, in SI units."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer

__all__ = ["EstimatorConfig"]

#: Fields that may be 0 (a state the filter holds fixed, a pose taken as current).
_NONNEGATIVE = (
    "speed_scale_density",
    "gyro_bias_density",
    "initial_speed_scale_std",
    "initial_gyro_bias_std",
)


@dataclass(frozen=True, kw_only=True)
class EstimatorConfig:
    """Settings of :class:`~rkmpc.estimation.filter.StateEstimator` (and of its smoother).

    Measurement noise is a standard deviation per sample; process noise is a density, the
    standard deviation a white noise adds over one second (its variance grows with the time
    step: ``variance = density^2 * dt``).

    Parameters
    ----------
    control_period : float
        Period at which commands are sent and held (s); the wheel-angle model steps with it.
    position_std, yaw_std : float
        Noise of the localiser's pose: position per axis (m), heading (rad).
    speed_std : float
        Noise of the wheel-speed measurement (m/s).
    yaw_rate_std : float
        Noise of the gyro's yaw rate (rad/s).
    slip_std : float
        Noise of a measured side-slip angle (rad), where the car has one.
    position_density : float
        Model error of the kinematics (m/sqrt(s)).
    yaw_density : float
        Model error of the heading (rad/sqrt(s)).
    acceleration_density : float
        Longitudinal speed random walk (m/s/sqrt(s)): the speed is not modelled, it follows the
        measurements.
    lateral_velocity_density : float
        Model error of the lateral velocity (m/s/sqrt(s)).
    yaw_acceleration_density : float
        Model error of the yaw rate (rad/s/sqrt(s)) of the filter that runs in the loop: large
        enough that the gyro, not the wheel angle's model, drives the yaw rate, so the estimate
        keeps up with a car whose steering is later than its model says.
    smoothing_yaw_acceleration_density : float or None
        The same when a whole recording is smoothed into training labels
        (:func:`~rkmpc.estimation.smoother.smooth_sequence`); None: ``yaw_acceleration_density``.
        A smaller value keeps a noisy gyro out of the labels' yaw rate and heading; a smoother sees
        the measurements after each sample too, so it loses no response by it, where the loop's
        filter would (at 2 rather than 5 the LMPC behind it leaves the track under 20 ms of
        actuation delay). It costs robustness where the car's yaw response is not the model's
        (more gyro readings fall outside the gate). The real F1TENTH car's file sets 2
        (``configs/f1tenth-real-car.toml``, chosen on its logs, ``docs/real-logs.md``).
    speed_scale_density : float
        Random walk of the wheel-speed sensor's scale (1/sqrt(s)); 0 holds the scale fixed.
    gyro_bias_density : float
        Random walk of the gyro's bias (rad/s/sqrt(s)); 0 holds the bias fixed.
    yaw_rate_time_constant : float
        Time (s) in which the yaw rate relaxes to the steady cornering rate of the wheel angle.
    lateral_time_constant : float
        Time (s) in which the lateral velocity relaxes to its steady value for the yaw rate.
    understeer_gradient : float or None
        ``K`` (s^2/m) of the steady cornering rate ``v tan(delta) / (L + K v^2)``; None for the
        car's linear-tyre value ``(m / L) (lr / C_f - lf / C_r)``.
    initial_position_std, initial_yaw_std, initial_speed_std, initial_lateral_velocity_std,
    initial_yaw_rate_std : float
        Standard deviations (m, rad, m/s, m/s, rad/s) of the state at the first measurement, and of
        a part that is re-initialised.
    initial_speed_scale_std, initial_gyro_bias_std : float
        Standard deviations of the sensor scale (-) and bias (rad/s) at the start; 0 holds them at
        1 and 0.
    gate_probability : float
        Probability mass inside each measurement's chi-square gate, in (0, 1): a measurement
        whose normalised innovation lies beyond it is rejected (a pose jump).
    max_rejections : int
        Consecutive rejections of one sensor after which the filter re-initialises the part of
        the state that sensor measures from it, rather than drifting away from it (>= 1).
    max_latency : float
        Oldest pose (s behind the observation's time) the filter uses.
    max_gap : float
        Longest time (s) between two updates, a longer one restarts the filter; and between two
        poses used, after a longer one the next pose restarts the pose (the dead-reckoned one and
        its covariance no longer mean anything).
    min_slip_speed : float
        Speed (m/s) below which a measured slip angle is not used (it is undefined at rest).
    """

    control_period: float = 0.05
    position_std: float = 0.05
    yaw_std: float = 0.03
    speed_std: float = 0.1
    yaw_rate_std: float = 0.05
    slip_std: float = 0.02
    position_density: float = 0.02
    yaw_density: float = 0.01
    acceleration_density: float = 3.0
    lateral_velocity_density: float = 0.3
    yaw_acceleration_density: float = 5.0
    smoothing_yaw_acceleration_density: float | None = None
    speed_scale_density: float = 0.01
    gyro_bias_density: float = 0.005
    yaw_rate_time_constant: float = 0.1
    lateral_time_constant: float = 0.1
    understeer_gradient: float | None = None
    initial_position_std: float = 0.3
    initial_yaw_std: float = 0.1
    initial_speed_std: float = 0.5
    initial_lateral_velocity_std: float = 0.2
    initial_yaw_rate_std: float = 0.3
    initial_speed_scale_std: float = 0.2
    initial_gyro_bias_std: float = 0.05
    gate_probability: float = 0.999
    max_rejections: int = 10
    max_latency: float = 0.5
    max_gap: float = 0.5
    min_slip_speed: float = 0.5

    def __post_init__(self) -> None:
        for f in fields(self):
            value: Any = getattr(self, f.name)
            if f.name in ("understeer_gradient", "max_rejections") or (
                f.name == "smoothing_yaw_acceleration_density" and value is None
            ):
                continue
            number = isinstance(value, int | float) and not isinstance(value, bool)
            low_ok = number and (value >= 0.0 if f.name in _NONNEGATIVE else value > 0.0)
            if not (low_ok and math.isfinite(value)):
                bound = ">= 0" if f.name in _NONNEGATIVE else "> 0"
                raise ParameterError(f"EstimatorConfig.{f.name} must be finite and {bound}, got {value!r}")
        if not self.gate_probability < 1.0:
            raise ParameterError(
                f"EstimatorConfig.gate_probability must be in (0, 1), got {self.gate_probability!r}"
            )
        if not is_integer(self.max_rejections, 1):
            raise ParameterError(
                f"EstimatorConfig.max_rejections must be an integer >= 1, got {self.max_rejections!r}"
            )
        k = self.understeer_gradient
        if k is not None and not (
            isinstance(k, int | float) and not isinstance(k, bool) and math.isfinite(k)
        ):
            raise ParameterError(f"EstimatorConfig.understeer_gradient must be finite or None, got {k!r}")

    def process_densities(self) -> tuple[float, ...]:
        """The process noise densities in the order of the state (``x, y, yaw, vx, vy, r, k, b``)."""
        return (
            self.position_density,
            self.position_density,
            self.yaw_density,
            self.acceleration_density,
            self.lateral_velocity_density,
            self.yaw_acceleration_density,
            self.speed_scale_density,
            self.gyro_bias_density,
        )

    def for_smoothing(self) -> EstimatorConfig:
        """These settings with the smoother's yaw-rate model error in the filter's place."""
        density = self.smoothing_yaw_acceleration_density
        return self if density is None else replace(self, yaw_acceleration_density=density)

    def initial_stds(self) -> tuple[float, ...]:
        """The initial standard deviations in the order of the estimator's state."""
        return (
            self.initial_position_std,
            self.initial_position_std,
            self.initial_yaw_std,
            self.initial_speed_std,
            self.initial_lateral_velocity_std,
            self.initial_yaw_rate_std,
            self.initial_speed_scale_std,
            self.initial_gyro_bias_std,
        )

    def describe(self) -> dict[str, Any]:
        """Every setting as a JSON-able dictionary."""
        return {f.name: getattr(self, f.name) for f in fields(self)}
