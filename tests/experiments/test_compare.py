"""The one-track experiment: fault classification and settings validation."""

from __future__ import annotations

import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.experiments.compare import DEGRADE_THRESHOLD, CompareConfig, fault_effect

NOMINAL = {"completed": True, "lateral_error_mean_m": 0.02}


@pytest.mark.parametrize(
    ("faulted", "outcome", "effect"),
    [
        ({"completed": True, "lateral_error_mean_m": 0.021}, "completed", "completes"),
        (
            {"completed": True, "lateral_error_mean_m": 0.02 * (1 + DEGRADE_THRESHOLD) + 1e-6},
            "completed",
            "degrades",
        ),
        ({"completed": False, "lateral_error_mean_m": 0.05}, "off_track", "leaves the track"),
        ({"completed": False, "lateral_error_mean_m": 0.05}, "timeout", "does not finish"),
    ],
)
def test_fault_effect_classes(faulted, outcome, effect):
    assert fault_effect(NOMINAL, faulted, outcome) == effect


@pytest.mark.parametrize(
    "kwargs",
    [{"laps": 0}, {"seed": -1}, {"kmpc_samples": 10}, {"controllers": ()}, {"epochs": 0}, {"run_laps": 0}],
)
def test_compare_config_rejects_bad_settings(kwargs):
    with pytest.raises(ParameterError):
        CompareConfig(track="builtin", **kwargs)
