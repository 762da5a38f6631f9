"""The estimate of a whole recorded sequence: the filter forward, a Rauch-Tung-Striebel pass back.

:func:`smooth_sequence` runs :class:`~rkmpc.estimation.filter.StateEstimator` over arrays
(time first) of times, raw observations and the commands sent, exactly as it runs in the closed
loop (same models, same gates: a pose jump is rejected here as there), and then smooths every
stretch the filter ran without a restart or re-initialisation with :func:`rts`. Each sample's
estimate then uses the measurements after it too: the labels a model learns from.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS, Command, Observation
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.estimation.diagnostics import EstimatorDiagnostics, FilterStep
from rkmpc.estimation.filter import StateEstimator
from rkmpc.estimation.model import N_STATES, VX, VY, YAW, R, X, Y, slip_of
from rkmpc.estimation.steering import SteeringModel
from rkmpc.vehicle.params import VehicleParams

__all__ = ["SmoothedSequence", "rts", "smooth_sequence"]


@dataclass(frozen=True, kw_only=True)
class SmoothedSequence:
    """The estimates of a recorded sequence of ``n`` samples.

    Parameters
    ----------
    times : numpy.ndarray
        Sample times (s), shape (n,).
    states : numpy.ndarray
        Estimated state (:data:`~rkmpc.estimation.model.STATE_NAMES`), shape (n, 8); NaN rows
        before the first pose.
    covariances : numpy.ndarray
        Their covariances, shape (n, 8, 8).
    observations : numpy.ndarray
        The estimates as observation columns (:data:`~rkmpc.core.observation.OBSERVATION_FIELDS`):
        pose, speed ``vx``, yaw rate, slip angle and wheel angle, shape (n, 7).
    valid : numpy.ndarray
        Whether a sample has an estimate (after the first finite pose), shape (n,).
    segment_starts : numpy.ndarray
        Whether a sample starts a stretch smoothed on its own (the filter started, restarted or
        re-initialised part of its state there: the estimate may jump), shape (n,).
    smoothed : bool
        True for the RTS estimates, False for the causal filter's.
    diagnostics : EstimatorDiagnostics
        The filter's counts over the sequence (rejected poses and the like).
    """

    times: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    observations: np.ndarray
    valid: np.ndarray
    segment_starts: np.ndarray
    smoothed: bool
    diagnostics: EstimatorDiagnostics

    @property
    def segments(self) -> int:
        """Stretches smoothed on their own."""
        return int(np.count_nonzero(self.segment_starts))


def rts(
    states: np.ndarray,
    covariances: np.ndarray,
    prior_states: np.ndarray,
    prior_covariances: np.ndarray,
    transitions: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The Rauch-Tung-Striebel smoother over one stretch of a (extended) Kalman filter.

    For ``k = n-2 .. 0``: ``C_k = P_k F_{k+1}^T (P^-_{k+1})^+``,
    ``x^s_k = x_k + C_k (x^s_{k+1} - x^-_{k+1})``,
    ``P^s_k = P_k + C_k (P^s_{k+1} - P^-_{k+1}) C_k^T`` (``+``: the pseudo-inverse, so a state held
    fixed, with no variance, stays fixed).

    Parameters
    ----------
    states, covariances : numpy.ndarray
        Filtered estimates ``x_k`` (n, d) and ``P_k`` (n, d, d).
    prior_states, prior_covariances : numpy.ndarray
        Predictions ``x^-_k`` (n, d) and ``P^-_k`` (n, d, d) from step ``k - 1`` (entry 0 unused).
    transitions : numpy.ndarray
        Jacobians ``F_k`` (n, d, d) of the step from ``k - 1`` to ``k`` (entry 0 unused).

    Returns
    -------
    tuple of numpy.ndarray
        Smoothed states (n, d) and covariances (n, d, d).
    """
    xs = np.array(states, dtype=float)
    Ps = np.array(covariances, dtype=float)
    for k in range(len(xs) - 2, -1, -1):
        F = transitions[k + 1]
        gain = covariances[k] @ F.T @ np.linalg.pinv(prior_covariances[k + 1], hermitian=True)
        xs[k] = states[k] + gain @ (xs[k + 1] - prior_states[k + 1])
        Ps[k] = covariances[k] + gain @ (Ps[k + 1] - prior_covariances[k + 1]) @ gain.T
    return xs, Ps


def _checked(
    times: np.ndarray, observations: np.ndarray, commands: np.ndarray, pose_times: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    t = np.asarray(times, dtype=float)
    obs = np.asarray(observations, dtype=float)
    cmd = np.asarray(commands, dtype=float)
    n = t.shape[0] if t.ndim == 1 else -1
    if n < 1:
        raise ParameterError(f"smooth_sequence: times must have shape (n,) with n >= 1, got {t.shape}")
    if obs.shape != (n, len(OBSERVATION_FIELDS)):
        raise ParameterError(
            f"smooth_sequence: observations must have shape ({n}, {len(OBSERVATION_FIELDS)}), got {obs.shape}"
        )
    if cmd.shape not in ((n, 2), (n - 1, 2)):
        raise ParameterError(
            f"smooth_sequence: commands must have shape ({n}, 2) or ({n - 1}, 2), got {cmd.shape}"
        )
    if not np.all(np.isfinite(t)):
        raise ParameterError("smooth_sequence: times must be finite")
    lags = np.full(n, math.nan) if pose_times is None else np.asarray(pose_times, dtype=float)
    if lags.shape != (n,):
        raise ParameterError(f"smooth_sequence: pose_times must have shape ({n},), got {lags.shape}")
    return t, obs, cmd, lags


def smooth_sequence(
    times: np.ndarray,
    observations: np.ndarray,
    commands: np.ndarray,
    vehicle: VehicleParams,
    *,
    steering: SteeringModel | None = None,
    config: EstimatorConfig | None = None,
    pose_times: np.ndarray | None = None,
    causal: bool = False,
) -> SmoothedSequence:
    """Estimate the state at every sample of a recording.

    Parameters
    ----------
    times : numpy.ndarray
        Sample times (s), shape (n,).
    observations : numpy.ndarray
        Raw observations, columns :data:`~rkmpc.core.observation.OBSERVATION_FIELDS`, NaN where
        not measured, shape (n, 7).
    commands : numpy.ndarray
        ``[speed (m/s), steer (rad)]`` sent after each sample, shape (n, 2) (or (n - 1, 2)): the
        filter at sample ``k`` is told ``commands[k - 1]``.
    vehicle : VehicleParams
        The car.
    steering : SteeringModel, optional
        The servo (the car's nominal one by default).
    config : EstimatorConfig, optional
        Tuning; its ``control_period`` must be the commands' period. The smoothed estimates run
        the filter with its :meth:`~rkmpc.estimation.config.EstimatorConfig.for_smoothing`
        settings, the causal ones with the loop's.
    pose_times : numpy.ndarray, optional
        When each sample's pose was measured (s), shape (n,); NaN (default) for current.
    causal : bool
        Return the filter's estimates (each from the samples up to it) instead of the smoothed ones.

    Returns
    -------
    SmoothedSequence
    """
    t, obs, cmd, lags = _checked(times, observations, commands, pose_times)
    settings = config if config is not None else EstimatorConfig()
    estimator = StateEstimator(vehicle, settings if causal else settings.for_smoothing(), steering)
    n = len(t)
    steps: list[FilterStep | None] = []
    for k in range(n):
        sent = None if k == 0 else Command(float(cmd[k - 1, 0]), float(cmd[k - 1, 1]))
        x, y, yaw, speed, yaw_rate, slip, steer = obs[k].tolist()
        raw = Observation(x, y, yaw, speed, yaw_rate, slip, steer, float(t[k]), float(lags[k]))
        estimator.update(raw, sent)
        steps.append(estimator.last_step() if estimator.initialised else None)
    valid = np.array([s is not None for s in steps], dtype=bool)
    states = np.full((n, N_STATES), math.nan)
    covs = np.full((n, N_STATES, N_STATES), math.nan)
    wheel = np.array([math.nan if s is None else s.wheel_angle for s in steps])
    # Stretches the filter ran through: from a (re)start to the sample before the next one (the
    # samples without an estimate, after a restart that found no pose, are at a stretch's end).
    starts = [k for k, s in enumerate(steps) if s is not None and s.started]
    bounds = [*starts, n]
    for begin, end in itertools.pairwise(bounds):
        stretch = [s for s in steps[begin:end] if s is not None]
        stop = begin + len(stretch)
        x = np.array([s.state for s in stretch])
        P = np.array([s.covariance for s in stretch])
        if not causal:
            x, P = rts(
                x,
                P,
                np.array([s.prior_state for s in stretch]),
                np.array([s.prior_covariance for s in stretch]),
                np.array([s.transition for s in stretch]),
            )
        states[begin:stop], covs[begin:stop] = x, P
    return SmoothedSequence(
        times=t,
        states=states,
        covariances=covs,
        observations=_as_observations(states, wheel),
        valid=valid,
        segment_starts=np.isin(np.arange(n), starts),
        smoothed=not causal,
        diagnostics=estimator.diagnostics(),
    )


def _as_observations(states: np.ndarray, wheel: np.ndarray) -> np.ndarray:
    """Observation columns of estimated states (n, 8) and wheel angles (n,)."""
    vx, vy = states[:, VX], states[:, VY]
    slip = np.array(
        [slip_of(a, b) if math.isfinite(a + b) else math.nan for a, b in zip(vx, vy, strict=True)]
    )
    return np.column_stack([states[:, X], states[:, Y], states[:, YAW], vx, states[:, R], slip, wheel])
