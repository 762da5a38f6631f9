"""One feature map feeds a model in training and on the car: the inputs agree bit for bit.

For every Koopman recipe, the state a model is trained on at the first sample of each
local-frame window (the car at the window's origin) must be exactly what the controller
lifts when it sees the same observation. The controllers' calls of ``model.lift`` are
recorded and compared with the training arrays with ``np.array_equal``.
"""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.control import make_controller
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS, Observation
from rkmpc.learning.data.augmentation import AugmentConfig, local_frame_windows
from rkmpc.learning.features import (
    HISTORY_FIELDS,
    KMPC_STATE,
    PAPER_STATE,
    RESIDUAL_STATE,
    FeatureMap,
    previous_commands,
)
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.pipeline import TrainConfig, train_model, training_arrays
from rkmpc.learning.recipes import RECIPES, KoopmanLearner, recipe_for, recipe_of_kind
from rkmpc.sim.collect import collect

KOOPMAN_RECIPES = [r for r in RECIPES if isinstance(r.learner, KoopmanLearner)]


@pytest.fixture(scope="module")
def laps(builtin_scenario):
    return collect(builtin_scenario, laps=1)


class _Recorder:
    """A fitted model whose ``lift`` records every state it is given."""

    def __init__(self, model: KoopmanModel) -> None:
        self.model = model
        self.A_, self.B_, self.C_, self.D_ = model.A_, model.B_, model.C_, model.D_
        self.seen: list[np.ndarray] = []

    def lift(self, X: np.ndarray) -> np.ndarray:
        self.seen.append(np.array(X, copy=True))
        return self.model.lift(X)


@pytest.mark.parametrize("recipe", KOOPMAN_RECIPES, ids=lambda r: r.controller)
def test_training_inputs_equal_the_controllers_inputs_bit_for_bit(builtin_scenario, laps, recipe):
    sc = builtin_scenario
    wheelbase = sc.vehicle.wheelbase
    windows = local_frame_windows(laps, AugmentConfig(ratio=0.05, seed=3))
    Xw, _, _ = training_arrays(laps, wheelbase, recipe.kind, windows)
    config = TrainConfig(kind=recipe.kind, augment=AugmentConfig(ratio=0.3, seed=0), model=KoopmanModel(None))
    model, _ = train_model(laps, wheelbase, config)
    checked = 0
    for m, origin in enumerate(windows.origin_index[:12]):
        obs = Observation(*laps.obs[origin])
        recorder = _Recorder(model)
        controller = make_controller(recipe.controller, sc.reference, sc.vehicle, model=recorder)
        if recipe.state.uses_history:  # the command the car held before this transition
            controller.assume_previous(previous_commands(laps.command, laps.episode)[origin])
        controller.step(obs)
        assert recorder.seen, f"{recipe.controller} never lifted a state"
        fed = recorder.seen[-1]
        assert fed.shape == (recipe.state.size,)
        assert np.array_equal(fed, Xw[m, 0]), (recipe.controller, fed, Xw[m, 0])
        checked += 1
    assert checked == 12


def test_the_controllers_use_their_recipes_feature_maps():
    assert recipe_for("rkmpc").state is RESIDUAL_STATE
    assert recipe_for("rkmpc-paper").state is PAPER_STATE
    assert recipe_for("kmpc").state is KMPC_STATE
    assert recipe_of_kind("identified").state is None


def test_a_feature_map_reads_named_fields_in_order():
    fm = FeatureMap(("yaw_rate", "speed"))
    obs = np.arange(14.0).reshape(2, 7)
    np.testing.assert_array_equal(fm.of_array(obs), obs[:, [4, 3]])
    live = Observation(x=1.0, y=2.0, yaw=3.0, speed=4.0, yaw_rate=5.0)
    np.testing.assert_array_equal(fm.of_observation(live), [5.0, 4.0])
    pose = FeatureMap(("x", "yaw", "steer_angle"))
    assert pose.of_observation(Observation(7.0, 8.0, 9.0, 1.0, steer_angle=0.2)).tolist() == [0.0, 0.0, 0.2]
    assert pose.columns == [OBSERVATION_FIELDS.index(n) for n in ("x", "yaw", "steer_angle")]


@pytest.mark.parametrize("names", [(), ("speed", "speed"), ("warp",)])
def test_a_feature_map_refuses_unknown_or_repeated_fields(names):
    with pytest.raises(ParameterError, match="FeatureMap"):
        FeatureMap(names)


def test_every_recipe_is_complete_and_unique():
    assert len({r.controller for r in RECIPES}) == len({r.kind for r in RECIPES}) == len(RECIPES)
    assert [r.controller for r in KOOPMAN_RECIPES] == ["rkmpc-paper", "rkmpc", "kmpc"]
    for r in KOOPMAN_RECIPES:
        model = r.koopman().default_model(seed=4, epochs=3)
        training = model.get_params()["lifting"]["training"]
        assert (training["seed"], training["epochs"]) == (4, 3)
        augment = r.koopman().augment(5)
        assert augment.seed == 5 and augment.ratio == r.koopman().augment_ratio
    with pytest.raises(ParameterError, match="identified"):
        recipe_of_kind("identified").koopman()
    with pytest.raises(ParameterError, match="unknown model kind"):
        recipe_of_kind("quantum")


def test_the_understeer_model_of_the_fit_is_the_one_lmpc_id_drives_with():
    """Identify K on data made by the model itself: the fit must give it back exactly (any L, v, kappa)."""
    from rkmpc.learning.identification import steady_state_steer, understeer_excess

    rng = np.random.default_rng(2)
    wheelbase, gradient = 0.307, 0.012
    v = rng.uniform(1.0, 6.0, 500)
    kappa = rng.uniform(-1.5, 1.5, 500)
    steer = steady_state_steer(kappa, v, wheelbase, gradient)
    yaw_rate = v * kappa
    excess = understeer_excess(steer, v, yaw_rate, wheelbase)
    np.testing.assert_allclose(excess, gradient * v * yaw_rate, rtol=1e-10, atol=1e-12)


def test_history_features_read_the_previous_command():
    fm = FeatureMap(("speed", *HISTORY_FIELDS))
    assert fm.uses_history and not FeatureMap(("speed",)).uses_history
    obs = np.arange(14.0).reshape(2, 7)
    previous = np.array([[1.5, 0.1], [2.5, -0.2]])
    np.testing.assert_array_equal(fm.of_array(obs, previous), [[3.0, 1.5, 0.1], [10.0, 2.5, -0.2]])
    live = Observation(x=1.0, y=2.0, yaw=3.0, speed=4.0)
    np.testing.assert_array_equal(fm.of_observation(live, np.array([3.0, 0.05])), [4.0, 3.0, 0.05])
    with pytest.raises(ParameterError, match="need the previous command"):
        fm.of_observation(live)
    with pytest.raises(ParameterError, match="need the previous command"):
        fm.of_array(obs)


def test_previous_commands_shift_within_episodes_only():
    command = np.array([[1.0, 0.1], [2.0, 0.2], [3.0, 0.3], [4.0, 0.4]])
    episode = np.array([0, 0, 1, 1])
    expected = [[1.0, 0.1], [1.0, 0.1], [3.0, 0.3], [3.0, 0.3]]
    np.testing.assert_array_equal(previous_commands(command, episode), expected)
