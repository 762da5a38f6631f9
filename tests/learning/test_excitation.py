"""Random-excitation data of the f1tenth plant: settings, shapes, ranges, episodes, seeding."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.learning.data.excitation import ExcitationConfig, random_excitation
from rkmpc.vehicle.registry import make_plant

DT = 0.05
N = 300
COL = {name: i for i, name in enumerate(OBSERVATION_FIELDS)}


def _config(**overrides) -> ExcitationConfig:
    settings = {"n_samples": N, "episode_steps": 60, "seed": 3}
    settings.update(overrides)
    return ExcitationConfig(**settings)


def _run(config: ExcitationConfig):
    return random_excitation(make_plant("f1tenth"), config, dt=DT)


@pytest.fixture(scope="module")
def data():
    return _run(_config())


def _episode_starts(episode: np.ndarray) -> np.ndarray:
    return np.r_[0, np.flatnonzero(np.diff(episode)) + 1]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_samples": 0}, "n_samples"),
        ({"episode_steps": 1}, "episode_steps"),
        ({"speed_range": (-0.5, 2.0)}, "speed_range"),
        ({"speed_range": (2.0, 2.0)}, "speed_range"),
        ({"speed_range": (3.0, 1.0)}, "speed_range"),
        ({"steer_fraction": 0.0}, "steer_fraction"),
        ({"steer_fraction": 1.5}, "steer_fraction"),
        ({"hold_range": (0.0, 1.0)}, "hold_range"),
        ({"hold_range": (1.0, 0.5)}, "hold_range"),
        ({"smoothing": 0.0}, "smoothing"),
        ({"smoothing": math.nan}, "smoothing"),
    ],
)
def test_config_validation(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        ExcitationConfig(**kwargs)


def test_config_accepts_edge_values():
    cfg = ExcitationConfig(n_samples=1, episode_steps=2, speed_range=(0.0, 0.1), steer_fraction=1.0)
    assert cfg.hold_range[0] <= cfg.hold_range[1]
    ExcitationConfig(hold_range=(0.5, 0.5))


def test_shapes_and_dtypes(data):
    obs, command, next_obs, episode = data
    assert obs.shape == (N, len(OBSERVATION_FIELDS)) == (N, 7)
    assert next_obs.shape == (N, 7)
    assert command.shape == (N, 2)
    assert episode.shape == (N,)
    assert episode.dtype == np.int64
    for array in (obs, command, next_obs):
        assert array.dtype == np.float64
        assert np.isfinite(array).all()


def test_commands_stay_within_the_configured_ranges(data):
    cfg = _config()
    _, command, _, _ = data
    steer_max = cfg.steer_fraction * make_plant("f1tenth").params.steering.max_angle
    lo, hi = cfg.speed_range
    assert command[:, 0].min() >= lo and command[:, 0].max() <= hi
    assert np.abs(command[:, 1]).max() <= steer_max
    # The excitation uses a good part of the ranges, on both sides for the steering.
    assert command[:, 0].max() - command[:, 0].min() > 0.3 * (hi - lo)
    assert command[:, 1].min() < 0.0 < command[:, 1].max()


def test_narrow_ranges_are_respected():
    cfg = _config(n_samples=150, speed_range=(1.0, 1.5), steer_fraction=0.2, seed=11)
    _, command, _, _ = _run(cfg)
    steer_max = 0.2 * make_plant("f1tenth").params.steering.max_angle
    assert command[:, 0].min() >= 1.0 and command[:, 0].max() <= 1.5
    assert np.abs(command[:, 1]).max() <= steer_max


def test_commands_move_smoothly(data):
    cfg = _config()
    _, command, _, episode = data
    alpha = 1.0 - math.exp(-DT / cfg.smoothing)
    same = episode[1:] == episode[:-1]
    steer_max = cfg.steer_fraction * make_plant("f1tenth").params.steering.max_angle
    lo, hi = cfg.speed_range
    step = np.abs(np.diff(command, axis=0))[same]
    # One filter step moves by at most alpha times the widest distance to a target.
    assert (step[:, 0] <= alpha * (hi - lo) + 1e-12).all()
    assert (step[:, 1] <= alpha * 2 * steer_max + 1e-12).all()


def test_episodes_are_non_decreasing_and_chained(data):
    obs, _, next_obs, episode = data
    assert episode[0] == 0
    assert (np.diff(episode) >= 0).all()
    assert len(np.unique(episode)) >= 2  # 300 samples of 60-step episodes: several episodes
    same = episode[1:] == episode[:-1]
    assert_array_equal(next_obs[:-1][same], obs[1:][same])
    # Across an episode boundary the car is reset, so the chain breaks.
    assert not np.array_equal(next_obs[:-1][~same], obs[1:][~same])
    assert (np.bincount(episode)[np.unique(episode)] <= _config().episode_steps).all()


def test_columns_are_the_observation_fields(data):
    cfg = _config()
    obs, _, next_obs, episode = data
    steer_max = cfg.steer_fraction * make_plant("f1tenth").params.steering.max_angle
    starts = _episode_starts(episode)
    first = obs[starts]
    # Every episode starts at the origin with a random heading, a speed in range and half the steering.
    assert_array_equal(first[:, COL["x"]], 0.0)
    assert_array_equal(first[:, COL["y"]], 0.0)
    assert (np.abs(first[:, COL["yaw"]]) <= math.pi).all()
    assert len(np.unique(first[:, COL["yaw"]])) == len(starts)
    assert (first[:, COL["speed"]] >= cfg.speed_range[0]).all()
    assert (first[:, COL["speed"]] <= cfg.speed_range[1]).all()
    assert (np.abs(first[:, COL["steer_angle"]]) <= 0.5 * steer_max + 1e-12).all()
    # Kinematic consistency of the columns: x, y move along yaw at the speed, yaw at the yaw rate.
    speed, yaw = obs[:, COL["speed"]], obs[:, COL["yaw"]]
    dx = next_obs[:, COL["x"]] - obs[:, COL["x"]]
    dy = next_obs[:, COL["y"]] - obs[:, COL["y"]]
    assert np.abs(dx - DT * speed * np.cos(yaw)).max() < 0.03
    assert np.abs(dy - DT * speed * np.sin(yaw)).max() < 0.03
    dyaw = next_obs[:, COL["yaw"]] - obs[:, COL["yaw"]]
    assert np.abs(dyaw - DT * obs[:, COL["yaw_rate"]]).max() < 0.02
    assert (np.abs(next_obs[:, COL["slip_angle"]]) <= cfg.max_slip).all()
    assert (next_obs[:, COL["speed"]] >= 0.0).all()


def test_same_seed_same_data_other_seed_other_data(data):
    again = _run(_config())
    for a, b in zip(data, again, strict=True):
        assert_array_equal(a, b)
    other = _run(_config(seed=4))
    assert other[0].shape == data[0].shape
    assert not np.array_equal(other[0], data[0])
    assert not np.array_equal(other[1], data[1])


def test_reusing_the_plant_gives_the_same_data(data):
    plant = make_plant("f1tenth")
    random_excitation(plant, _config(n_samples=40, seed=9), dt=DT)
    reused = random_excitation(plant, _config(), dt=DT)
    for a, b in zip(data, reused, strict=True):
        assert_array_equal(a, b)


def test_exactly_n_samples_with_short_episodes():
    obs, command, next_obs, episode = _run(_config(n_samples=25, episode_steps=2, seed=5))
    assert len(obs) == len(command) == len(next_obs) == len(episode) == 25
    assert np.bincount(episode).max() <= 2
    assert episode[-1] >= 12
