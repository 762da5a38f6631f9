"""Data no model should be learned from are refused, naming the data set, the field and the rows."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.plausibility import check_learnable
from rkmpc.learning.features import RESIDUAL_STATE
from rkmpc.learning.pipeline import TrainConfig, train_model

DT = 0.05
L = 0.307  # wheelbase (m)


def _drive(n: int = 400, seed: int = 0, weave: float = 0.3) -> np.ndarray:
    """Observations of a kinematic car weaving at 2-4 m/s, shape (n + 1, 7)."""
    rng = np.random.default_rng(seed)
    t = DT * np.arange(n + 1)
    speed = 3.0 + np.sin(t / 3.0)
    steer = weave * np.sin(t / 1.3) + 0.01 * rng.standard_normal(n + 1)
    yaw_rate = speed * np.tan(steer) / L
    yaw = np.concatenate([[0.4], 0.4 + np.cumsum(yaw_rate[:-1] * DT)])
    x = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.cos(yaw[:-1]) * DT)])
    y = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.sin(yaw[:-1]) * DT)])
    return np.column_stack([x, y, yaw, speed, yaw_rate, np.zeros(n + 1), steer])


def _data(obs: np.ndarray, next_obs: np.ndarray | None = None) -> TransitionDataset:
    n = len(obs) - 1
    return TransitionDataset(
        obs=obs[:-1],
        command=np.column_stack([obs[:-1, 3], obs[:-1, 6]]),
        next_obs=obs[1:] if next_obs is None else next_obs,
        dt=DT,
        episode=np.zeros(n, dtype=int),
    )


def test_a_car_driving_passes():
    check_learnable(_data(_drive()), L, "laps.npz", RESIDUAL_STATE.names)


def test_a_car_that_stood_still_is_refused():
    obs = _drive()
    obs[:, 0:2] = obs[0, 0:2] + 1e-4 * np.random.default_rng(1).standard_normal((len(obs), 2))
    obs[:, 3] = 0.0
    with pytest.raises(InputFileError, match=r"laps\.npz \[obs\.x, obs\.y\]: the car travels .* stood still"):
        check_learnable(_data(obs), L, "laps.npz")


def test_shuffled_next_observations_are_refused_with_their_share():
    obs = _drive()
    shuffled = obs[1:][np.random.default_rng(2).permutation(len(obs) - 1)]
    with pytest.raises(InputFileError, match=r"\[next_obs\]: \d+ of 400 transitions \(\d+ %") as info:
        check_learnable(_data(obs, shuffled), L, "laps.npz")
    assert "shuffled" in info.value.problem


def test_yaw_in_degrees_under_100_is_refused():
    obs = _drive(n=200, weave=0.05)
    c, s = np.cos(-0.8), np.sin(-0.8)  # turn the frame so the heading stays within +-100 degrees
    obs[:, 0], obs[:, 1] = c * obs[:, 0] - s * obs[:, 1], s * obs[:, 0] + c * obs[:, 1]
    obs[:, 2] -= 0.8
    check_learnable(_data(obs), L, "laps.npz")
    obs[:, 2] = np.degrees(obs[:, 2])
    assert np.abs(obs[:, 2]).max() < 100.0  # the magnitude check lets it through
    TransitionDataset(obs[:-1], obs[:-1, 3:5], obs[1:], DT, np.zeros(len(obs) - 1, dtype=int))
    with pytest.raises(InputFileError, match=r"\[obs\.yaw\]: .*degrees"):
        check_learnable(_data(obs), L, "laps.npz")


def test_a_nan_feature_names_the_file_field_and_row():
    obs = _drive()
    obs[37, 4] = np.nan
    with pytest.raises(InputFileError, match=r"laps\.npz \[obs\.yaw_rate\]: 1 of 400 rows .* row 37"):
        check_learnable(_data(obs), L, "laps.npz", RESIDUAL_STATE.names)
    check_learnable(_data(obs), L, "laps.npz", ("x", "y", "yaw"))  # a model not reading it is fine


def test_training_refuses_before_fitting():
    obs = _drive()
    obs[:, 0:2] = 0.0
    obs[:, 3] = 0.0
    with pytest.raises(InputFileError, match="stood still"):
        train_model(_data(obs), L, TrainConfig(kind="residual"), source="laps.npz")


def test_learning_runs_on_one_blas_thread_and_restores_it(monkeypatch):
    """A threaded BLAS sums in a core-dependent order: every model is learned on one thread."""
    threadpoolctl = pytest.importorskip("threadpoolctl")
    from rkmpc.learning import learn as learn_module
    from rkmpc.learning.contract import Provenance
    from rkmpc.learning.recipes import recipe_for
    from rkmpc.vehicle.params import f1tenth

    def blas_threads() -> set[int]:
        return {i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"}

    seen: list[set[int]] = []

    def spy(data, vehicle):
        seen.append(blas_threads())
        raise RuntimeError("stop after the check")

    before = blas_threads()
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        monkeypatch.setattr(learn_module, "identify", spy)
        recipe = recipe_for("lmpc-id")
        assert recipe is not None
        with pytest.raises(RuntimeError, match="stop after"):
            learn_module.learn(
                recipe, _data(_drive()), made_for=Provenance(dt=DT, wheelbase=L), vehicle=f1tenth()
            )
        inside = blas_threads()
    assert seen == [{1}]
    assert inside == {2} or inside == before  # the caller's setting is back (a 1-core BLAS stays at 1)
