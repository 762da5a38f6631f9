"""rkmpc controllers driving the Gymnasium environment through the adapter, and data sets from it.

The environment integrates the same plant as the project's closed loop
(:func:`rkmpc.sim.closed_loop.simulate`): a 0.05 s command held for five 0.01 s steps is the same
fifty 1 ms RK4 substeps as one 0.05 s step, and the adapter hands the controller the observation the
closed loop would (float64 throughout). Only the rounding of the step boundaries differs, so the
runs agree to far below a millimetre (4e-12 m on a lap of the built-in track when written); the
tolerances below (1e-6 m on positions, 1e-6 relative on the mean lateral error, 1 ms on the lap
time, whose crossing is interpolated within a 0.01 s instead of a 0.05 s step) leave room for
another machine's floating point and would still catch a command held one step too long or short
(that moves the car by centimetres).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from rkmpc.control import make_controller
from rkmpc.control.base import Controller
from rkmpc.control.estimated import EstimatedController
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.envs.adapter import (
    ControllerPolicy,
    action_from_command,
    observation_from_f1tenth,
    run_episode,
)
from rkmpc.envs.f1tenth import F1TenthEnvConfig, F1TenthTrackEnv
from rkmpc.learning.data.augmentation import AugmentConfig, local_frame_windows
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.pipeline import TrainConfig, train_model, training_arrays
from rkmpc.sim.build import build_controller
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.run import RunSpec, drive
from rkmpc.sim.scenario import load_scenario


def _controller(scenario, name="lmpc", model=None):
    """The controller as every command builds it: the car's settings, the model checked."""
    return build_controller(name, scenario, model)


@pytest.fixture(scope="module")
def in_process(builtin_scenario):
    """One LMPC lap of the built-in track in the project's own closed loop."""
    return drive(builtin_scenario, RunSpec("lmpc"))


@pytest.fixture(scope="module", params=[0.01, 0.05], ids=["env-step-10ms", "env-step-50ms"])
def gym_lap(request, builtin_scenario):
    """The same lap in the environment, the LMPC driving through the adapter."""
    env = F1TenthTrackEnv(builtin_scenario, F1TenthEnvConfig(timestep=request.param, max_laps=1))
    policy = ControllerPolicy(_controller(builtin_scenario), env.timestep)
    return env, policy, run_episode(env, policy, seed=0)


def test_the_lmpc_drives_a_lap_in_the_env_as_in_the_closed_loop(builtin_scenario, in_process, gym_lap):
    env, policy, episode = gym_lap
    assert policy.hold_steps == round(0.05 / env.timestep)
    assert episode.truncated and not episode.terminated and episode.info["outcome"] == "max_laps"
    assert in_process.completed
    (lap,) = episode.info["completed_lap_times"]
    assert lap == pytest.approx(in_process.lap_times[0], abs=1e-3)
    # The controller's rows: one per control period, at the closed loop's instants and poses.
    log, ref = episode.log, in_process.log
    rows = len(ref)
    assert len(log) == rows + 1  # and the final observation
    np.testing.assert_allclose(log["t"][:rows], ref["t"], atol=1e-9)
    np.testing.assert_allclose(log["x"][:rows], ref["x"], atol=1e-6)
    np.testing.assert_allclose(log["y"][:rows], ref["y"], atol=1e-6)
    _, lateral = builtin_scenario.reference.path.project_many(np.column_stack([log["x"], log["y"]])[:rows])
    mean_env, mean_in = np.mean(np.abs(lateral)), np.mean(np.abs(ref["lateral_error"]))
    assert mean_env == pytest.approx(mean_in, rel=1e-6)
    assert mean_in < 0.05
    # The reward adds up to the lap.
    assert episode.total_reward == pytest.approx(builtin_scenario.reference.path.length, rel=1e-3)


def test_a_data_set_from_the_env_is_the_closed_loops_and_trains(builtin_scenario, in_process, gym_lap):
    env, _, episode = gym_lap
    data = episode.dataset(metadata={"controller": "lmpc"}, made_with=env.provenance())
    n = len(in_process.log)
    assert data.obs.shape == (n, 7) and data.command.shape == (n, 2) and data.next_obs.shape == (n, 7)
    assert data.dt == 0.05 and np.all(data.episode == 0)
    assert data.metadata["source"] == "gym" and data.metadata["controller"] == "lmpc"
    contract = data.contract
    assert (contract.vehicle, contract.dt, contract.scale) == ("f1tenth", 0.05, 1.0) and contract.recorded
    # The same transitions as the closed loop's own data (the in-process set ends one row earlier:
    # the closed loop stops at the line before commanding, the env after the step that crosses it).
    reference = TransitionDataset.from_log(in_process.log, dt=0.05)
    np.testing.assert_allclose(data.obs[: len(reference)], reference.obs, atol=1e-6)
    np.testing.assert_allclose(data.command[: len(reference)], reference.command, atol=1e-6)
    # It feeds the residual data builder and trains a (least-squares) residual model.
    windows = local_frame_windows(data, AugmentConfig(ratio=0.1, seed=0))
    X, U, _ = training_arrays(data, builtin_scenario.vehicle.wheelbase, "residual", windows)
    assert X.shape[0] == U.shape[0] == windows.n_windows and np.all(np.isfinite(X)) and np.all(np.isfinite(U))
    config = TrainConfig(kind="residual", augment=AugmentConfig(ratio=0.2, seed=0), model=KoopmanModel(None))
    model, report = train_model(data, builtin_scenario.vehicle.wheelbase, config, vehicle="f1tenth")
    assert report.raw_count == len(data) and np.all(np.isfinite(model.A_))


def test_pure_pursuit_and_the_residual_mpc_drive_through_the_adapter(builtin_scenario, small_paper_model):
    """Any controller: one that plans with no period (given one) and a learned one (steering measured)."""
    sc = builtin_scenario
    env = F1TenthTrackEnv(sc)
    for name, model in (("pp", None), ("rkmpc-paper", small_paper_model)):
        policy = ControllerPolicy(_controller(sc, name, model), env.timestep, control_period=sc.dt)
        episode = run_episode(env, policy, seed=0, max_steps=600)  # 6 s
        assert episode.steps == 600 and not episode.terminated
        config = SimConfig(dt=sc.dt, max_time=6.0)
        ref = simulate(sc.make_plant(), _controller(sc, name, model), sc.track, sc.reference, config)
        rows = len(episode.log) - 1
        np.testing.assert_allclose(episode.log["x"][:rows], ref.log["x"][:rows], atol=1e-6)
        np.testing.assert_allclose(episode.log["cmd_steer"][:rows], ref.log["cmd_steer"][:rows], atol=1e-6)


class _Counter(Controller):
    """Records what it is given; commands its step count as the speed."""

    name = "counter"
    dt = 0.05

    def __init__(self) -> None:
        super().__init__()
        self.seen: list[Observation] = []

    def _reset(self) -> None:
        self.seen = []

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        self.seen.append(observation)
        return Command(speed=float(len(self.seen)), steer=0.1), "ok", ""


def _obs(n=1, **values):
    base = {key: np.zeros(n) for key in ("poses_x", "poses_y", "poses_theta", "linear_vels_y", "ang_vels_z")}
    base["linear_vels_x"] = np.ones(n)
    base.update({k: np.asarray(v, dtype=float) for k, v in values.items()})
    return base


def test_the_policy_holds_each_command_for_a_control_period_and_stamps_its_own_time():
    controller = _Counter()
    policy = ControllerPolicy(controller, 0.01)
    policy.reset()
    actions = [policy(_obs(poses_x=[0.1 * k])) for k in range(12)]
    assert policy.hold_steps == 5
    assert [o.time for o in controller.seen] == pytest.approx([0.0, 0.05, 0.10])
    assert [o.x for o in controller.seen] == pytest.approx([0.0, 0.5, 1.0])
    assert [a[0, 1] for a in actions] == [1.0] * 5 + [2.0] * 5 + [3.0] * 2
    assert all(a.shape == (1, 2) and a[0, 0] == 0.1 for a in actions)
    policy.reset()
    assert controller.seen == [] and policy.time == 0.0


def test_the_policy_refuses_periods_it_cannot_hold():
    with pytest.raises(ParameterError, match="whole number of environment steps"):
        ControllerPolicy(_Counter(), 0.03)
    with pytest.raises(ParameterError, match="whole number"):
        ControllerPolicy(_Counter(), 0.1)
    sc = load_scenario("builtin")
    with pytest.raises(ParameterError, match="plans with no period; give control_period"):
        ControllerPolicy(make_controller("pp", sc.reference, sc.vehicle), 0.01)
    with pytest.raises(ParameterError, match="timestep"):
        ControllerPolicy(_Counter(), -0.01)
    policy = ControllerPolicy(_Counter(), 0.01)
    with pytest.raises(ParameterError, match="one agent's action; the observation has 2"):
        policy(_obs(2))
    assert policy.command(_obs(2)).speed == 1.0  # the ego of two agents, by command


def test_a_state_estimator_must_step_at_the_policys_period(builtin_scenario):
    """The estimator propagates the wheel angle one control period per step: another period is refused."""
    car = builtin_scenario.car.with_sensors("no-steer")
    controller = build_controller("lmpc", replace(builtin_scenario, car=car))
    assert isinstance(controller, EstimatedController)
    assert ControllerPolicy(controller, 0.01).control_period == 0.05
    with pytest.raises(ParameterError, match=r"propagates the wheel angle every 0.05 s, the policy .* 0.1 s"):
        ControllerPolicy(controller, 0.01, control_period=0.1)


def test_run_episode_hands_every_steps_info_to_on_step(builtin_scenario):
    env = F1TenthTrackEnv(builtin_scenario)
    seen = []
    episode = run_episode(
        env,
        ControllerPolicy(_controller(builtin_scenario), env.timestep),
        seed=0,
        max_steps=12,
        on_step=seen.append,
    )
    assert len(seen) == episode.steps == 12
    assert [info["time"] for info in seen] == pytest.approx(0.01 * np.arange(1, 13))
    assert seen[-1]["lateral_error"] == episode.info["lateral_error"]


def test_f1tenth_observations_convert_to_the_projects():
    obs = observation_from_f1tenth(
        _obs(
            2, poses_x=[1.0, 5.0], linear_vels_x=[2.0, 3.0], linear_vels_y=[0.0, 3.0], ang_vels_z=[0.0, 0.7]
        ),
        agent=1,
        time=0.35,
    )
    assert (obs.x, obs.speed, obs.yaw_rate, obs.time) == (5.0, 3.0, 0.7, 0.35)
    assert obs.slip_angle == pytest.approx(math.pi / 4)
    assert math.isnan(obs.steer_angle)  # not measured without "steering_angles"
    assert observation_from_f1tenth(_obs(steering_angles=[0.2])).steer_angle == 0.2
    with pytest.raises(ParameterError, match=r"lacks the F1TENTH keys \['poses_theta'\]"):
        observation_from_f1tenth({k: v for k, v in _obs().items() if k != "poses_theta"})
    with pytest.raises(ParameterError, match="agent 3 asked for"):
        observation_from_f1tenth(_obs(2), agent=3)
    with pytest.raises(ParameterError, match="must be finite"):
        observation_from_f1tenth(_obs(poses_y=[math.nan]))
    np.testing.assert_array_equal(action_from_command(Command(speed=2.0, steer=-0.1)), [[-0.1, 2.0]])


def test_an_episode_cut_mid_period_keeps_only_whole_periods(builtin_scenario):
    env = F1TenthTrackEnv(builtin_scenario)
    policy = ControllerPolicy(_controller(builtin_scenario), env.timestep)
    episode = run_episode(env, policy, seed=0, max_steps=23)  # 4 periods and 3 steps of a fifth
    assert len(episode.log) == 6 and episode.log["t"][-1] == pytest.approx(0.23)
    data = episode.dataset()
    assert len(data) == 4 and "contract" not in data.metadata
    with pytest.raises(ParameterError, match="max_steps"):
        run_episode(env, policy, max_steps=0)


@pytest.mark.slow
@pytest.mark.parametrize("car", ["gym", "overshoot"])
def test_a_zoo_car_drives_a_lap_in_the_env_as_in_the_closed_loop(car):
    """The zoo's actuators keep their own clocks (the gym servo's 10 ms ticks): env steps change nothing."""
    sc = load_scenario("builtin", car=car)
    ref = drive(sc, RunSpec("lmpc"))
    env = F1TenthTrackEnv(sc, F1TenthEnvConfig(max_laps=1))
    episode = run_episode(env, ControllerPolicy(_controller(sc), env.timestep), seed=0)
    assert ref.completed and episode.truncated
    assert episode.info["completed_lap_times"][0] == pytest.approx(ref.lap_times[0], abs=1e-3)
    rows = len(ref.log)
    _, lateral = sc.reference.path.project_many(np.column_stack([episode.log["x"], episode.log["y"]])[:rows])
    assert np.mean(np.abs(lateral)) == pytest.approx(np.mean(np.abs(ref.log["lateral_error"])), rel=1e-6)
