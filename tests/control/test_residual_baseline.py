"""A residual MPC on another baseline: lmpc-id's plan corrected through the kinematic input channel."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from driving import drive_then_step
from rkmpc.control.learned.rkmpc import ResidualKoopmanMPC
from rkmpc.control.linear.lmpc import LinearMPC, LMPCConfig
from rkmpc.control.linear.lmpc_id import IdentifiedLMPC
from rkmpc.core.errors import ParameterError
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.sim.scenario import Scenario, load_scenario
from rkmpc.vehicle.registry import make_plant


def _identified() -> IdentifiedModel:
    """A servo with a 30 ms delay and an 80 ms lag, some understeer."""
    return IdentifiedModel(0.08, 0.01, 0.99, 0.9, 1000, "delay-lag", 0.03, None)


def _kinematic_model() -> SimpleNamespace:
    """A residual model of a car that is exactly kinematic: ``U_p = U``, on the 5 rkmpc features."""
    return SimpleNamespace(
        A_=0.5 * np.eye(5), B_=np.zeros((5, 2)), C_=np.zeros((2, 5)), D_=np.eye(2), lift=lambda x: x
    )


def _start(sc: Scenario):
    plant = make_plant("f1tenth")
    start = sc.reference.horizon(0.0, 1, sc.dt)
    plant.reset(start.x[0], start.y[0], start.theta[0], start.v[0], start.delta[0])
    return plant


def test_lmpc_id_hands_a_residual_mpc_its_plan_with_the_kinematic_prediction(builtin_scenario):
    sc = builtin_scenario
    ctrl = IdentifiedLMPC(sc.reference, sc.vehicle, _identified())
    assert ctrl.kinematic_prediction() is None
    obs = drive_then_step(sc, ctrl, 30)
    own, kin = ctrl.last_prediction, ctrl.kinematic_prediction()
    assert own is not None and kin is not None
    n = ctrl.config.horizon
    ref = own.reference
    # The nominal LMPC's prediction along the same reference, at the reference inputs.
    plain = LinearMPC(sc.reference, sc.vehicle)
    u_ref = plain._reference_inputs(ref)
    xi0, Phi, Gamma = plain._prediction(obs, ref, u_ref)
    np.testing.assert_array_equal(kin.Phi, Phi)
    np.testing.assert_array_equal(kin.Gamma, Gamma)
    np.testing.assert_array_equal(kin.u_ref, u_ref)
    np.testing.assert_allclose(kin.xi0, xi0, atol=1e-15)
    # lmpc-id's own plan (its wheel feed-forward holds understeer and the delay, not the kinematic one).
    np.testing.assert_array_equal(kin.plan, own.plan)
    assert own.Phi.shape[1] > 3 and kin.Phi.shape == (3 * n, 3)


def test_rkmpc_on_lmpc_id_drives_and_the_baseline_runs_its_servo_from_what_was_sent(builtin_scenario):
    sc = builtin_scenario
    baseline = IdentifiedLMPC(sc.reference, sc.vehicle, _identified())
    ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, _kinematic_model(), baseline=baseline)
    assert ctrl.lmpc is baseline
    plant = _start(sc)
    corrected = 0
    for _ in range(60):
        command = ctrl.step(plant.observe())
        assert np.isfinite([command.speed, command.steer]).all()
        assert ctrl.info.status == "ok"
        sent = np.array([command.speed, command.steer])
        np.testing.assert_array_equal(baseline.previous_command, sent)
        corrected += bool(np.any(ctrl.last_correction != 0.0))
        plant.step(command, sc.dt)
    assert corrected > 30  # the residual QP did correct lmpc-id's plan


def test_the_nominal_baseline_keeps_planning_from_its_own_command(builtin_scenario):
    # rkmpc's tuning: the LMPC's rate constraint starts from the LMPC's own last command.
    sc = builtin_scenario
    ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, _kinematic_model())
    plant = _start(sc)
    differed = 0
    for _ in range(30):
        command = ctrl.step(plant.observe())
        sent = np.array([command.speed, command.steer])
        differed += bool(np.any(ctrl.lmpc.previous_command != sent))
        plant.step(command, sc.dt)
    assert differed > 10


def test_a_baseline_comes_with_its_own_settings_and_the_same_reference(builtin_scenario):
    sc = builtin_scenario
    baseline = IdentifiedLMPC(sc.reference, sc.vehicle, _identified())
    with pytest.raises(ParameterError, match="baseline"):
        ResidualKoopmanMPC(
            sc.reference, sc.vehicle, _kinematic_model(), lmpc_config=LMPCConfig(), baseline=baseline
        )
    other = IdentifiedLMPC(load_scenario("builtin").reference, sc.vehicle, _identified())
    with pytest.raises(ParameterError, match="same reference"):
        ResidualKoopmanMPC(sc.reference, sc.vehicle, _kinematic_model(), baseline=other)
