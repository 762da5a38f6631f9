"""Training labels from what a car measured: a transition data set with its observations estimated.

:func:`estimate_dataset` replaces the observations of a
:class:`~rkmpc.learning.data.dataset.TransitionDataset` by the smoothed (or, on request, the
causally filtered) estimates of :func:`~rkmpc.estimation.smoother.smooth_sequence`: poses without
the localiser's jumps, the speed without the sensor's scale, the yaw rate without the gyro's bias,
an estimated slip angle and the wheel angle propagated from the commands. Each episode is one
recording; a transition whose ``next_obs`` is not the next transition's ``obs`` is a gap and
starts a new episode. The metadata record what was done (key ``"estimation"``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.estimation.smoother import SmoothedSequence, smooth_sequence
from rkmpc.estimation.steering import SteeringModel
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.vehicle.params import VehicleParams

__all__ = ["ESTIMATION_KEY", "estimate_dataset", "recordings"]

#: Metadata key of what :func:`estimate_dataset` did.
ESTIMATION_KEY = "estimation"
_STEER = OBSERVATION_FIELDS.index("steer_angle")
_SPEED = OBSERVATION_FIELDS.index("speed")
#: Counts of the filter summed over the recordings (the others are per recording).
_SUMMED = (
    "updates",
    "poses_used",
    "poses_rejected",
    "poses_repeated",
    "poses_too_old",
    "speeds_used",
    "speeds_rejected",
    "yaw_rates_used",
    "yaw_rates_rejected",
    "slips_used",
    "slips_rejected",
    "pose_reinitialisations",
    "speed_reinitialisations",
    "yaw_rate_reinitialisations",
    "slip_reinitialisations",
    "restarts_gap",
    "restarts_time",
    "restarts_diverged",
)


def recordings(data: TransitionDataset) -> list[np.ndarray]:
    """The rows of each unbroken recording: per episode, split where ``next_obs[k] != obs[k + 1]``.

    Returns
    -------
    list of numpy.ndarray
        Row indices (consecutive) of each recording, in order.
    """
    out: list[np.ndarray] = []
    for episode in np.unique(data.episode):
        rows = np.flatnonzero(data.episode == episode)
        a, b = data.next_obs[rows[:-1]], data.obs[rows[1:]]
        same = np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
        out.extend(np.split(rows, np.flatnonzero(~same) + 1))
    return out


def estimate_dataset(
    data: TransitionDataset,
    vehicle: VehicleParams,
    *,
    steering: SteeringModel | None = None,
    config: EstimatorConfig | None = None,
    causal: bool = False,
    pose_latency: float = 0.0,
) -> TransitionDataset:
    """``data`` with every observation replaced by its estimate.

    Parameters
    ----------
    data : TransitionDataset
        Raw transitions (NaN where a field was not measured).
    vehicle : VehicleParams
        The car the data were recorded with.
    steering : SteeringModel, optional
        The servo (the car's nominal one by default); an identified one where there is one.
    config : EstimatorConfig, optional
        Tuning; its ``control_period`` must be the data's ``dt`` (by default it is).
    causal : bool
        Use the filter's estimates (what the controller sees in the loop) instead of the smoothed ones.
    pose_latency : float
        How much older (s) than its row each pose is (the localiser's latency, as the sensor profile
        says: :attr:`~rkmpc.vehicle.sensors.profile.SensorProfile.pose_latency`), in [0,
        ``config.max_latency``). The filter moves each pose forward from its own time, as it does in
        the loop; without it the labels' poses lag the car by the latency (30 ms of the
        ``f1tenth-real`` localiser: about a control step with the pose's hold).

    Returns
    -------
    TransitionDataset
        The same commands; the estimated observations, one episode per stretch the filter ran
        through (a transition before a recording's first estimate, or across a restart or
        re-initialisation of the filter, is dropped); an estimated speed below 0 is held at 0.
        Metadata: the data's, plus ``"estimation"``: method, steering model, settings, the filter's
        counts summed over the recordings, the sensor scale and bias per recording.

    Raises
    ------
    ParameterError
        When ``config.control_period`` is not ``data.dt``, or no transition can be estimated.
    """
    steer_model = steering if steering is not None else SteeringModel.nominal(vehicle)
    cfg = config if config is not None else EstimatorConfig(control_period=data.dt)
    if not (math.isfinite(pose_latency) and 0.0 <= pose_latency < cfg.max_latency):
        raise ParameterError(
            f"estimate_dataset: pose_latency must be in [0, max_latency {cfg.max_latency!r} s), "
            f"got {pose_latency!r}"
        )
    if not math.isclose(cfg.control_period, data.dt, rel_tol=1e-9):
        raise ParameterError(
            f"estimate_dataset: config.control_period is {cfg.control_period!r} s, "
            f"the data's dt {data.dt!r} s"
        )
    obs: list[np.ndarray] = []
    command: list[np.ndarray] = []
    next_obs: list[np.ndarray] = []
    episode: list[np.ndarray] = []
    runs: list[SmoothedSequence] = []
    clipped = 0
    for rows in recordings(data):
        raw = np.concatenate([data.obs[rows], data.next_obs[rows[-1:]]])
        commands = data.command[rows]
        # Without a measured wheel angle at the start, the wheel is taken as settled at the first command.
        if not math.isfinite(raw[0, _STEER]):
            raw[0, _STEER] = commands[0, 1]
        times = data.dt * np.arange(len(raw))
        result = smooth_sequence(
            times,
            raw,
            commands,
            vehicle,
            steering=steer_model,
            config=cfg,
            pose_times=times - pose_latency if pose_latency > 0.0 else None,
            causal=causal,
        )
        runs.append(result)
        estimate = result.observations.copy()
        negative = estimate[:, _SPEED] < 0.0
        clipped += int(np.count_nonzero(negative))
        estimate[negative, _SPEED] = 0.0
        # A transition needs an estimate at both ends from the same stretch of the filter (where
        # it restarted or re-initialised, the estimate jumps: no label, and a new episode).
        keep = result.valid[:-1] & result.valid[1:] & ~result.segment_starts[1:]
        for part in np.split(np.flatnonzero(keep), np.flatnonzero(np.diff(np.flatnonzero(keep)) != 1) + 1):
            if part.size == 0:
                continue
            obs.append(estimate[part])
            next_obs.append(estimate[part + 1])
            command.append(commands[part])
            episode.append(np.full(part.size, len(episode), dtype=np.int64))
    if not obs:
        raise ParameterError("estimate_dataset: no transition has an estimate (no finite pose in the data)")
    metadata = dict(data.metadata)
    metadata[ESTIMATION_KEY] = _describe(
        runs, steer_model, cfg, causal, clipped, (len(data), sum(map(len, obs)))
    )
    metadata[ESTIMATION_KEY]["pose_latency_s"] = pose_latency
    out = TransitionDataset(
        obs=np.concatenate(obs),
        command=np.concatenate(command),
        next_obs=np.concatenate(next_obs),
        dt=data.dt,
        episode=np.concatenate(episode),
        metadata=metadata,
    )
    return out.with_contract(data.contract) if data.contract.recorded else out


def _describe(
    runs: list[SmoothedSequence],
    steering: SteeringModel,
    config: EstimatorConfig,
    causal: bool,
    clipped: int,
    counts_in_out: tuple[int, int],
) -> dict[str, Any]:
    """The ``"estimation"`` metadata: what was done, with the filter's counts."""
    n_in, n_out = counts_in_out
    counts = {name: 0 for name in _SUMMED}
    for run in runs:
        record = run.diagnostics.as_dict(prefix="")
        for name in _SUMMED:
            counts[name] += int(record[name])
    return {
        "method": "filter" if causal else "rts",
        "steering": steering.describe(),
        "config": config.describe(),
        "recordings": len(runs),
        "segments": sum(run.segments for run in runs),
        "transitions_in": n_in,
        "transitions_out": n_out,
        "speeds_held_at_zero": clipped,
        "counts": counts,
        "speed_scale": [run.diagnostics.speed_scale for run in runs],
        "gyro_bias_rad_s": [run.diagnostics.gyro_bias for run in runs],
    }
