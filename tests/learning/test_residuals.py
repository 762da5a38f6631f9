import math

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.residuals import control_residuals, kinematic_inverse
from rkmpc.vehicle.kinematic import kinematic_step
from rkmpc.vehicle.registry import make_plant

WHEELBASE = 0.307
DT = 0.05


def wrap(a):
    return math.pi - (math.pi - a) % (2 * math.pi)


def kinematic_dataset(n=400, seed=1, wheelbase=WHEELBASE, dt=DT):
    """A trajectory of the exact kinematic model under random inputs; yaw stored wrapped."""
    rng = np.random.default_rng(seed)
    speeds = rng.uniform(0.5, 5.0, n)
    steers = rng.uniform(-0.41, 0.41, n)
    state = np.array([1.0, -2.0, 3.0])
    obs = np.full((n, 7), np.nan)
    next_obs = np.full((n, 7), np.nan)
    for k in range(n):
        new = kinematic_step(state, (speeds[k], steers[k]), wheelbase, dt)
        obs[k, :4] = (state[0], state[1], wrap(state[2]), speeds[k])
        next_obs[k, :4] = (new[0], new[1], wrap(new[2]), speeds[k])
        state = new
    command = np.stack([speeds, steers], axis=1)
    return TransitionDataset(obs, command, next_obs, dt, np.zeros(n, dtype=np.int64))


def test_residuals_vanish_on_the_nominal_model():
    data = kinematic_dataset()
    labels = control_residuals(data, WHEELBASE)
    np.testing.assert_allclose(labels.nominal, data.command, atol=1e-9, rtol=0)
    np.testing.assert_allclose(labels.delta, 0.0, atol=1e-9)
    np.testing.assert_array_equal(labels.applied, data.command)
    np.testing.assert_allclose(labels.direction_error, 0.0, atol=1e-9)
    # The stored headings jump at +-pi; the inverse does not care about the branch.
    assert np.any(np.abs(data.next_obs[:, 2] - data.obs[:, 2]) > math.pi)


def test_inverse_straight_line_backwards_and_standstill():
    pose = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 0.5], [2.0, 1.0, -1.0]])
    fwd = kinematic_step(pose[0], (2.0, 0.0), WHEELBASE, DT)
    back = kinematic_step(pose[1], (-1.5, 0.3), WHEELBASE, DT)
    nxt = np.stack([fwd, back, pose[2]])
    u = kinematic_inverse(pose, nxt, WHEELBASE, DT)
    np.testing.assert_allclose(u[0], [2.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(u[1], [-1.5, 0.3], atol=1e-9)
    np.testing.assert_array_equal(u[2], [0.0, 0.0])


def test_inverse_rejects_bad_parameters():
    pose = np.zeros((1, 3))
    with pytest.raises(ParameterError, match="wheelbase"):
        kinematic_inverse(pose, pose, 0.0, DT)
    with pytest.raises(ParameterError, match="dt"):
        kinematic_inverse(pose, pose, WHEELBASE, -1.0)
    with pytest.raises(ValueError, match="shape"):
        kinematic_inverse(np.zeros((2, 3)), np.zeros((3, 3)), WHEELBASE, DT)


def constant_steer_corner(speed, steer, steps=60, settle=20):
    """Residual labels of the f1tenth plant holding ``(speed, steer)``, after it settles."""
    plant = make_plant("f1tenth")
    plant.reset(0.0, 0.0, 0.0, speed, steer)
    command = Command(speed, steer)
    rows = []
    for _ in range(steps):
        before = plant.observe().as_array()
        plant.step(command, DT)
        rows.append((before, plant.observe().as_array()))
    obs = np.array([r[0] for r in rows])[settle:]
    next_obs = np.array([r[1] for r in rows])[settle:]
    n = len(obs)
    data = TransitionDataset(obs, np.tile([speed, steer], (n, 1)), next_obs, DT, np.zeros(n, dtype=int))
    return data, control_residuals(data, plant.params.wheelbase)


def test_dynamic_car_understeers_in_a_constant_steer_corner():
    speed, steer = 3.0, 0.15
    data, labels = constant_steer_corner(speed, steer)
    delta_p = float(np.mean(labels.nominal[:, 1]))
    # The car turns less than the kinematic model would with the same wheel angle
    # (measured: delta_p = 0.118 rad for delta = 0.15 rad) ...
    assert 0.0 < delta_p < steer - 0.02
    # ... so the steering residual dU = delta - delta_p is positive.
    assert np.all(labels.delta[:, 1] > 0.0)
    assert float(np.mean(labels.delta[:, 1])) == pytest.approx(steer - delta_p)
    # The speed loop has settled: no speed residual.
    np.testing.assert_allclose(labels.delta[:, 0], 0.0, atol=1e-3)
    # The displacement leaves the kinematic chord by the body side-slip angle.
    np.testing.assert_allclose(labels.direction_error, data.obs[:, 5], atol=2e-3)
    # Understeer grows with speed: at 1 m/s the car is almost kinematic.
    _, slow = constant_steer_corner(1.0, steer)
    assert delta_p < float(np.mean(slow.nominal[:, 1])) < steer
