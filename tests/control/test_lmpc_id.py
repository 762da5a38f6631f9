"""lmpc-id drives with what was identified: the delayed lag predicted exactly, the rate limit applied."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rkmpc.analysis.metrics import lap_metrics
from rkmpc.control.linear.lmpc_id import IdentifiedLMPC
from rkmpc.control.linear.problem import condense
from rkmpc.estimation.steering import SteeringModel, WheelAnglePropagator
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.learning.servo_fit import lag_delay_weights
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.registry import make_plant


def _model(tau: float = 0.08, delay: float = 0.0, rate: float | None = None) -> IdentifiedModel:
    structure = "delay-lag" if rate is None else "delay-lag-rate"
    return IdentifiedModel(tau, 0.01, 0.99, 0.9, 1000, structure, delay, rate)


class _Recording(IdentifiedLMPC):
    """Keeps the full condensed model of its last step."""

    def _model(self, observation, ref, u_ref):
        xi0, A, B = super()._model(observation, ref, u_ref)
        self.full = (xi0, *condense(A, B))
        self.wheel_ref = self._wheel_reference(ref)
        return xi0, A, B


@pytest.mark.parametrize("delay", [0.0, 0.03, 0.05, 0.07, 0.12])
def test_the_prediction_of_the_wheel_is_the_delayed_lag_of_past_and_planned_commands(builtin_scenario, delay):
    sc = builtin_scenario
    ctrl = _Recording(sc.reference, sc.vehicle, _model(delay=delay))
    plant = make_plant("f1tenth")
    start = sc.reference.horizon(0.0, 1, sc.dt)
    plant.reset(start.x[0], start.y[0], start.theta[0], start.v[0], start.delta[0])
    for _ in range(45):  # into the first corner, with a history of commands
        command = ctrl.step(plant.observe())
        plant.step(command, sc.dt)
    ctrl.step(plant.observe())
    xi0, Phi, Gamma = ctrl.full
    pred = ctrl.last_prediction
    n, nx = ctrl.config.horizon, len(xi0)
    X = (Phi @ xi0 + Gamma @ (pred.plan - pred.u_ref).reshape(-1)).reshape(n, nx)
    predicted = X[:, 3] + ctrl.wheel_ref[1:]
    # The same by the servo's exact discretisation, from the measured wheel angle.
    a, w = lag_delay_weights(0.08, delay, sc.dt)
    past = list(ctrl._wheel.past_commands[::-1])  # u_{k-p}, ..., u_{k-1}
    commands = np.concatenate([past, pred.plan[:, 1]])
    wheel = xi0[3] + ctrl.wheel_ref[0]
    expected = []
    for i in range(n):
        now = len(past) + i  # index of u_{k+i}
        wheel = a * wheel + sum(w[j] * commands[now - j] for j in range(len(w)))
        expected.append(wheel)
    np.testing.assert_allclose(predicted, expected, atol=1e-10)
    assert np.ptp(ctrl.wheel_ref) > 0.05  # the reference wheel angle moves over the horizon
    # The QP gets the pose rows of the same prediction.
    pose = (
        Phi.reshape(n, nx, nx)[:, :3].reshape(3 * n, nx),
        Gamma.reshape(n, nx, -1)[:, :3].reshape(3 * n, -1),
    )
    np.testing.assert_array_equal(pred.Phi, pose[0])
    np.testing.assert_array_equal(pred.Gamma, pose[1])


def test_a_tighter_identified_rate_limit_limits_the_steering_steps(builtin_scenario):
    sc = builtin_scenario
    slow = IdentifiedLMPC(sc.reference, sc.vehicle, _model(rate=1.0))
    assert slow._guard.steer_step_max == pytest.approx(1.0 * sc.dt)
    assert slow.problem.steer_step_max == pytest.approx(1.0 * sc.dt)
    fast = IdentifiedLMPC(sc.reference, sc.vehicle, _model(rate=50.0))
    assert fast._guard.steer_step_max == pytest.approx(sc.vehicle.steering.max_rate * sc.dt)
    assert slow.vehicle.steering.max_rate == 1.0 and sc.vehicle.steering.max_rate > 1.0


def test_on_a_delay_dominated_servo_the_delay_states_beat_a_lag_folded_from_the_delay(builtin_scenario):
    """0.12 s delay and 0.03 s lag: driving with the delay beats a 0.15 s lag without it."""
    sc = builtin_scenario
    params = replace(sc.vehicle, steering=replace(sc.vehicle.steering, time_constant=0.03))

    def lateral_error(model: IdentifiedModel) -> float:
        plant = DynamicPlant(params, input_delay=0.12)
        ctrl = IdentifiedLMPC(sc.reference, sc.vehicle, model)
        result = simulate(plant, ctrl, sc.track, sc.reference, SimConfig(dt=sc.dt, max_time=12.0))
        assert result.outcome == "timeout"  # still on the track
        return float(lap_metrics(result).lateral_error_mean_m)

    with_delay = lateral_error(_model(tau=0.03, delay=0.12))
    folded = lateral_error(_model(tau=0.15, delay=0.0))
    assert with_delay < 0.7 * folded


@pytest.mark.parametrize("fitted_on", ["steer_angle", "yaw_rate", None])
def test_a_servo_identified_from_the_yaw_rate_runs_its_wheel_from_the_commands(builtin_scenario, fitted_on):
    """Its wheel is the steering as the yaw rate sees it: a measured wheel angle is not that state."""
    sc = builtin_scenario
    model = replace(_model(tau=0.1, delay=0.05), fitted_on=fitted_on)
    ctrl = _Recording(sc.reference, sc.vehicle, model)
    plant = make_plant("f1tenth")
    start = sc.reference.horizon(0.0, 1, sc.dt)
    plant.reset(start.x[0], start.y[0], start.theta[0], start.v[0], start.delta[0])
    from_commands = WheelAnglePropagator(
        SteeringModel.from_identified(model, sc.vehicle.steering.max_angle), sc.dt
    )
    apart = 0.0
    for _ in range(60):  # into the first corner
        observation = plant.observe()
        previous = None if ctrl._guard.previous is None else ctrl._guard.previous.copy()
        command = ctrl.step(observation)
        plant.step(command, sc.dt)
        wheel = ctrl.full[0][3] + ctrl.wheel_ref[0]
        estimate = from_commands.step(None if previous is None else float(previous[1]))
        expected = estimate if fitted_on == "yaw_rate" else observation.steer_angle
        assert wheel == pytest.approx(expected, abs=1e-12)
        apart = max(apart, abs(estimate - observation.steer_angle))
    assert apart > 1e-3  # the two differ on this drive
