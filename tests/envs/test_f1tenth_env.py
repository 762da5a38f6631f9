"""The Gymnasium environment: Gymnasium's own checker, seeding, spaces, bad actions, episode ends."""

from __future__ import annotations

import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

from rkmpc.core.errors import ParameterError  # noqa: E402
from rkmpc.envs.f1tenth import (  # noqa: E402
    AGENT_KEYS,
    ENV_ID,
    STEERING_KEY,
    F1TenthEnvConfig,
    F1TenthTrackEnv,
)
from rkmpc.vehicle.wrappers import NoiseStd  # noqa: E402


@pytest.fixture(scope="module")
def env(builtin_scenario):
    return F1TenthTrackEnv(builtin_scenario)


def _straight(env, speed=2.0):
    """The action that drives straight at ``speed`` (m/s)."""
    return np.array([[0.0, speed]])


@pytest.mark.parametrize(
    "config",
    [F1TenthEnvConfig(), F1TenthEnvConfig(timestep=0.05, measured_steering=False, random_start=True)],
    ids=["f1tenth-step", "controller-step"],
)
def test_gymnasiums_checker_passes_without_a_warning(builtin_scenario, config):
    """``check_env`` on the unwrapped environment made by ``gymnasium.make`` (it has a spec, so the
    close and render checks run too); any warning of the checker fails the test."""
    made = gym.make(ENV_ID, scenario=builtin_scenario, config=config)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(made.unwrapped)
    made.close()


def test_the_spaces_follow_the_f1tenth_gym_and_hold_every_observation(env):
    space = env.observation_space
    assert set(space.spaces) == {"ego_idx", *AGENT_KEYS, STEERING_KEY}
    assert all(space[key].shape == (1,) and space[key].dtype == np.float64 for key in AGENT_KEYS)
    assert env.action_space.shape == (1, 2) and env.action_space.dtype == np.float64
    steer_limit = env.scenario.vehicle.steering.max_angle
    assert env.action_space.low[0, 0] == -steer_limit and env.action_space.high[0, 0] == steer_limit
    obs, info = env.reset(seed=0)
    assert obs in space
    for _ in range(300):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert obs in space
        assert isinstance(reward, float) and math.isfinite(reward)
        if terminated or truncated:
            break
    assert set(info) >= {"time", "lateral_error", "heading_error", "track_margin", "outcome"}


def test_without_measured_steering_the_observation_has_the_f1tenth_keys_only(builtin_scenario):
    env = F1TenthTrackEnv(builtin_scenario, F1TenthEnvConfig(measured_steering=False))
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"ego_idx", *AGENT_KEYS} == set(env.observation_space.spaces)


def test_the_same_seed_gives_the_same_episode_and_another_seed_another(builtin_scenario):
    """With odometry noise and a random start, everything random comes from ``reset(seed=...)``."""
    config = F1TenthEnvConfig(random_start=True, noise=NoiseStd(position=0.01, yaw=0.01, speed=0.05))
    env = F1TenthTrackEnv(builtin_scenario, config)

    def episode(seed):
        obs, _ = env.reset(seed=seed)
        rows = [np.concatenate([obs[k] for k in AGENT_KEYS])]
        for _ in range(30):
            obs, *_ = env.step(_straight(env, 1.0))
            rows.append(np.concatenate([obs[k] for k in AGENT_KEYS]))
        return np.array(rows)

    first, again, other = episode(7), episode(7), episode(8)
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first[0, :2], other[0, :2])  # another start
    # The noise is there: the observed pose jitters around the true one.
    clean = F1TenthTrackEnv(builtin_scenario, F1TenthEnvConfig(random_start=True))
    obs, _ = clean.reset(seed=7)
    assert obs["poses_x"][0] == pytest.approx(first[0, 0], abs=0.05) and obs["poses_x"][0] != first[0, 0]


def test_reset_options_place_the_car(env, builtin_scenario):
    path = builtin_scenario.reference.path
    x, y = path.position(20.0)
    obs, info = env.reset(options={"poses": np.array([[x, y, path.heading(20.0)]])})
    assert (obs["poses_x"][0], obs["poses_y"][0]) == (x, y)
    assert info["s"] == pytest.approx(20.0, abs=1e-6)
    obs, info = env.reset(options={"start_s": 30.0})
    assert info["s"] == pytest.approx(30.0, abs=1e-6)
    assert obs["linear_vels_x"][0] == pytest.approx(builtin_scenario.reference.profile.speed(30.0))
    standstill = F1TenthTrackEnv(builtin_scenario, F1TenthEnvConfig(flying_start=False))
    obs, _ = standstill.reset()
    assert obs["linear_vels_x"][0] == 0.0 and obs[STEERING_KEY][0] == 0.0
    with pytest.raises(ParameterError, match="options may hold one of"):
        env.reset(options={"pose": np.zeros((1, 3))})
    with pytest.raises(ParameterError, match=r"shape \(1, 3\)"):
        env.reset(options={"poses": np.zeros((2, 3))})
    for bad in (math.nan, "far"):
        with pytest.raises(ParameterError, match="start_s'] must be a finite number"):
            env.reset(options={"start_s": bad})
    with pytest.raises(ParameterError, match="options may hold one of"):
        env.reset(options={"start_s": 1.0, "poses": np.zeros((1, 3))})


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (np.array([0.0, 1.0]), r"shape \(num_agents, 2\) = \(1, 2\).*got shape \(2,\)"),
        (np.zeros((2, 2)), r"got shape \(2, 2\)"),
        (np.array([[math.nan, 1.0]]), "must be finite"),
        (np.array([[0.0, math.inf]]), "must be finite"),
        ("fast", "must be numeric"),
    ],
    ids=["flat", "two-agents", "nan", "inf", "text"],
)
def test_bad_actions_raise_a_clear_error(env, action, message):
    env.reset(seed=0)
    with pytest.raises(ParameterError, match=message):
        env.step(action)


def test_actions_outside_the_space_are_clipped_to_it(builtin_scenario):
    """The car's own limits: an action beyond them drives like the action at them."""
    env = F1TenthTrackEnv(builtin_scenario)
    limit = env.action_space.high
    results = []
    for action in (np.array([[5.0, 99.0]]), limit.copy()):
        env.reset(seed=0)
        for _ in range(20):
            obs, *_ = env.step(action)
        results.append(np.concatenate([obs[k] for k in AGENT_KEYS]))
    np.testing.assert_array_equal(results[0], results[1])


def test_step_before_reset_needs_a_reset(builtin_scenario):
    with pytest.raises(gym.error.ResetNeeded):
        F1TenthTrackEnv(builtin_scenario).step(np.zeros((1, 2)))


def test_rendering_is_refused(builtin_scenario):
    with pytest.raises(ParameterError, match="render_mode must be None"):
        F1TenthTrackEnv(builtin_scenario, render_mode="human")


def test_leaving_the_track_terminates_with_a_collision(env):
    """Full lock at speed leaves the 1.6 m wide track: terminated, ``collisions`` 1, no truncation."""
    env.reset(seed=0)
    total = 0.0
    for _ in range(1000):
        obs, reward, terminated, truncated, info = env.step(np.array([[0.4, 3.0]]))
        total += reward
        if terminated or truncated:
            break
    assert terminated and not truncated
    assert obs["collisions"][0] == 1.0 and info["outcome"] == "off_track" and info["track_margin"] < 0.0
    # The reward is the progress along the path (m).
    assert total == pytest.approx(info["progress_laps"] * env.scenario.reference.path.length)


def test_the_time_limit_is_gymnasiums_wrapper(builtin_scenario):
    made = gym.make(ENV_ID, scenario=builtin_scenario, max_episode_steps=25)
    made.reset(seed=0)
    for step in range(25):
        obs, reward, terminated, truncated, _ = made.step(np.array([[0.0, 3.0]]))
        assert not terminated
        assert truncated == (step == 24)
    assert obs["lap_times"][0] == pytest.approx(0.25)
    assert reward > 0.0


def test_the_configuration_is_validated():
    with pytest.raises(ParameterError, match="timestep"):
        F1TenthEnvConfig(timestep=0.0)
    with pytest.raises(ParameterError, match="max_laps"):
        F1TenthEnvConfig(max_laps=0)
    with pytest.raises(ParameterError, match="start_s"):
        F1TenthEnvConfig(start_s=math.inf)


def test_the_core_package_and_the_adapter_do_not_need_gymnasium():
    code = (
        "import sys, rkmpc, rkmpc.sim.closed_loop, rkmpc.envs, rkmpc.envs.adapter\n"
        "print('gymnasium' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
