"""The RTS smoother against filterpy's, over a sequence, and over a transition data set."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.estimation import EstimatorConfig, StateEstimator, SteeringModel
from rkmpc.estimation.labels import ESTIMATION_KEY, estimate_dataset, recordings
from rkmpc.estimation.model import SingleTrackModel
from rkmpc.estimation.smoother import rts, smooth_sequence
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.vehicle.params import f1tenth

CAR = f1tenth()
DT = 0.05


def circle(
    n: int, seed: int = 0, scale: float = 1.1, bias: float = 0.03
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raw observations of a car on a circle of radius 5 m at 2.5 m/s: times, (n, 7), and commands (n, 2).

    Driven as the estimator's model drives it: the heading is the course less the rear axle's
    slip, the wheel angle that of steady cornering.
    """
    rng = np.random.default_rng(seed)
    model = SingleTrackModel(CAR, EstimatorConfig())
    speed, rate = 2.5, 0.5
    slip = math.atan(model.lateral_gain(speed) * rate / speed)
    t = DT * np.arange(n)
    course = rate * t
    truth = np.column_stack(
        [
            5 * np.sin(course),
            5 * (1 - np.cos(course)),
            course - slip,
            np.full(n, speed * math.cos(slip)),
            np.full(n, rate),
            np.full(n, slip),
            np.zeros(n),
        ]
    )
    raw = truth.copy()
    raw[:, :2] += 0.05 * rng.standard_normal((n, 2))
    raw[:, 2] += 0.03 * rng.standard_normal(n)
    raw[:, 3] = scale * truth[:, 3] + 0.05 * rng.standard_normal(n)
    raw[:, 4] = truth[:, 4] + bias + 0.03 * rng.standard_normal(n)
    raw[:, 5:] = math.nan
    steer = math.atan(model.effective_wheelbase(speed) * rate / speed)
    commands = np.column_stack([np.full(n, speed), np.full(n, steer)])
    return t, raw, commands, truth


def test_rts_is_filterpys_rts_smoother_on_a_linear_model():
    kalman = pytest.importorskip("filterpy.kalman", reason="filterpy 2.0.0 (the test extra) is the reference")
    rng = np.random.default_rng(4)
    kf = kalman.KalmanFilter(dim_x=4, dim_z=2)
    kf.F = np.array([[1, 0, DT, 0], [0, 1, 0, DT], [0, 0, 1, 0], [0, 0, 0, 1]], dtype=float)
    kf.H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    kf.Q = np.diag([1e-4, 1e-4, 1e-2, 1e-2])
    kf.R = np.eye(2) * 0.05**2
    kf.x = np.zeros(4)
    kf.P = np.eye(4)
    zs = np.column_stack([np.linspace(0, 5, 80), np.sin(np.linspace(0, 3, 80))]) + 0.05 * rng.standard_normal(
        (80, 2)
    )
    means, covs, means_p, covs_p = kf.batch_filter(zs)
    Fs = np.repeat(kf.F[None], 80, axis=0)
    expected_x, expected_P, _, _ = kf.rts_smoother(means, covs, Fs, np.repeat(kf.Q[None], 80, axis=0))
    xs, Ps = rts(means, covs, means_p, covs_p, Fs)
    np.testing.assert_allclose(xs, expected_x, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Ps, expected_P, rtol=1e-8, atol=1e-14)


def test_the_causal_sequence_is_the_online_filter_bit_for_bit():
    t, raw, commands, _ = circle(120)
    causal = smooth_sequence(t, raw, commands, CAR, causal=True)
    estimator = StateEstimator(CAR, EstimatorConfig(control_period=DT))
    online = []
    for k in range(len(t)):
        obs = Observation(*raw[k, :4], raw[k, 4], time=float(t[k]))
        sent = None if k == 0 else Command(*commands[k - 1])
        online.append(estimator.update(obs, sent).as_array())
    np.testing.assert_array_equal(causal.observations, np.array(online))
    assert not causal.smoothed and causal.segments == 1 and causal.valid.all()


def test_smoothing_beats_filtering_and_both_beat_the_raw_measurements():
    t, raw, commands, truth = circle(300, seed=1)
    filtered = smooth_sequence(t, raw, commands, CAR, causal=True).observations
    smoothed = smooth_sequence(t, raw, commands, CAR).observations
    late = slice(100, None)  # once the scale and bias have settled

    def position_rms(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum((a[late, :2] - truth[late, :2]) ** 2, axis=1))))

    assert position_rms(smoothed) < 0.8 * position_rms(filtered) < 0.5 * position_rms(raw)
    # Speed and yaw rate: the scale (10 %) and the bias (0.03 rad/s, as large as the gyro's noise) removed.
    for column, share in ((3, 0.3), (4, 0.8)):
        raw_error = np.sqrt(np.mean((raw[late, column] - truth[late, column]) ** 2))
        assert np.sqrt(np.mean((smoothed[late, column] - truth[late, column]) ** 2)) < share * raw_error


def test_the_smoother_can_run_with_its_own_yaw_rate_model_error():
    t, raw, commands, truth = circle(300, seed=1)
    loop = EstimatorConfig(control_period=DT)
    assert loop.smoothing_yaw_acceleration_density is None and loop.for_smoothing() is loop
    own = EstimatorConfig(control_period=DT, smoothing_yaw_acceleration_density=2.0)
    same = EstimatorConfig(control_period=DT, yaw_acceleration_density=2.0)
    np.testing.assert_array_equal(
        smooth_sequence(t, raw, commands, CAR, config=own).observations,
        smooth_sequence(t, raw, commands, CAR, config=same).observations,
    )
    # The causal estimates are the loop's filter, with the loop's model error.
    np.testing.assert_array_equal(
        smooth_sequence(t, raw, commands, CAR, config=own, causal=True).observations,
        smooth_sequence(t, raw, commands, CAR, config=loop, causal=True).observations,
    )
    # The smaller model error keeps the gyro's noise out of the smoothed yaw rate.
    late = slice(100, None)

    def yaw_rate_rms(config: EstimatorConfig) -> float:
        smoothed = smooth_sequence(t, raw, commands, CAR, config=config).observations
        return float(np.sqrt(np.mean((smoothed[late, 4] - truth[late, 4]) ** 2)))

    assert yaw_rate_rms(own) < yaw_rate_rms(loop)
    with pytest.raises(ParameterError, match="smoothing_yaw_acceleration_density"):
        EstimatorConfig(smoothing_yaw_acceleration_density=0.0)


def test_a_reinitialisation_splits_the_sequence_into_segments():
    t, raw, commands, _ = circle(120)
    raw[60:, 1] += 1.5  # the localiser relocalised 1.5 m aside and stays there
    result = smooth_sequence(t, raw, commands, CAR, config=EstimatorConfig(max_rejections=5))
    assert result.segments == 2 and result.diagnostics.pose_reinitialisations == 1
    assert np.all(np.isfinite(result.states))


def test_samples_before_the_first_pose_have_no_estimate():
    t, raw, commands, _ = circle(40)
    raw[:5, :3] = math.nan
    result = smooth_sequence(t, raw, commands, CAR)
    assert not result.valid[:5].any() and result.valid[5:].all()
    assert np.isnan(result.states[:5]).all()


def test_bad_arrays_are_refused_naming_them():
    t, raw, commands, _ = circle(10)
    with pytest.raises(ParameterError, match="observations"):
        smooth_sequence(t, raw[:, :5], commands, CAR)
    with pytest.raises(ParameterError, match="commands"):
        smooth_sequence(t, raw, commands[:5], CAR)
    with pytest.raises(ParameterError, match="pose_times"):
        smooth_sequence(t, raw, commands, CAR, pose_times=t[:3])


# ---------------------------------------------------------------------------- data sets


def dataset(n: int = 200) -> tuple[TransitionDataset, np.ndarray]:
    _, raw, commands, truth = circle(n + 1, seed=2)
    raw[:, 3] = np.maximum(raw[:, 3], 0.0)
    data = TransitionDataset(
        obs=raw[:-1], command=commands[:-1], next_obs=raw[1:], dt=DT, episode=np.zeros(n, dtype=int)
    )
    return data, truth[:-1]


def test_a_data_set_gets_estimated_observations_and_says_what_was_done():
    data, truth = dataset()
    out = estimate_dataset(data, CAR, steering=SteeringModel.nominal(CAR))
    assert len(out) == len(data) and np.array_equal(out.command, data.command)
    assert np.all(np.isfinite(out.obs)) and np.all(np.isfinite(out.next_obs))  # slip and wheel filled in
    np.testing.assert_array_equal(out.obs[1:], out.next_obs[:-1])
    late = slice(100, None)
    assert np.sqrt(np.mean((out.obs[late, 3] - truth[late, 3]) ** 2)) < 0.05  # the 10 % scale is gone
    meta = out.metadata[ESTIMATION_KEY]
    assert meta["method"] == "rts" and meta["steering"]["structure"] == "lag-rate"
    assert meta["counts"]["poses_used"] == len(data) + 1 and meta["speed_scale"][0] == pytest.approx(
        1.1, abs=0.03
    )
    assert estimate_dataset(data, CAR, causal=True).metadata[ESTIMATION_KEY]["method"] == "filter"


def test_late_poses_are_dated_back_by_the_latency():
    n = 200
    _, raw, commands, truth = circle(n + 2, seed=3)
    raw[1:, :3] = raw[:-1, :3]  # every pose one control period (0.05 s) late
    raw, commands, truth = raw[1:], commands[1:], truth[1:]
    data = TransitionDataset(
        obs=raw[:-1], command=commands[:-1], next_obs=raw[1:], dt=DT, episode=np.zeros(n, dtype=int)
    )
    late = slice(50, None)

    def position_rms(latency: float) -> float:
        out = estimate_dataset(data, CAR, pose_latency=latency)
        assert out.metadata[ESTIMATION_KEY]["pose_latency_s"] == latency
        return float(np.sqrt(np.mean(np.sum((out.obs[late, :2] - truth[:-1][late, :2]) ** 2, axis=1))))

    # 2.5 m/s for 0.05 s: the undated poses put the car 0.125 m behind itself.
    assert position_rms(DT) < 0.05 < 0.1 < position_rms(0.0)
    with pytest.raises(ParameterError, match="pose_latency"):
        estimate_dataset(data, CAR, pose_latency=EstimatorConfig().max_latency)


def test_a_gap_inside_an_episode_starts_a_new_one():
    data, _ = dataset(100)
    next_obs = data.next_obs.copy()
    next_obs[49, 0] += 0.5  # the transition after 49 does not start where 49 ended
    broken = TransitionDataset(
        obs=data.obs, command=data.command, next_obs=next_obs, dt=DT, episode=data.episode
    )
    assert [len(r) for r in recordings(broken)] == [50, 50]
    out = estimate_dataset(broken, CAR)
    assert np.unique(out.episode).tolist() == [0, 1] and len(out) == 100
    assert out.metadata[ESTIMATION_KEY]["recordings"] == 2


def test_no_transition_spans_a_reinitialisation_of_the_filter():
    data, _ = dataset(120)
    obs, next_obs = data.obs.copy(), data.next_obs.copy()
    obs[60:, 1] += 1.5  # the localiser relocalised 1.5 m aside and stays there
    next_obs[59:, 1] += 1.5
    moved = TransitionDataset(obs=obs, command=data.command, next_obs=next_obs, dt=DT, episode=data.episode)
    out = estimate_dataset(moved, CAR, config=EstimatorConfig(control_period=DT, max_rejections=5))
    assert out.metadata[ESTIMATION_KEY]["segments"] == 2 and np.unique(out.episode).size == 2
    assert len(out) == len(moved) - 1  # the transition across the jump of the estimate is no label
    steps = np.hypot(*(out.next_obs[:, :2] - out.obs[:, :2]).T)
    assert steps.max() < 0.2  # 2.5 m/s over 0.05 s: 0.125 m


def test_the_settings_must_have_the_data_period():
    data, _ = dataset(20)
    with pytest.raises(ParameterError, match="control_period"):
        estimate_dataset(data, CAR, config=EstimatorConfig(control_period=0.1))
