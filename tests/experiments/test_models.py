"""learn_models: identification warnings reach the comparison's messages and its training record."""

from __future__ import annotations

import numpy as np
import pytest

import rkmpc.experiments.models as models
import rkmpc.learning.learn as learn_module
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.learning.data.dataset import TransitionDataset


def _held_wheel(n: int = 60) -> TransitionDataset:
    """A car cornering steadily on a held wheel angle: its servo cannot be identified."""
    obs = np.zeros((n + 1, 7))
    obs[:, 3], obs[:, 6], obs[:, 5] = 3.0, 0.1, np.nan
    obs[:, 4] = 3.0 * np.tan(0.1) / 0.4
    # On the circle that speed and yaw rate drive (the data must show a moving car to be learned from).
    yaw = obs[:, 4] * 0.05 * np.arange(n + 1)
    radius = obs[0, 3] / obs[0, 4]
    obs[:, 0], obs[:, 1], obs[:, 2] = radius * np.sin(yaw), radius * (1.0 - np.cos(yaw)), yaw
    command = np.column_stack([np.full(n, 3.0), np.full(n, 0.1)])
    return TransitionDataset(
        obs[:-1], command, obs[1:], 0.05, np.zeros(n, dtype=int), {"outcome": "completed"}
    )


def test_identification_warnings_are_told_and_recorded(builtin_scenario, monkeypatch, recwarn):
    monkeypatch.setattr(models, "collect", lambda *args, **kwargs: _held_wheel())
    messages: list[str] = []
    learned, record = learn_models(
        builtin_scenario, ModelPlan(controllers=["lmpc-id"], use_cache=False), say=messages.append
    )
    model = learned["lmpc-id"]
    assert model.servo_structure == "nominal" and model.warnings
    told = [m for m in messages if m.startswith("lmpc-id: identification warning: ")]
    assert [m.split(": ", 2)[2] for m in told] == list(model.warnings)
    written = record.to_json()["lmpc-id"]["identified"]
    assert written["warnings"] == list(model.warnings)
    assert written["servo_fit_r2"] is None  # no fit was made: null in results.json, not NaN


class _Trained(Exception):
    """Raised by the stand-in trainer once it has reported its epochs."""


def test_training_progress_is_told_with_an_estimate(builtin_scenario, monkeypatch):
    """The comparison's messages carry the training's epochs and the time left, not one silent line."""
    monkeypatch.setattr(models, "collect", lambda *args, **kwargs: _held_wheel())

    def fake_train(data, wheelbase, config, *, on_epoch=None, vehicle=None, allow_mismatch=False, source=""):
        assert on_epoch is not None
        for epoch in range(config.model.lifting.training.epochs + 1):
            on_epoch(epoch, 1.0 / (epoch + 1))
        raise _Trained

    monkeypatch.setattr(learn_module, "train_model", fake_train)  # the one place that trains
    messages: list[str] = []
    plan = ModelPlan(controllers=["rkmpc"], use_cache=False, epochs=20)
    with pytest.raises(_Trained):
        learn_models(builtin_scenario, plan, say=messages.append)
    progress = [m for m in messages if m.startswith("training the residual model of rkmpc: epoch ")]
    assert 10 <= len(progress) <= 12
    assert "left" in progress[1] and progress[-1].endswith("epoch 20/20, loss 0.0476, done")


def test_the_model_cache_key_follows_every_source_of_the_package(tmp_path):
    # A change anywhere in the code (here the simulation floor, not learning or vehicle) trains
    # again: a model another code made is never reused.
    from rkmpc.experiments.models import source_hash

    for sub in ("learning", "vehicle", "sim", "core"):
        (tmp_path / sub).mkdir()
        (tmp_path / sub / "a.py").write_text(f"X = '{sub}'\n")
    before = source_hash(tmp_path)
    assert source_hash(tmp_path) == before and len(before) == 16
    (tmp_path / "sim" / "a.py").write_text("X = 'changed'\n")
    assert source_hash(tmp_path) != before
    (tmp_path / "sim" / "a.py").rename(tmp_path / "sim" / "b.py")
    changed = source_hash(tmp_path)
    (tmp_path / "sim" / "b.py").write_text("X = 'sim'\n")
    assert source_hash(tmp_path) not in (before, changed)  # a renamed file counts too
