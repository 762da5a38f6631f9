"""The LMPC linearised about its own previous plan (``linearisation = "plan"``), with the affine term.

``"plan-midpoint"`` rolls the plan out by the midpoint rule instead of forward Euler.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from driving import drive_then_step
from rkmpc.analysis.metrics import lap_metrics
from rkmpc.control.linear.lmpc import LinearMPC, LMPCConfig, roll_out
from rkmpc.control.linear.lmpc_id import IdentifiedLMPC
from rkmpc.control.linear.problem import condense
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.vehicle.kinematic import kinematic_rhs
from rkmpc.vehicle.registry import make_plant

PLAN = LMPCConfig(linearisation="plan")
MIDPOINT = LMPCConfig(linearisation="plan-midpoint")


def _step(pose, v, rate, T, midpoint):
    """One step of the kinematic pose: the heading advances by ``T rate``, the position along the
    heading at the step's start (forward Euler) or its middle (midpoint)."""
    course = pose[2] + (0.5 * T * rate if midpoint else 0.0)
    return pose + T * np.array([v * np.cos(course), v * np.sin(course), rate])


def _horizon(sc, mpc):
    n = mpc.config.horizon
    ref = sc.reference.horizon(3.0, n, mpc.config.dt)
    u_ref = np.column_stack([ref.v[:n], ref.delta[:n]])
    observation = Observation(x=ref.x[0] + 0.05, y=ref.y[0] - 0.03, yaw=ref.theta[0] + 0.04, speed=ref.v[0])
    return ref, u_ref, observation


@pytest.mark.parametrize("config", [PLAN, MIDPOINT], ids=lambda c: c.linearisation)
def test_the_prediction_reproduces_the_plan_it_is_linearised_about(builtin_scenario, config):
    sc = builtin_scenario
    midpoint = config.linearisation == "plan-midpoint"
    mpc = LinearMPC(sc.reference, sc.vehicle, config)
    n, T, L = mpc.config.horizon, mpc.config.dt, sc.vehicle.wheelbase
    ref, u_ref, observation = _horizon(sc, mpc)
    # Before any plan: the prediction along the reference, with a zero affine column.
    xi0, Phi, Gamma = mpc._prediction(observation, ref, u_ref)
    plain = LinearMPC(sc.reference, sc.vehicle)._prediction(observation, ref, u_ref)
    assert xi0.shape == (4,) and xi0[3] == 1.0 and Phi.shape == (3 * n, 4)
    np.testing.assert_array_equal(Phi[:, :3], plain[1])
    np.testing.assert_array_equal(Phi[:, 3], 0.0)
    np.testing.assert_array_equal(Gamma, plain[2])
    # With a plan: driving the shifted plan, the prediction is that plan's roll-out.
    rng = np.random.default_rng(0)
    mpc.last_plan = u_ref + rng.normal(0.0, [0.2, 0.05], size=(n, 2))
    xi0, Phi, Gamma = mpc._prediction(observation, ref, u_ref)
    u_bar = np.vstack([mpc.last_plan[1:], mpc.last_plan[-1:]])
    state = np.array([observation.x, observation.y, ref.theta[0] + xi0[2]])
    rolled = []
    for k in range(n):
        state = _step(state, u_bar[k, 0], kinematic_rhs(state, u_bar[k], L)[2], T, midpoint)
        rolled.append(state)
    expected = np.array(rolled) - np.column_stack([ref.x[1 : n + 1], ref.y[1 : n + 1], ref.theta[1 : n + 1]])
    predicted = (Phi @ xi0 + Gamma @ (u_bar - u_ref).ravel()).reshape(n, 3)
    np.testing.assert_allclose(predicted, expected, atol=1e-9)
    # Near the plan the prediction is the model's to first order: a small change of the inputs
    # moves the roll-out by Gamma times it, up to second-order terms. The slopes are the forward-Euler
    # model's (the QP's), so with the midpoint rule they are off by terms of the order of a step's turn.
    tolerance = 5e-5 if midpoint else 1e-5
    change = rng.normal(0.0, [1e-3, 1e-4], size=(n, 2))
    state = np.array([observation.x, observation.y, ref.theta[0] + xi0[2]])
    moved = []
    for k in range(n):
        state = _step(
            state, u_bar[k, 0] + change[k, 0], kinematic_rhs(state, u_bar[k] + change[k], L)[2], T, midpoint
        )
        moved.append(state)
    linear = expected.ravel() + Gamma @ change.ravel()
    exact = (np.array(moved) - (np.array(rolled) - expected)).ravel()
    assert np.max(np.abs(linear - exact)) < tolerance < 0.2 * np.max(np.abs(Gamma @ change.ravel()))


def test_a_residual_mpc_on_top_gets_the_kinematic_prediction_along_the_reference(builtin_scenario):
    sc = builtin_scenario
    mpc = LinearMPC(sc.reference, sc.vehicle, PLAN)
    assert mpc.kinematic_prediction() is None
    obs = drive_then_step(sc, mpc, 20)
    own, kin = mpc.last_prediction, mpc.kinematic_prediction()
    assert own is not None and kin is not None
    assert own.xi0.shape == (4,) and np.any(own.Phi[:, 3] != 0.0)
    xi0, Phi, Gamma = LinearMPC(sc.reference, sc.vehicle)._prediction(obs, own.reference, own.u_ref)
    np.testing.assert_array_equal(kin.Phi, Phi)
    np.testing.assert_array_equal(kin.Gamma, Gamma)
    np.testing.assert_allclose(kin.xi0, xi0, atol=1e-15)
    np.testing.assert_array_equal(kin.plan, own.plan)


def test_about_its_plan_the_lmpc_gains_from_the_euler_roll_outs_chord_error(builtin_scenario):
    # Rolled out by forward Euler, the plan ends outside the arc the car drives, and the LMPC steers
    # into corners earlier: at least 10 % lower on the built-in track. Rolled out by the midpoint
    # rule, the plan's prediction is nearly the arc, and the LMPC gains less than 10 %.
    sc = builtin_scenario
    errors = {}
    for config in (LMPCConfig(), PLAN, MIDPOINT):
        result = simulate(
            make_plant("f1tenth"),
            LinearMPC(sc.reference, sc.vehicle, config),
            sc.track,
            sc.reference,
            SimConfig(dt=sc.dt, laps=1),
        )
        assert result.outcome == "completed"
        errors[config.linearisation] = lap_metrics(result).lateral_error_mean_m
    assert errors["plan"] < 0.9 * errors["reference"]
    assert 0.9 * errors["reference"] < errors["plan-midpoint"] < errors["reference"]


def test_the_midpoint_roll_out_follows_a_constant_turns_arc_where_euler_leaves_it():
    # A constant speed and turn: the car drives a circle of radius R = v T / turn through the start,
    # heading along +x, centred at (0, R).
    n, T, v, turn = 20, 0.05, 3.0, 0.15
    speed, turns = np.full(n, v), np.full(n, turn)
    zero = SimpleNamespace(x=np.zeros(n + 1), y=np.zeros(n + 1), theta=np.zeros(n + 1))
    radius = v * T / turn
    # The midpoint rule's steps are chords of the circle of radius v T / (2 sin(turn / 2)) tangent
    # to the start heading: larger by a relative turn^2 / 24, 0.09 % here.
    chord_radius = v * T / (2.0 * np.sin(turn / 2.0))
    off = {}
    for midpoint in (False, True):
        _, pose = roll_out((0.0, 0.0, 0.0), speed, turns, T, zero, midpoint=midpoint)
        np.testing.assert_allclose(pose[:, 2], turn * np.arange(1, n + 1))
        off[midpoint] = np.max(np.abs(np.hypot(pose[:, 0], pose[:, 1] - radius) - radius))
        if midpoint:
            distance = np.hypot(pose[:, 0], pose[:, 1] - chord_radius)
            np.testing.assert_allclose(distance, chord_radius, rtol=1e-12)
    # Off the car's circle: the midpoint rule by at most twice that radius difference; forward
    # Euler, whose steps start half a turn too early, by some 40 times more.
    assert off[True] <= 2.0 * (chord_radius - radius) * (1 + 1e-9)
    assert off[False] > 20.0 * off[True]


class _RecordingId(IdentifiedLMPC):
    """Keeps the plan its step is linearised about and its model along the reference."""

    def _prediction(self, observation, ref, u_ref):
        self.about = None if self.last_plan is None else self.last_plan.copy()
        return super()._prediction(observation, ref, u_ref)

    def _model(self, observation, ref, u_ref):
        xi0, A, B = super()._model(observation, ref, u_ref)
        self.along_reference = (xi0, *condense(A, B))
        return xi0, A, B


@pytest.mark.parametrize("config", [PLAN, MIDPOINT], ids=lambda c: c.linearisation)
def test_lmpc_id_about_its_plan_predicts_the_roll_out_of_its_servo_and_pose(builtin_scenario, config):
    sc = builtin_scenario
    model = IdentifiedModel(0.08, 0.02, 0.99, 0.9, 1000, "delay-lag", 0.05, None)
    ctrl = _RecordingId(sc.reference, sc.vehicle, model, config)
    obs = drive_then_step(sc, ctrl, 45)  # into the first corner, with a history of commands and plans
    pred = ctrl.last_prediction
    assert ctrl.about is not None and pred is not None
    n, T, L, K = ctrl.config.horizon, sc.dt, sc.vehicle.wheelbase, model.understeer_gradient
    u_bar = np.vstack([ctrl.about[1:], ctrl.about[-1:]])
    du_bar = (u_bar - pred.u_ref).reshape(-1)
    # The wheel angles of the plan: the servo is linear, the model along the reference has them.
    xi0, Phi_r, Gamma_r = ctrl.along_reference
    nx = len(xi0)
    wheel_ref = ctrl._wheel_reference(pred.reference)
    states = (Phi_r @ xi0 + Gamma_r @ du_bar).reshape(n, nx)
    wheel = wheel_ref[:n] + np.concatenate([[xi0[3]], states[:-1, 3]])
    # The pose rolled out from the measured one, heading rate v tan(delta) / (L + K v^2).
    ref = pred.reference
    pose = np.array([obs.x, obs.y, ref.theta[0] + xi0[2]])
    expected = []
    for k in range(n):
        v = u_bar[k, 0]
        rate = v * np.tan(wheel[k]) / (L + K * v * v)
        pose = _step(pose, v, rate, T, config.linearisation == "plan-midpoint")
        expected.append(pose - [ref.x[k + 1], ref.y[k + 1], ref.theta[k + 1]])
    predicted = (pred.Phi @ xi0 + pred.Gamma @ du_bar).reshape(n, 3)
    np.testing.assert_allclose(predicted, expected, atol=1e-9)
    # Along the reference the same plan is predicted differently (the linearisation moved).
    along = (Phi_r @ xi0 + Gamma_r @ du_bar).reshape(n, nx)[:, :3]
    assert np.max(np.abs(along - np.array(expected))) > 1e-4


def test_an_unknown_linearisation_is_refused():
    with pytest.raises(ParameterError, match="linearisation"):
        LMPCConfig(linearisation="trajectory")
