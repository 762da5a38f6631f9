"""benchmarks/plan_linearisation.py: the LMPC linearised about its previous plan, with the affine term."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.core.observation import Observation
from rkmpc.vehicle.kinematic import kinematic_rhs


@pytest.fixture
def script(benchmark_script):
    return benchmark_script("plan_linearisation")


def test_the_prediction_reproduces_the_plan_it_is_linearised_about(script, builtin_scenario):
    sc = builtin_scenario
    mpc = script.PlanLinearisedLMPC(sc.reference, sc.vehicle)
    n, T, L = mpc.config.horizon, mpc.config.dt, sc.vehicle.wheelbase
    ref = sc.reference.horizon(3.0, n, T)
    u_ref = np.column_stack([ref.v[:n], ref.delta[:n]])
    observation = Observation(x=ref.x[0] + 0.05, y=ref.y[0] - 0.03, yaw=ref.theta[0] + 0.04, speed=ref.v[0])
    # Before any plan: the LMPC's own prediction along the reference.
    xi0, Phi, Gamma = mpc._prediction(observation, ref, u_ref)
    assert xi0.shape == (3,) and Phi.shape == (3 * n, 3)
    # With a plan: driving the shifted plan, the prediction is that plan's forward-Euler roll-out.
    rng = np.random.default_rng(0)
    mpc.last_plan = u_ref + rng.normal(0.0, [0.2, 0.05], size=(n, 2))
    xi0, Phi, Gamma = mpc._prediction(observation, ref, u_ref)
    u_bar = np.vstack([mpc.last_plan[1:], mpc.last_plan[-1:]])
    state = np.array([observation.x, observation.y, ref.theta[0] + xi0[2]])
    rolled = []
    for k in range(n):
        state = state + T * kinematic_rhs(state, u_bar[k], L)
        rolled.append(state)
    expected = np.array(rolled) - np.column_stack([ref.x[1 : n + 1], ref.y[1 : n + 1], ref.theta[1 : n + 1]])
    predicted = (Phi @ xi0 + Gamma @ (u_bar - u_ref).ravel()).reshape(n, 3)
    np.testing.assert_allclose(predicted, expected, atol=1e-9)
