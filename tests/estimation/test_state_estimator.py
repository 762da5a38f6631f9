"""The EKF: its algebra against filterpy's, its models against their equations, rejections, restarts."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.core.angles import wrap_scalar
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.estimation import EstimatorConfig, StateEstimator, SteeringModel
from rkmpc.estimation.model import STATE_NAMES, SingleTrackModel, axle_cornering_stiffness
from rkmpc.vehicle.params import f1tenth

CAR = f1tenth()
DT = 0.05


def straight(t: float, speed: float = 2.0, **fields: float) -> Observation:
    """The car driving along x at ``speed`` (m/s), as measured at ``t`` (s)."""
    return Observation(speed * t, 0.0, 0.0, speed, **{"yaw_rate": 0.0, "time": t, **fields})


def drive(
    estimator: StateEstimator, observations: list[Observation], steer: float = 0.0
) -> list[Observation]:
    out = []
    for k, obs in enumerate(observations):
        out.append(estimator.update(obs, None if k == 0 else Command(2.0, steer)))
    return out


# ---------------------------------------------------------------------------- the models


def test_the_nominal_understeer_and_rear_compliance_follow_from_the_tyres():
    model = SingleTrackModel(CAR, EstimatorConfig())
    m, g, L, lf, lr = CAR.mass, CAR.gravity, CAR.wheelbase, CAR.lf, CAR.lr
    c_f = CAR.tyre_front.B * CAR.tyre_front.C * CAR.tyre_front.D * m * g * lr / L
    c_r = CAR.tyre_rear.B * CAR.tyre_rear.C * CAR.tyre_rear.D * m * g * lf / L
    assert axle_cornering_stiffness(CAR) == pytest.approx((c_f, c_r))
    assert model.understeer == pytest.approx(m / L * (lr / c_f - lf / c_r))
    assert 0.0 < model.understeer < 0.02  # the F1TENTH car understeers
    assert model.lateral_gain(0.0) == lr  # kinematic at rest: vy = lr r
    assert SingleTrackModel(CAR, EstimatorConfig(understeer_gradient=0.0)).steady_yaw_rate(2.0, 0.1) == (
        pytest.approx(2.0 * math.tan(0.1) / L)
    )


def test_the_transition_jacobian_is_the_derivative_of_the_transition():
    model = SingleTrackModel(CAR, EstimatorConfig())
    state = [1.0, -2.0, 0.7, 3.0, -0.1, 1.2, 1.1, 0.02]
    model.transition(state, 0.04, 0.15)
    F = model.F.copy()
    numeric = np.empty_like(F)
    for j in range(len(state)):
        up, down = list(state), list(state)
        up[j] += 1e-6
        down[j] -= 1e-6
        numeric[:, j] = (
            np.array(model.transition(up, 0.04, 0.15)) - model.transition(down, 0.04, 0.15)
        ) / 2e-6
    np.testing.assert_allclose(F, numeric, atol=1e-8)


# ---------------------------------------------------------------------------- against filterpy


def pose_of(x: np.ndarray, lag: float) -> np.ndarray:
    """The model's pose measurement, written from the module's equations."""
    yaw, vx, vy, r = x[2], x[3], x[4], x[5]
    psi = yaw - 0.5 * lag * r
    return np.array(
        [
            x[0] - lag * (vx * math.cos(psi) - vy * math.sin(psi)),
            x[1] - lag * (vx * math.sin(psi) + vy * math.cos(psi)),
            yaw - lag * r,
        ]
    )


def jacobian(h, x: np.ndarray) -> np.ndarray:
    cols = []
    for j in range(len(x)):
        e = np.zeros(len(x))
        e[j] = 1e-6
        cols.append((h(x + e) - h(x - e)) / 2e-6)
    return np.column_stack(cols)


def test_one_update_is_filterpys_ekf_predict_and_updates_on_the_same_model():
    """Prediction by filterpy's KalmanFilter with the step's F and Q; then pose, speed and gyro
    updates by filterpy's ExtendedKalmanFilter with measurement functions written here."""
    kalman = pytest.importorskip("filterpy.kalman", reason="filterpy 2.0.0 (the test extra) is the reference")
    config = EstimatorConfig()
    estimator = StateEstimator(CAR, config)
    history = [straight(0.05 * k, speed=2.0, yaw_rate=0.3, pose_time=0.05 * k - 0.04) for k in range(6)]
    drive(estimator, history, steer=0.1)
    before = estimator.last_step()
    t, lag = 0.3, 0.045
    obs = Observation(0.63, 0.05, 0.04, 2.3, 0.42, time=t, pose_time=t - lag)
    estimator.update(obs, Command(2.0, 0.1))
    step = estimator.last_step()

    kf = kalman.KalmanFilter(dim_x=8, dim_z=1)
    kf.x, kf.P = before.state.copy(), before.covariance.copy()
    kf.predict(F=step.transition, Q=step.noise)
    np.testing.assert_allclose(step.prior_covariance, kf.P, rtol=1e-12, atol=1e-15)

    ekf = kalman.ExtendedKalmanFilter(dim_x=8, dim_z=3)
    ekf.x, ekf.P = step.prior_state.copy(), step.prior_covariance.copy()
    R = np.diag(
        [
            config.position_std**2 + lag * config.position_density**2,
            config.position_std**2 + lag * config.position_density**2,
            config.yaw_std**2 + lag * config.yaw_density**2,
        ]
    )

    def residual(a, b):
        d = np.asarray(a, dtype=float) - b
        d[2] = wrap_scalar(float(d[2]))
        return d

    z = np.array([obs.x, obs.y, obs.yaw])
    ekf.update(
        z, lambda x: jacobian(lambda s: pose_of(s, lag), x), lambda x: pose_of(x, lag), R=R, residual=residual
    )
    scalar = kalman.ExtendedKalmanFilter(dim_x=8, dim_z=1)
    scalar.x, scalar.P = ekf.x, ekf.P
    for value, h, var in (
        (obs.speed, lambda s: np.array([s[6] * s[3]]), config.speed_std**2),
        (obs.yaw_rate, lambda s: np.array([s[5] + s[7]]), config.yaw_rate_std**2),
    ):
        scalar.update(np.array([value]), lambda x, h=h: jacobian(h, x), h, R=np.array([[var]]))
    np.testing.assert_allclose(step.state, scalar.x, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(step.covariance, scalar.P, rtol=1e-6, atol=1e-10)


def test_the_yaw_accelerations_noise_moves_the_heading_as_continuous_white_noise():
    kalman = pytest.importorskip("filterpy.common", reason="filterpy 2.0.0 (the test extra) is the reference")
    config = EstimatorConfig()
    model = SingleTrackModel(CAR, config)
    h = 0.05
    q = model.process_noise(h)
    yaw, r = STATE_NAMES.index("yaw"), STATE_NAMES.index("yaw_rate")
    block = q[np.ix_([yaw, r], [yaw, r])].copy()
    block[0, 0] -= config.yaw_density**2 * h  # the heading's own random walk
    reference = kalman.Q_continuous_white_noise(
        dim=2, dt=h, spectral_density=config.yaw_acceleration_density**2
    )
    np.testing.assert_allclose(block, reference, rtol=1e-12)
    others = np.delete(np.delete(q, [yaw, r], axis=0), [yaw, r], axis=1)
    assert np.count_nonzero(others - np.diag(np.diag(others))) == 0


# ---------------------------------------------------------------------------- behaviour


def test_a_pose_jump_is_rejected_and_counted():
    estimator = StateEstimator(CAR)
    obs = [straight(DT * k) for k in range(40)]
    obs[25] = replace(obs[25], x=obs[25].x + 1.0, y=0.4)
    out = drive(estimator, obs)
    assert abs(out[25].x - obs[25].x + 1.0) < 0.05 and abs(out[25].y) < 0.05
    diag = estimator.diagnostics()
    assert (diag.poses_rejected, diag.pose_reinitialisations) == (1, 0)
    assert diag.poses_used == 39


def test_a_lasting_offset_reinitialises_the_pose_instead_of_drifting():
    config = EstimatorConfig(max_rejections=5)
    estimator = StateEstimator(CAR, config)
    obs = [straight(DT * k) for k in range(60)]
    obs = obs[:30] + [replace(o, y=1.0) for o in obs[30:]]  # the localiser relocalised 1 m aside
    out = drive(estimator, obs)
    diag = estimator.diagnostics()
    assert diag.pose_reinitialisations == 1 and diag.poses_rejected == 5
    assert out[-1].y == pytest.approx(1.0, abs=0.02)


def test_a_pose_that_did_not_change_is_no_measurement():
    estimator = StateEstimator(CAR)
    obs = [straight(DT * k, pose_time=DT * (k // 2) * 2) for k in range(20)]
    obs = [replace(o, x=2.0 * o.pose_time) for o in obs]  # the pose of its own time, held
    out = drive(estimator, obs)
    diag = estimator.diagnostics()
    assert diag.poses_repeated == 10 and diag.poses_used == 10
    # Between poses the car is dead-reckoned, not held back at the old pose.
    assert out[-1].x == pytest.approx(2.0 * obs[-1].time, abs=0.02)
    # Without a pose_time, the same values again are the same pose.
    held = [Observation(2.0, 0.0, 0.0, 2.0, time=1.0 + DT * k) for k in range(4)]
    drive(estimator, held)
    assert estimator.diagnostics().poses_repeated == 10 + 3
    # Nor with a pose_time that moves on with the message (an odometry's stamp less a latency).
    later = [Observation(2.0, 0.0, 0.0, 2.0, time=1.2 + DT * k, pose_time=1.17 + DT * k) for k in range(4)]
    drive(estimator, later)
    assert estimator.diagnostics().poses_repeated == 10 + 3 + 4


def test_the_pose_is_brought_forward_over_its_latency():
    lag = 0.1
    estimator = StateEstimator(CAR)
    obs = [
        Observation(3.0 * (DT * k - lag), 0.0, 0.0, 3.0, 0.0, time=DT * k, pose_time=DT * k - lag)
        for k in range(30)
    ]
    out = drive(estimator, obs)
    # The pose reports where the car was 0.1 s (0.3 m) ago; the estimate is where it is now.
    assert out[-1].x == pytest.approx(3.0 * obs[-1].time, abs=0.01)
    # An older sample than the limit allows (0.6 s late: where the car was 0.6 s before then).
    too_old = replace(
        obs[-1], x=3.0 * (obs[-1].time + DT - 0.6), time=obs[-1].time + DT, pose_time=obs[-1].time + DT - 0.6
    )
    estimator.update(too_old, Command(3.0, 0.0))
    assert estimator.diagnostics().poses_too_old == 1


def test_the_sensor_scale_and_gyro_bias_are_learned_from_the_poses():
    # A circle of radius 4 m at 2 m/s driven as the estimator's model drives it: the heading is the
    # course less the rear axle's slip, the wheel angle that of steady cornering. (Driven
    # kinematically instead, heading = course, the slip the model expects is found nowhere and
    # the bias takes up part of it: 0.054 rad/s for 0.04.)
    model = SingleTrackModel(CAR, EstimatorConfig())
    speed, rate = 2.0, 0.5
    slip = math.atan(model.lateral_gain(speed) * rate / speed)
    steer = math.atan(model.effective_wheelbase(speed) * rate / speed)
    estimator = StateEstimator(CAR)
    out = []
    for k in range(400):
        t = DT * k
        course = rate * t
        obs = Observation(
            4 * math.sin(course),
            4 * (1 - math.cos(course)),
            course - slip,
            1.2 * speed * math.cos(slip),
            rate + 0.04,
            time=t,
        )
        out.append(estimator.update(obs, None if k == 0 else Command(speed, steer)))
    diag = estimator.diagnostics()
    assert diag.speed_scale == pytest.approx(1.2, abs=0.03)
    assert diag.gyro_bias == pytest.approx(0.04, abs=0.005)
    assert out[-1].speed == pytest.approx(2.0 * math.cos(slip), abs=0.06)
    assert out[-1].yaw_rate == pytest.approx(0.5, abs=0.01)
    assert out[-1].slip_angle == pytest.approx(slip, abs=0.005)


def test_a_gap_or_a_time_going_back_restarts_the_filter():
    estimator = StateEstimator(CAR)
    drive(estimator, [straight(DT * k) for k in range(5)])
    estimator.update(straight(5.0), Command(2.0, 0.0))
    estimator.update(straight(1.0), Command(2.0, 0.0))
    diag = estimator.diagnostics()
    assert (diag.restarts_gap, diag.restarts_time) == (1, 1)
    assert estimator.last_step().started


def test_the_first_pose_after_a_long_blackout_restarts_the_pose_without_a_rejection():
    estimator = StateEstimator(CAR)
    drive(estimator, [straight(DT * k) for k in range(10)])
    # 3 s without a pose (the last one repeated) nor speed and yaw rate: dead reckoning only.
    blind = [Observation(0.9, 0.0, 0.0, math.nan, time=DT * k, pose_time=0.45) for k in range(10, 70)]
    drive(estimator, blind)
    back = estimator.update(Observation(3.0, 2.0, 1.0, 0.0, 0.0, time=3.5, pose_time=3.5), Command(0.0, 0.0))
    diag = estimator.diagnostics()
    assert (diag.restarts_gap, diag.poses_rejected, diag.pose_reinitialisations) == (1, 0, 0)
    assert (back.x, back.y, back.yaw) == pytest.approx((3.0, 2.0, 1.0))


def test_measured_wheel_and_slip_angles_are_used():
    estimator = StateEstimator(CAR)
    obs = [straight(DT * k, slip_angle=0.05, steer_angle=0.12) for k in range(30)]
    out = drive(estimator, obs, steer=0.3)
    assert out[-1].steer_angle == 0.12
    assert estimator.diagnostics().slips_used == 29
    assert out[-1].slip_angle == pytest.approx(0.05, abs=0.01)


def test_without_a_pose_the_observation_passes_with_the_wheel_angle():
    estimator = StateEstimator(CAR, steering=SteeringModel.nominal(CAR))
    blind = Observation(math.nan, math.nan, math.nan, 2.0, time=0.0)
    out = estimator.update(blind, None)
    assert math.isnan(out.x) and out.steer_angle == 0.0 and not estimator.initialised
    assert estimator.update(straight(DT), Command(2.0, 0.2)).x == pytest.approx(2.0 * DT)


def test_the_state_names_and_the_diagnostics_record():
    assert STATE_NAMES[:3] == ("x", "y", "yaw") and len(STATE_NAMES) == 8
    estimator = StateEstimator(CAR)
    drive(estimator, [straight(DT * k) for k in range(3)])
    record = estimator.diagnostics().as_dict()
    assert record["estimator_updates"] == 3.0 and record["estimator_poses_used"] == 3.0


@pytest.mark.parametrize(
    ("field", "value"),
    [("position_std", 0.0), ("gate_probability", 1.0), ("max_rejections", 0), ("speed_scale_density", -1.0)],
)
def test_a_bad_setting_is_refused_naming_it(field, value):
    with pytest.raises(ParameterError, match=f"EstimatorConfig.{field}"):
        EstimatorConfig(**{field: value})
