"""EstimatedController: any controller stepped with the estimator's states, never crashing its caller."""

from __future__ import annotations

import math

import pytest

from rkmpc.control.base import Controller
from rkmpc.control.estimated import EstimatedController
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.estimation import EstimatorConfig, StateEstimator
from rkmpc.vehicle.params import f1tenth
from scripted_controller import Scripted as ScriptedController

CAR = f1tenth()
DT = 0.05


class Scripted(ScriptedController):
    """Answers a fixed command (or NaN, or raises), needs the optional fields measured, counts its steps."""

    dt = DT
    measured_fields = ("yaw_rate", "steer_angle")

    def diagnostics(self) -> dict[str, float]:
        return {"scripted_steps": float(len(self.seen))}


class Broken(StateEstimator):
    def update(self, observation, command_sent_last):
        raise RuntimeError("estimator exploded")


def raw(t: float) -> Observation:
    """What a car without a wheel-angle sensor measures, driving along x at 2 m/s."""
    return Observation(2.0 * t, 0.0, 0.0, 2.0, 0.0, math.nan, math.nan, t)


def wrapped(inner: Controller | None = None, estimator: StateEstimator | None = None) -> EstimatedController:
    return EstimatedController(
        inner or Scripted(), estimator or StateEstimator(CAR, EstimatorConfig(control_period=DT))
    )


def test_the_inner_controller_sees_estimates_and_the_estimator_the_commands_sent():
    controller = wrapped()
    controller.reset()
    commands = [controller.step(raw(DT * k)) for k in range(10)]
    assert commands[-1] == Command(2.0, 0.1) and controller.info.status == "ok"
    seen = controller.inner.seen
    assert all(math.isfinite(o.steer_angle) and math.isfinite(o.slip_angle) for o in seen)
    # The wheel angle lags the command it was told about: 0, then towards 0.1.
    assert seen[0].steer_angle == 0.0 and 0.0 < seen[1].steer_angle < seen[-1].steer_angle < 0.1
    assert controller.name == "scripted" and controller.dt == DT


def test_the_diagnostics_merge_the_estimators_counts():
    controller = wrapped()
    controller.reset()
    for k in range(5):
        controller.step(raw(DT * k))
    diagnostics = controller.diagnostics()
    assert diagnostics["scripted_steps"] == 5.0 and diagnostics["estimator_poses_used"] == 5.0
    controller.reset()
    assert controller.diagnostics()["estimator_updates"] == 0.0


def test_without_a_pose_the_inner_controller_refuses_and_the_command_is_a_stop():
    controller = wrapped()
    controller.reset()
    command = controller.step(Observation(math.nan, math.nan, math.nan, math.nan, time=0.0))
    assert command == Command(0.0, 0.0) and controller.info.status == "invalid_input"
    assert controller.step(raw(DT)).speed == 2.0


@pytest.mark.parametrize(
    ("inner", "estimator", "status"),
    [
        (Scripted(fail=True), None, "exception"),
        (Scripted(Command(math.nan, 0.1)), None, "nonfinite_command"),
        (None, Broken(CAR, EstimatorConfig(control_period=DT)), "exception"),
    ],
)
def test_a_failure_inside_is_a_finite_stop_never_an_exception(inner, estimator, status):
    controller = wrapped(inner, estimator)
    controller.reset()
    command = controller.step(raw(0.0))
    assert controller.info.status == status and command == Command(0.0, 0.0)
    assert controller.fallback_count == 1


def test_the_periods_must_agree():
    with pytest.raises(ParameterError, match="period"):
        EstimatedController(Scripted(), StateEstimator(CAR, EstimatorConfig(control_period=0.1)))
