"""What training says on the terminal: data whose laps fell short, the unit of the held-out error."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rkmpc.config.loader import load_car_config
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.experiments.training import data_fell_short, prediction_error_unit
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.sim.scenario import Scenario

RACE = Path(__file__).resolve().parents[2] / "configs" / "f1tenth-race.toml"


def _data(**metadata) -> TransitionDataset:
    obs = np.zeros((10, 7))
    obs[:, 3] = 1.0
    return TransitionDataset(
        obs=obs,
        command=np.ones((10, 2)),
        next_obs=obs,
        dt=0.05,
        episode=np.zeros(10, dtype=int),
        metadata=metadata,
    )


def test_data_whose_laps_did_not_complete_are_said_in_one_line():
    full = _data(outcome="completed", controller="lmpc", laps=2, progress_laps=2.0)
    assert data_fell_short(full) is None and data_fell_short(_data()) is None  # a bag: no laps asked
    short = data_fell_short(
        replace(full, metadata={**full.metadata, "outcome": "off_track", "progress_laps": 0.41})
    )
    assert short == (
        "the lmpc laps of the data did not complete (off_track after 0.41 of 2 laps; 10 transitions): "
        "the model learns from less than was asked"
    )


@pytest.mark.parametrize(
    ("kind", "unit"),
    [
        ("residual", "norm of U_p speed (m/s), U_p wheel angle (rad)"),
        ("paper", "norm of x (m), y (m), yaw (rad)"),
        ("koopman", "norm of x (m), y (m), yaw (rad), speed (m/s), yaw_rate (rad/s), steer_angle (rad)"),
    ],
)
def test_the_held_out_error_says_what_it_measures_and_in_which_units(kind, unit):
    assert prediction_error_unit(recipe_of_kind(kind).learner) == unit


def test_a_comparison_says_when_its_lmpc_laps_left_the_track():
    """At race pace the LMPC spins: lmpc-id learns from what it recorded, and the terminal hears it."""
    scenario = Scenario.from_car(load_car_config(RACE), "builtin")
    said: list[str] = []
    models, record = learn_models(
        scenario, ModelPlan(controllers=("lmpc-id",), use_cache=False), say=said.append
    )
    assert record.data is not None and record.data.outcome == "stopped" and "lmpc-id" in models
    warned = [line for line in said if line.startswith("warning: the lmpc laps of the data did not complete")]
    assert len(warned) == 1 and "(stopped after 0." in warned[0] and "of 2 laps" in warned[0], said
