"""learn_models: identification warnings reach the comparison's messages and its training record."""

from __future__ import annotations

import numpy as np

import rkmpc.experiments.models as models
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.learning.data.dataset import TransitionDataset


def _held_wheel(n: int = 60) -> TransitionDataset:
    """A car cornering steadily on a held wheel angle: its servo cannot be identified."""
    obs = np.zeros((n + 1, 7))
    obs[:, 3], obs[:, 6], obs[:, 5] = 3.0, 0.1, np.nan
    obs[:, 4] = 3.0 * np.tan(0.1) / 0.4
    command = np.column_stack([np.full(n, 3.0), np.full(n, 0.1)])
    return TransitionDataset(
        obs[:-1], command, obs[1:], 0.05, np.zeros(n, dtype=int), {"outcome": "completed"}
    )


def test_identification_warnings_are_told_and_recorded(builtin_scenario, monkeypatch, recwarn):
    monkeypatch.setattr(models, "collect", lambda *args, **kwargs: _held_wheel())
    messages: list[str] = []
    options, record = learn_models(
        builtin_scenario, ModelPlan(["lmpc-id"], use_cache=False), say=messages.append
    )
    model = options["lmpc-id"]["model"]
    assert model.servo_structure == "nominal" and model.warnings
    told = [m for m in messages if m.startswith("lmpc-id: identification warning: ")]
    assert [m.split(": ", 2)[2] for m in told] == list(model.warnings)
    written = record.to_json()["lmpc-id"]["identified"]
    assert written["warnings"] == list(model.warnings)
    assert written["servo_fit_r2"] is None  # no fit was made: null in results.json, not NaN
