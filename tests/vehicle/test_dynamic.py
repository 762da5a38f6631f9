"""Tests of the 1:10 dynamic single-track plant."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import fsolve

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command
from rkmpc.vehicle.friction import CircularRegion, FrictionChange
from rkmpc.vehicle.kinematic import kinematic_step
from rkmpc.vehicle.params import VehicleParams, f1tenth
from rkmpc.vehicle.plants.dynamic import DynamicPlant

P = f1tenth()
L = P.wheelbase


def magic(alpha: float, fz: float, b: float, c: float, d: float, e: float, mu: float) -> float:
    """The magic formula, written out independently of the package."""
    return mu * fz * d * math.sin(c * math.atan(b * alpha - e * (b * alpha - math.atan(b * alpha))))


def axle_forces(
    p: VehicleParams, v: float, beta: float, r: float, delta: float, mu: float
) -> tuple[float, float]:
    """Front and rear lateral forces at zero longitudinal acceleration."""
    fz_f = p.mass * p.gravity * p.lr / p.wheelbase
    fz_r = p.mass * p.gravity * p.lf / p.wheelbase
    alpha_f = delta - math.atan((v * math.sin(beta) + p.lf * r) / (v * math.cos(beta)))
    alpha_r = -math.atan((v * math.sin(beta) - p.lr * r) / (v * math.cos(beta)))
    tf, tr = p.tyre_front, p.tyre_rear
    return magic(alpha_f, fz_f, tf.B, tf.C, tf.D, tf.E, mu), magic(alpha_r, fz_r, tr.B, tr.C, tr.D, tr.E, mu)


def run_steady(plant: DynamicPlant, speed: float, steer: float, duration: float = 8.0) -> np.ndarray:
    plant.reset(0.0, 0.0, 0.0, speed, 0.0)
    command = Command(speed, steer)
    for _ in range(round(duration / 0.05)):
        plant.step(command, 0.05)
    return plant.state


def test_state_names_and_observation() -> None:
    plant = DynamicPlant()
    plant.reset(1.0, 2.0, 0.3, 2.0, 0.1)
    assert plant.STATE_NAMES == ("x", "y", "yaw", "v", "beta", "yaw_rate", "delta")
    state = plant.state
    assert state.shape == (7,)
    obs = plant.observe()
    assert (obs.x, obs.y, obs.yaw, obs.steer_angle) == (1.0, 2.0, 0.3, 0.1)
    assert obs.slip_angle == pytest.approx(math.atan(P.lr / L * math.tan(0.1)))
    assert obs.speed == pytest.approx(2.0 * math.cos(obs.slip_angle))
    assert plant.wheel_angle == 0.1
    state[0] = 99.0
    assert plant.state[0] == 1.0  # state is a copy


def test_steady_state_cornering_satisfies_single_track_equations() -> None:
    speed, steer = 3.0, 0.1
    plant = DynamicPlant()
    _, _, _, v, beta, r, delta = run_steady(plant, speed, steer)
    assert v == pytest.approx(speed, abs=1e-9)
    assert delta == pytest.approx(steer, abs=1e-9)
    fy_f, fy_r = axle_forces(P, v, beta, r, delta, P.mu)
    # Lateral force balance normal to the path and yaw moment balance.
    lateral = fy_f * math.cos(delta - beta) + fy_r * math.cos(beta)
    assert lateral == pytest.approx(P.mass * v * r, rel=1e-7)
    assert P.lf * fy_f * math.cos(delta) == pytest.approx(P.lr * fy_r, rel=1e-7)

    # The same steady state solved by hand from these equations.
    def residual(z: np.ndarray) -> list[float]:
        f, rr = axle_forces(P, speed, z[0], z[1], steer, P.mu)
        return [
            f * math.cos(steer - z[0]) + rr * math.cos(z[0]) - P.mass * speed * z[1],
            P.lf * f * math.cos(steer) - P.lr * rr,
        ]

    beta_ss, r_ss = fsolve(residual, [0.0, speed * math.tan(steer) / L], xtol=1e-13)
    assert beta == pytest.approx(beta_ss, abs=1e-8)
    assert r == pytest.approx(r_ss, rel=1e-8)


def test_understeer_matches_hand_gradient() -> None:
    # Linear tyres: C = mu * Fz * B*C*D per axle; K_us = m/L * (lr/C_f - lf/C_r) > 0: understeer.
    c_f = P.mu * P.mass * P.gravity * P.lr / L * P.tyre_front.cornering_stiffness_per_load
    c_r = P.mu * P.mass * P.gravity * P.lf / L * P.tyre_rear.cornering_stiffness_per_load
    k_us = P.mass / L * (P.lr / c_f - P.lf / c_r)
    assert k_us > 0.0
    plant = DynamicPlant()
    for speed, steer in [(2.0, 0.05), (3.0, 0.1)]:
        state = run_steady(plant, speed, steer)
        v, r = state[3], state[5]
        radius = v / r
        kinematic_radius = math.hypot(P.lr, L / math.tan(steer))
        assert radius > 1.05 * kinematic_radius  # understeer: wider than the kinematic circle
        lateral_acc = v * r
        measured = (steer - math.atan(L / math.sqrt(radius**2 - P.lr**2))) / lateral_acc
        assert measured == pytest.approx(k_us, rel=0.1)


def test_low_speed_matches_kinematic_model() -> None:
    plant = DynamicPlant()
    speed, steer = 0.3, 0.3
    plant.reset(0.0, 0.0, 0.0, speed, steer)
    beta_k = math.atan(P.lr / L * math.tan(steer))
    for _ in range(20):
        plant.step(Command(speed, steer), 0.05)
    x, y, yaw, v, beta, r, _ = plant.state
    assert beta == pytest.approx(beta_k, abs=1e-12)
    assert r == pytest.approx(v * math.cos(beta_k) * math.tan(steer) / L, rel=1e-12)
    # The paper's model drives the rear axle at the rear-axle speed v cos(beta).
    rear = np.array([x - P.lr * math.cos(yaw), y - P.lr * math.sin(yaw), yaw])
    predicted = kinematic_step(rear, [v * math.cos(beta), steer], L, 2.0)
    for _ in range(40):
        plant.step(Command(speed, steer), 0.05)
    x, y, yaw = plant.state[:3]
    np.testing.assert_allclose(
        [x - P.lr * math.cos(yaw), y - P.lr * math.sin(yaw), yaw], predicted, atol=1e-9
    )


def test_starts_smoothly_from_standstill() -> None:
    plant = DynamicPlant()
    plant.reset(0.0, 0.0, 0.0, 0.0, 0.0)
    plant.step(Command(0.0, 0.3), 0.5)
    assert plant.state[2] == 0.0  # no yaw while standing
    yaw_rates = []
    for _ in range(100):
        plant.step(Command(2.0, 0.3), 0.05)
        yaw_rates.append(plant.state[5])
    assert np.all(np.isfinite(plant.state))
    assert plant.state[3] == pytest.approx(2.0, abs=1e-3)
    # The yaw rate grows with speed but without kinks through the blending band (0.5-1 m/s).
    assert np.max(np.abs(np.diff(yaw_rates, 2))) < 0.05


def test_servo_first_order_lag() -> None:
    plant = DynamicPlant()
    plant.reset(0.0, 0.0, 0.0, 2.0, 0.0)
    target = 0.1  # initial rate target/tau = 0.63 rad/s, below the rate limit
    tau = P.steering.time_constant
    times, angles = [0.0], [0.0]
    for _ in range(400):
        plant.step(Command(2.0, target), 1e-3)
        times.append(plant.time)
        angles.append(plant.wheel_angle)
    crossing = float(np.interp(target * (1 - math.exp(-1)), angles, times))
    assert crossing == pytest.approx(tau, abs=1e-3)


def test_servo_rate_and_angle_limits() -> None:
    plant = DynamicPlant()
    plant.reset(0.0, 0.0, 0.0, 2.0, -P.steering.max_angle)
    angles = [plant.wheel_angle]
    for _ in range(1500):
        plant.step(Command(2.0, 5.0), 1e-3)
        angles.append(plant.wheel_angle)
    rates = np.diff(angles) / 1e-3
    assert np.max(rates) == pytest.approx(P.steering.max_rate, rel=1e-6)
    assert max(angles) <= P.steering.max_angle + 1e-12
    assert angles[-1] == pytest.approx(P.steering.max_angle, abs=1e-3)


def test_speed_loop_limits() -> None:
    plant = DynamicPlant()
    plant.reset(0.0, 0.0, 0.0, 0.0)
    plant.step(Command(50.0, 0.0), 0.1)
    assert plant.state[3] == pytest.approx(P.drive.max_accel * 0.1, rel=1e-9)
    for _ in range(100):
        plant.step(Command(50.0, 0.0), 0.05)
    top = plant.state[3]
    assert top == pytest.approx(P.drive.max_speed, abs=1e-6)  # top speed
    plant.step(Command(-3.0, 0.0), 0.1)
    assert plant.state[3] == pytest.approx(top - P.drive.max_brake * 0.1, rel=1e-12)
    speeds = []
    for _ in range(100):
        plant.step(Command(-3.0, 0.0), 0.05)
        speeds.append(plant.state[3])
    assert min(speeds) >= 0.0
    assert speeds[-1] == pytest.approx(0.0, abs=1e-6)
    # Between the limits the loop is a first-order lag.
    plant.reset(0.0, 0.0, 0.0, 2.0)
    plant.step(Command(2.2, 0.0), P.drive.time_constant)
    assert plant.state[3] == pytest.approx(2.0 + 0.2 * (1 - math.exp(-1)), rel=1e-9)


def commanded_profile(k: int) -> Command:
    return Command(2.0 + 0.5 * math.sin(0.3 * k), 0.2 * math.sin(0.2 * k))


def test_input_delay_multiple_of_period_shifts_response() -> None:
    immediate = DynamicPlant()
    delayed = DynamicPlant(input_delay=0.1)
    for plant in (immediate, delayed):
        plant.reset(0.0, 0.0, 0.0, 2.0)
    history = []
    for k in range(60):
        immediate.step(commanded_profile(k), 0.05)
        delayed.step(commanded_profile(k), 0.05)
        history.append(immediate.state)
        if k >= 2:
            # delayed at t_k matches immediate at t_{k-2}, for the states that do not integrate position
            np.testing.assert_allclose(delayed.state[3:], history[k - 2][3:], atol=1e-12)


def test_input_delay_inside_a_period_is_exact() -> None:
    delay = 0.03
    delayed = DynamicPlant(input_delay=delay)
    fine = DynamicPlant()
    for plant in (delayed, fine):
        plant.reset(0.0, 0.0, 0.0, 2.0)
    previous = Command(2.0, 0.0)
    for k in range(30):
        command = commanded_profile(k)
        delayed.step(command, 0.05)
        # the same input seen directly: old command for 30 ms, then the new one for 20 ms
        for _ in range(3):
            fine.step(previous, 0.01)
        for _ in range(2):
            fine.step(command, 0.01)
        previous = command
        np.testing.assert_allclose(delayed.state, fine.state, atol=1e-9)


def test_friction_drop_increases_understeer_and_slip() -> None:
    speed, steer = 4.0, 0.1
    nominal = run_steady(DynamicPlant(), speed, steer)
    slippery = run_steady(DynamicPlant(friction=FrictionChange(0.6)), speed, steer)
    assert slippery[3] / slippery[5] > 1.05 * nominal[3] / nominal[5]  # wider circle
    front_slip = [
        steer - math.atan((s[3] * math.sin(s[4]) + P.lf * s[5]) / (s[3] * math.cos(s[4])))
        for s in (nominal, slippery)
    ]
    assert front_slip[1] > front_slip[0] > 0.0
    # A patch the car never reaches, or a window already over, changes nothing.
    far = FrictionChange(0.3, region=CircularRegion(center=(100.0, 100.0), radius=1.0))
    past = FrictionChange(0.3, start_time=-2.0, end_time=-1.0)
    for schedule in (far, past):
        np.testing.assert_array_equal(run_steady(DynamicPlant(friction=schedule), speed, steer), nominal)


def test_friction_change_window() -> None:
    change = FrictionChange(0.5, start_time=1.0, end_time=2.0, region=CircularRegion((0.0, 0.0), 2.0))
    assert change(0.5, 0.0, 0.0) == 1.0
    assert change(1.0, 1.0, 1.0) == 0.5
    assert change(1.5, 3.0, 0.0) == 1.0
    assert change(2.0, 0.0, 0.0) == 1.0
    with pytest.raises(ParameterError):
        FrictionChange(0.0)
    with pytest.raises(ParameterError):
        FrictionChange(0.5, start_time=2.0, end_time=1.0)


def drive_sine(plant: DynamicPlant, duration: float = 3.0) -> np.ndarray:
    plant.reset(0.0, 0.0, 0.0, 3.0)
    for k in range(round(duration / 0.05)):
        plant.step(Command(3.0 + math.sin(0.5 * k), 0.3 * math.sin(0.15 * k)), 0.05)
    return plant.state


def test_internal_step_independence() -> None:
    reference = drive_sine(DynamicPlant(internal_dt=1e-3))
    np.testing.assert_allclose(drive_sine(DynamicPlant(internal_dt=5e-4)), reference, atol=1e-6)
    # A step that does not divide the period (last substep shorter) still agrees.
    np.testing.assert_allclose(drive_sine(DynamicPlant(internal_dt=3e-3)), reference, atol=1e-4)


def test_bad_arguments_raise() -> None:
    with pytest.raises(ParameterError):
        DynamicPlant(internal_dt=0.0)
    with pytest.raises(ParameterError):
        DynamicPlant(input_delay=-0.1)
    plant = DynamicPlant()
    with pytest.raises(ValueError, match="speed"):
        plant.reset(0.0, 0.0, 0.0, -1.0)
    with pytest.raises(ValueError, match="steer"):
        plant.reset(0.0, 0.0, 0.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="dt"):
        plant.step(Command(1.0, 0.0), 0.0)
    with pytest.raises(ValueError, match="finite"):
        plant.step(Command(math.nan, 0.0), 0.05)
