"""The simulated car's physics clock (``rkmpc sim-node``), without ROS."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.control.registry import make_controller
from rkmpc.core.observation import Command
from rkmpc.ros.sim_config import SimNodeConfig
from rkmpc.ros.sim_plant import PhysicsPlant
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.vehicle.registry import make_plant
from rkmpc.vehicle.wrappers import CommandDelay


def drive(plant, commands, dt=0.05):
    plant.reset(0.0, 0.0, 0.0, 2.0, 0.05)
    states = []
    for command in commands:
        plant.step(command, dt)
        states.append(plant.state)
    return np.array(states)


COMMANDS = [Command(2.0 + 0.1 * k, 0.2 * np.sin(0.3 * k)) for k in range(40)]


def test_physics_steps_of_10_ms_drive_as_one_control_period():
    whole = drive(make_plant("f1tenth"), COMMANDS)
    split = drive(PhysicsPlant(make_plant("f1tenth"), physics_dt=0.01), COMMANDS)
    assert np.allclose(split, whole, rtol=0, atol=1e-9)


def test_an_actuation_delay_of_one_period_is_the_delay_fault():
    delayed = drive(PhysicsPlant(make_plant("f1tenth"), physics_dt=0.01, actuation_delay=0.05), COMMANDS)
    fault = drive(CommandDelay(make_plant("f1tenth"), 1), COMMANDS)
    assert np.allclose(delayed, fault, rtol=0, atol=1e-9)
    # A delay that is not a whole period acts in the middle of one.
    half = drive(PhysicsPlant(make_plant("f1tenth"), physics_dt=0.01, actuation_delay=0.02), COMMANDS)
    assert not np.allclose(half, delayed) and not np.allclose(half, fault)


def test_a_stop_from_outside_ends_the_run_with_its_log(builtin_scenario):
    sc = builtin_scenario
    reason: list[str] = []
    plant = PhysicsPlant(
        make_plant("f1tenth"), physics_dt=0.01, stop_reason=lambda: reason[0] if reason else None
    )
    controller = make_controller("pp", sc.reference, sc.vehicle)

    def on_step(t: float, progress: float) -> None:
        if t >= 1.0:
            reason.append("interrupted")

    result = simulate(plant, controller, sc.track, sc.reference, SimConfig(dt=0.05), on_step=on_step)
    assert result.outcome == "plant_failure" and result.failure == "interrupted"
    assert len(result.log) == 22  # the steps up to t = 1.0 s, and the one refused


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"clock": "sundial"}, "clock must be one of"),
        ({"laps": 0}, "laps must be an integer"),
        ({"period": 0.055}, "whole physics steps"),
        ({"actuation_delay": -0.01}, "actuation_delay"),
        ({"odometry_rate_hz": 200.0}, "must not exceed"),
        ({"startup_timeout": 0.0}, "startup_timeout"),
    ],
)
def test_sim_node_settings_are_checked(changes, words):
    with pytest.raises(ValueError, match=words):
        SimNodeConfig(**changes)
    assert SimNodeConfig().odometry_every == 2 and SimNodeConfig().physics_dt == 0.01
