"""What the state estimator did: counts by sensor and reason (typed record), and one update for a smoother."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

__all__ = ["SENSORS", "EstimatorCounts", "EstimatorDiagnostics", "FilterStep"]

#: The measurements the filter fuses, in the order it applies them in one update.
SENSORS: tuple[str, ...] = ("pose", "speed", "yaw_rate", "slip")


class EstimatorCounts:
    """The running counts of a filter (mutable; :meth:`record` freezes them)."""

    def __init__(self) -> None:
        self.updates = 0
        self.used = dict.fromkeys(SENSORS, 0)
        self.rejected = dict.fromkeys(SENSORS, 0)
        self.reinitialised = dict.fromkeys(SENSORS, 0)
        self.poses_repeated = 0
        self.poses_too_old = 0
        self.restarts_gap = 0
        self.restarts_time = 0
        self.restarts_diverged = 0

    def record(self, speed_scale: float, gyro_bias: float) -> EstimatorDiagnostics:
        """The counts so far with the sensor estimates, as an :class:`EstimatorDiagnostics`."""
        return EstimatorDiagnostics(
            updates=self.updates,
            poses_used=self.used["pose"],
            poses_rejected=self.rejected["pose"],
            poses_repeated=self.poses_repeated,
            poses_too_old=self.poses_too_old,
            speeds_used=self.used["speed"],
            speeds_rejected=self.rejected["speed"],
            yaw_rates_used=self.used["yaw_rate"],
            yaw_rates_rejected=self.rejected["yaw_rate"],
            slips_used=self.used["slip"],
            slips_rejected=self.rejected["slip"],
            pose_reinitialisations=self.reinitialised["pose"],
            speed_reinitialisations=self.reinitialised["speed"],
            yaw_rate_reinitialisations=self.reinitialised["yaw_rate"],
            slip_reinitialisations=self.reinitialised["slip"],
            restarts_gap=self.restarts_gap,
            restarts_time=self.restarts_time,
            restarts_diverged=self.restarts_diverged,
            speed_scale=speed_scale,
            gyro_bias=gyro_bias,
        )


@dataclass(frozen=True, kw_only=True)
class EstimatorDiagnostics:
    """Counts of a :class:`~rkmpc.estimation.filter.StateEstimator` since its reset.

    Parameters
    ----------
    updates : int
        Calls of ``update``.
    poses_used, poses_rejected : int
        New poses fused, and rejected by the chi-square gate (jumps of the localiser).
    poses_repeated : int
        Observations whose pose was not new (an unchanged ``pose_time``, or the same pose
        again): no measurement.
    poses_too_old : int
        New poses older than ``max_latency``, or older than a pose already used: not used.
    speeds_used, speeds_rejected, yaw_rates_used, yaw_rates_rejected, slips_used, slips_rejected : int
        The same for the wheel speed, the gyro and a measured slip angle (NaN ones are neither).
    pose_reinitialisations, speed_reinitialisations, yaw_rate_reinitialisations,
    slip_reinitialisations : int
        Times that part of the state was reset to its sensor after ``max_rejections`` rejections
        in a row (the sensor was right and the filter wrong).
    restarts_gap, restarts_time, restarts_diverged : int
        Restarts of the whole filter: after a gap longer than ``max_gap`` (or of its pose, after as
        long without one), a time going backwards, a state turned non-finite.
    speed_scale : float
        Estimated scale of the wheel-speed sensor (measured / true, -).
    gyro_bias : float
        Estimated bias of the gyro (rad/s).
    """

    updates: int
    poses_used: int
    poses_rejected: int
    poses_repeated: int
    poses_too_old: int
    speeds_used: int
    speeds_rejected: int
    yaw_rates_used: int
    yaw_rates_rejected: int
    slips_used: int
    slips_rejected: int
    pose_reinitialisations: int
    speed_reinitialisations: int
    yaw_rate_reinitialisations: int
    slip_reinitialisations: int
    restarts_gap: int
    restarts_time: int
    restarts_diverged: int
    speed_scale: float
    gyro_bias: float

    def as_dict(self, prefix: str = "estimator_") -> dict[str, float]:
        """Every field as a float under ``prefix + name`` (for controller diagnostics and metadata)."""
        return {f"{prefix}{f.name}": float(getattr(self, f.name)) for f in fields(self)}


@dataclass(frozen=True)
class FilterStep:
    """One update of the filter, for a smoother (copies).

    Parameters
    ----------
    started : bool
        The update (re)started the filter, or re-initialised part of its state: no Bayesian
        link to the update before.
    transition, noise : numpy.ndarray
        Jacobian ``F`` and process noise ``Q`` of the prediction from the update before (8, 8).
    prior_state, prior_covariance : numpy.ndarray
        The prediction (8,), (8, 8).
    state, covariance : numpy.ndarray
        The estimate after the measurements (8,), (8, 8).
    wheel_angle : float
        The wheel angle used (rad).
    """

    started: bool
    transition: np.ndarray
    noise: np.ndarray
    prior_state: np.ndarray
    prior_covariance: np.ndarray
    state: np.ndarray
    covariance: np.ndarray
    wheel_angle: float
