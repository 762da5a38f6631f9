"""The estimator in the loop: the LMPC drives the dynamic plant through a real car's sensors.

The sensors (``sensor_faults.RealSensors``): pose at 20-40 Hz, 30-60 ms late, 3 cm / 0.02 rad of
noise, 1 % of the poses jumping 0.36-1.2 m; speed 15 % too high with 5 cm/s of noise; yaw rate with
a 0.05 rad/s bias and 0.03 rad/s of noise; no wheel angle, no slip angle. Seeded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from sensor_faults import Faults, RealSensors

from rkmpc.control.estimated import EstimatedController
from rkmpc.control.registry import make_controller
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.estimation import EstimatorConfig, StateEstimator
from rkmpc.estimation.smoother import smooth_sequence
from rkmpc.sim.closed_loop import SimConfig, SimResult, simulate
from rkmpc.vehicle.registry import make_plant

SKIP = 40  # the first 2 s, while the sensor scale and the gyro bias settle


@dataclass
class Lap:
    result: SimResult
    plant: RealSensors
    estimates: np.ndarray
    raw: np.ndarray
    truth: np.ndarray
    controller: EstimatedController


def drive_lap(scenario, seed: int = 0) -> Lap:
    plant = RealSensors(make_plant("f1tenth"), Faults(), seed=seed)
    inner = make_controller("lmpc", scenario.reference, scenario.vehicle)
    controller = EstimatedController(
        inner, StateEstimator(scenario.vehicle, EstimatorConfig(control_period=scenario.dt))
    )
    estimates: list[np.ndarray] = []
    result = simulate(
        plant,
        controller,
        scenario.track,
        scenario.reference,
        SimConfig(dt=scenario.dt, laps=1),
        on_step=lambda t, p: estimates.append(controller.estimate.as_array()),
    )
    log = result.log
    n = len(estimates)
    raw = np.column_stack([log[c] for c in OBSERVATION_FIELDS])[:n]
    v, beta = log["state_v"], log["state_beta"]
    truth = np.column_stack(
        [
            log["state_x"],
            log["state_y"],
            log["state_yaw"],
            v * np.cos(beta),
            log["state_yaw_rate"],
            beta,
            log["wheel_angle"],
        ]
    )[:n]
    return Lap(result, plant, np.array(estimates), raw, truth, controller)


@pytest.fixture(scope="module")
def lap(builtin_scenario) -> Lap:
    return drive_lap(builtin_scenario)


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a[SKIP:] ** 2)))


def test_the_lap_is_driven_without_a_fall_back(lap):
    assert lap.result.completed
    assert lap.result.status_counts == {"ok": len(lap.result.log)}


def test_the_estimate_is_far_better_than_the_measurements(lap):
    est, raw, truth = lap.estimates, lap.raw, lap.truth
    position = (rms(np.hypot(*(est[:, :2] - truth[:, :2]).T)), rms(np.hypot(*(raw[:, :2] - truth[:, :2]).T)))
    assert position[0] < 0.03 and position[0] < 0.15 * position[1]  # measured: 0.018 m against 0.23 m
    assert rms(est[:, 2] - truth[:, 2]) < 0.3 * rms(raw[:, 2] - truth[:, 2])  # 0.013 against 0.055 rad
    assert rms(est[:, 3] - truth[:, 3]) < 0.15 * rms(raw[:, 3] - truth[:, 3])  # 0.043 against 0.48 m/s
    assert rms(est[:, 4] - truth[:, 4]) < 0.6 * rms(raw[:, 4] - truth[:, 4])  # 0.030 against 0.059 rad/s
    # The slip angle, never measured: better than taking it as 0 (0.012 against 0.023 rad).
    assert rms(est[:, 5] - truth[:, 5]) < 0.6 * rms(truth[:, 5])


def test_pose_jumps_are_rejected(lap):
    diagnostics = lap.result.diagnostics
    assert lap.plant.jumps >= 5 and diagnostics["estimator_poses_rejected"] >= 3
    assert diagnostics["estimator_pose_reinitialisations"] == 0
    error = np.hypot(*(lap.estimates[:, :2] - lap.truth[:, :2]).T)
    assert np.max(np.hypot(*(lap.raw[:, :2] - lap.truth[:, :2]).T)) > 0.5 and np.max(error[SKIP:]) < 0.08


def test_the_wheel_angle_follows_the_plants(lap):
    assert np.max(np.abs(lap.estimates[:, 6] - lap.truth[:, 6])) < 1e-6  # measured: 2.5e-12 rad


def test_the_sensor_estimates_are_the_injected_ones(lap):
    diagnostics = lap.result.diagnostics
    assert diagnostics["estimator_speed_scale"] == pytest.approx(Faults().speed_scale, abs=0.02)
    assert diagnostics["estimator_gyro_bias"] == pytest.approx(Faults().gyro_bias, abs=0.01)


def test_offline_the_filter_gives_the_same_estimates_and_the_smoother_better_ones(lap):
    delivered = lap.plant.delivered[: len(lap.estimates)]
    times = np.array([o.time for o in delivered])
    raw = np.array([o.as_array() for o in delivered])
    poses = np.array([o.pose_time for o in delivered])
    commands = np.column_stack([lap.result.log["cmd_speed"], lap.result.log["cmd_steer"]])[: len(raw)]
    vehicle, config = lap.controller.estimator.vehicle, lap.controller.estimator.config
    causal = smooth_sequence(times, raw, commands, vehicle, config=config, pose_times=poses, causal=True)
    np.testing.assert_array_equal(causal.observations, lap.estimates)
    smoothed = smooth_sequence(times, raw, commands, vehicle, config=config, pose_times=poses)
    position = [
        rms(np.hypot(*(o[:, :2] - lap.truth[:, :2]).T)) for o in (smoothed.observations, lap.estimates)
    ]
    assert position[0] < 0.85 * position[1]


@pytest.mark.slow
def test_without_the_estimator_the_lmpc_leaves_the_track(builtin_scenario, lap):
    sc = builtin_scenario
    plant = RealSensors(make_plant("f1tenth"), Faults(), seed=0)
    result = simulate(
        plant, make_controller("lmpc", sc.reference, sc.vehicle), sc.track, sc.reference, SimConfig(dt=sc.dt)
    )
    assert not result.completed and lap.result.completed
