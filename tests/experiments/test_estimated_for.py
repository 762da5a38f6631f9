"""What a recipe learns from (issue 25): the data as recorded, or estimates where a field was never measured.

:func:`~rkmpc.experiments.training.estimated_for` replaces data whose wheel angle (or speed, or
yaw rate) no row measured by the smoothed estimates, the wheel angle propagated through the servo
the data show (:func:`~rkmpc.experiments.training.identified_steering`), and so does it with data
whose metadata say a simulated car's sensors were not exact (a wheel angle measured beside a
jumping localiser); measured data from exact sensors, and data missing a field in a few rows only
(for ``check_learnable`` to name), pass as they are.

The synthetic car: a kinematic bicycle (wheelbase of the f1tenth car, understeer 0) whose front
wheel follows the steering commands through a given servo (:func:`wheel_angles`, the same
integration the estimator runs), at 3 +- 1.5 m/s; its wheel angle and side-slip are not measured.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.estimation.labels import ESTIMATION_KEY
from rkmpc.estimation.steering import SteeringModel, wheel_angles
from rkmpc.experiments.training import estimated_for, identified_steering
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.identification import identify
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.vehicle.params import f1tenth

VEHICLE = f1tenth()
T = 0.05
STEER = OBSERVATION_FIELDS.index("steer_angle")
#: A servo unlike the car's nominal one (lag 0.158 s, rate 3.2 rad/s, no delay): faster, 0.1 s late.
LATE_SERVO = SteeringModel(time_constant=0.06, max_angle=VEHICLE.steering.max_angle, delay=0.1)


def commands(n: int, seed: int) -> np.ndarray:
    """Steering commands (rad): random levels held 1 to 8 periods, within +-0.35 rad."""
    rng = np.random.default_rng(seed)
    out = np.empty(n)
    k = 0
    while k < n:
        hold = int(rng.integers(1, 9))
        out[k : k + hold] = rng.uniform(-0.35, 0.35)
        k += hold
    return out


def synthetic(servo: SteeringModel, n: int = 600, seed: int = 1) -> TransitionDataset:
    """``n`` transitions of the synthetic car (module docstring); wheel angle and slip NaN."""
    steer = commands(n, seed)
    wheel = wheel_angles(servo, T, steer)
    t = T * np.arange(n + 1)
    speed = 3.0 + 1.5 * np.sin(2 * np.pi * t / 17.0)
    yaw_rate = speed * np.tan(wheel) / VEHICLE.wheelbase
    yaw = np.concatenate([[0.0], np.cumsum(yaw_rate[:-1] * T)])
    x = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.cos(yaw[:-1]) * T)])
    y = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.sin(yaw[:-1]) * T)])
    nan = np.full(n + 1, np.nan)
    obs = np.column_stack([x, y, yaw, speed, yaw_rate, nan, nan])
    return TransitionDataset(
        obs=obs[:-1],
        command=np.column_stack([speed[:-1], steer]),
        next_obs=obs[1:],
        dt=T,
        episode=np.zeros(n, dtype=int),
    )


def with_wheel(data: TransitionDataset, servo: SteeringModel) -> TransitionDataset:
    """``data`` with its wheel angle measured (the servo's true angle)."""
    wheel = wheel_angles(servo, T, data.command[:, 1])
    obs, next_obs = data.obs.copy(), data.next_obs.copy()
    obs[:, STEER], next_obs[:, STEER] = wheel[:-1], wheel[1:]
    return TransitionDataset(obs, data.command, next_obs, data.dt, data.episode, data.metadata)


@pytest.fixture(scope="module")
def unmeasured() -> TransitionDataset:
    return synthetic(LATE_SERVO)


@pytest.fixture(scope="module")
def estimated(unmeasured) -> TransitionDataset:
    return estimated_for(recipe_of_kind("residual"), unmeasured, VEHICLE)


def test_data_without_a_wheel_angle_are_estimated_with_the_servo_the_data_show(unmeasured, estimated):
    assert estimated is not unmeasured
    record = estimated.metadata[ESTIMATION_KEY]
    # The servo identified from the yaw rate's response to the commands: the delay and the fast lag.
    steering = SteeringModel.from_json(record["steering"])
    assert steering.source.startswith("identified")
    assert steering.delay == pytest.approx(0.1, abs=0.02)
    assert steering.time_constant == pytest.approx(0.06, abs=0.02)
    assert steering.max_angle == VEHICLE.steering.max_angle
    assert record["config"]["control_period"] == T
    # Every field is now an estimate: the wheel angle close to the servo's true one.
    assert np.isfinite(estimated.obs).all() and np.isfinite(estimated.next_obs).all()
    # One recording through which the filter ran: every transition kept, the commands as recorded.
    assert len(estimated) == len(unmeasured) and record["transitions_out"] == len(unmeasured)
    np.testing.assert_array_equal(estimated.command, unmeasured.command)
    # The wheel angle propagated through the identified servo is the true one, once the first few
    # steps (the angle at the start is unknown) are past: 0.002 rad at the 95th percentile, where the
    # nominal servo would be off by 0.027 rad in the median.
    truth = wheel_angles(LATE_SERVO, T, unmeasured.command[:, 1])[:-1]
    error = np.abs(estimated.obs[5:, STEER] - truth[5:])
    assert np.percentile(error, 95) < 0.005
    nominal = wheel_angles(SteeringModel.nominal(VEHICLE), T, unmeasured.command[:, 1])[:-1]
    assert np.median(np.abs(nominal[5:] - truth[5:])) > 5 * np.median(error)


@pytest.mark.parametrize("kind", ["paper", "koopman"])
def test_every_koopman_kind_learns_from_estimates_where_the_wheel_angle_is_unmeasured(kind):
    data = synthetic(LATE_SERVO, n=200)
    out = estimated_for(recipe_of_kind(kind), data, VEHICLE)
    assert out is not data and ESTIMATION_KEY in out.metadata and np.isfinite(out.obs[:, STEER]).all()


def test_data_that_never_measured_the_yaw_rate_are_estimated_too(unmeasured):
    measured = with_wheel(unmeasured, LATE_SERVO)
    obs, next_obs = measured.obs.copy(), measured.next_obs.copy()
    column = OBSERVATION_FIELDS.index("yaw_rate")
    obs[:, column] = next_obs[:, column] = np.nan
    data = TransitionDataset(obs, measured.command, next_obs, T, measured.episode)
    out = estimated_for(recipe_of_kind("residual"), data, VEHICLE)
    assert out is not data and ESTIMATION_KEY in out.metadata and np.isfinite(out.obs[:, column]).all()


def test_an_identification_learns_from_the_data_as_recorded(unmeasured):
    assert estimated_for(recipe_of_kind("identified"), unmeasured, VEHICLE) is unmeasured


def test_measured_data_are_returned_as_they_are(unmeasured):
    measured = with_wheel(unmeasured, LATE_SERVO)
    for kind in ("residual", "paper", "koopman", "identified"):
        assert estimated_for(recipe_of_kind(kind), measured, VEHICLE) is measured


def test_data_missing_a_field_in_a_few_rows_only_are_returned_as_they_are(unmeasured):
    measured = with_wheel(unmeasured, LATE_SERVO)
    obs = measured.obs.copy()
    obs[[10, 200, 201], STEER] = np.nan  # a sensor that dropped out: check_learnable names the rows
    holes = TransitionDataset(obs, measured.command, measured.next_obs, T, measured.episode)
    assert estimated_for(recipe_of_kind("residual"), holes, VEHICLE) is holes


def test_identified_steering_is_the_nominal_servo_where_identification_marks_it_nominal():
    nominal = SteeringModel.nominal(VEHICLE)
    data = synthetic(nominal)  # a car whose servo is exactly the nominal one, K = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = identify(data, VEHICLE)
    assert model.status == "nominal"
    assert identified_steering(data, VEHICLE) == nominal


def test_identified_steering_is_the_nominal_servo_where_identification_cannot_run():
    data = synthetic(LATE_SERVO, n=10)  # too few transitions to identify anything
    assert identified_steering(data, VEHICLE) == SteeringModel.nominal(VEHICLE)


def test_identified_steering_recovers_a_late_servo(unmeasured):
    steering = identified_steering(unmeasured, VEHICLE)
    assert steering.source.startswith("identified") and steering.delay == pytest.approx(0.1, abs=0.02)
    assert math.isclose(steering.max_angle, VEHICLE.steering.max_angle)


def _with_metadata(data: TransitionDataset, **metadata: object) -> TransitionDataset:
    return TransitionDataset(data.obs, data.command, data.next_obs, data.dt, data.episode, metadata)


def test_measured_data_from_inexact_sensors_are_estimated_keeping_the_measured_wheel(unmeasured):
    # The controller that drives with such sensors sees the estimator's states; from the raw data a
    # car with a wheel sensor and a jumping localiser would learn its labels from the jumps.
    metadata = {"source": "collect", "sensors": "f1tenth-real", "sensors_ideal": False}
    measured = _with_metadata(with_wheel(unmeasured, LATE_SERVO), **metadata)
    out = estimated_for(recipe_of_kind("residual"), measured, VEHICLE)
    assert out is not measured and ESTIMATION_KEY in out.metadata
    # The estimator takes the measured wheel angle (it propagates the servo only between measurements).
    np.testing.assert_allclose(out.obs[5:, STEER], measured.obs[5:, STEER], atol=1e-9)
    # An identification still learns from the data as recorded.
    assert estimated_for(recipe_of_kind("identified"), measured, VEHICLE) is measured


def test_measured_data_from_ideal_sensors_and_their_concatenations_are_returned_as_they_are(unmeasured):
    ideal = _with_metadata(
        with_wheel(unmeasured, LATE_SERVO), source="collect", sensors="ideal", sensors_ideal=True
    )
    assert estimated_for(recipe_of_kind("residual"), ideal, VEHICLE) is ideal
    both = TransitionDataset.concatenate([ideal, ideal])
    assert estimated_for(recipe_of_kind("residual"), both, VEHICLE) is both
    real = _with_metadata(ideal, source="collect", sensors="f1tenth-real", sensors_ideal=False)
    mixed = TransitionDataset.concatenate([ideal, real])
    assert estimated_for(recipe_of_kind("residual"), mixed, VEHICLE) is not mixed
    # A real car's log says nothing of its sensors' exactness: learned from as its fields say.
    bag = _with_metadata(ideal, source="bag")
    assert estimated_for(recipe_of_kind("residual"), bag, VEHICLE) is bag


def test_the_smoother_dates_the_poses_back_by_the_latency_the_data_record(unmeasured):
    real = {"source": "collect", "sensors": "f1tenth-real", "sensors_ideal": False}
    late = _with_metadata(unmeasured, **real, pose_latency=0.03)
    residual = recipe_of_kind("residual")

    def latency(data: TransitionDataset) -> float:
        return float(estimated_for(residual, data, VEHICLE).metadata[ESTIMATION_KEY]["pose_latency_s"])

    assert latency(late) == 0.03
    # A log that does not say is taken as its stamps say; a concatenation takes its parts' latency.
    assert latency(unmeasured) == 0.0
    assert latency(TransitionDataset.concatenate([late, late])) == 0.03
    other = _with_metadata(unmeasured, **real, pose_latency=0.05)
    with pytest.raises(ParameterError, match="different times"):
        estimated_for(residual, TransitionDataset.concatenate([late, other]), VEHICLE)
