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


def _spun_laps() -> TransitionDataset:
    """Laps whose next observations do not follow from the speeds (a car that spun): refused."""
    data = _held_wheel(200)
    jumbled = np.random.default_rng(0).permutation(len(data))
    return TransitionDataset(
        data.obs, data.command, data.next_obs[jumbled], data.dt, data.episode, data.metadata
    )


def test_refused_laps_leave_that_controller_undriven_and_the_others_reported(monkeypatch, tmp_path):
    """Laps that cannot be learned from: the LMPC's figures stand, and the rest says why it is missing."""
    from rkmpc.experiments.compare import CompareConfig, compare
    from rkmpc.experiments.report import write_comparison
    from rkmpc.experiments.results import NOT_LEARNED, TrackResult

    monkeypatch.setattr(models, "collect", lambda *args, **kwargs: _spun_laps())
    messages: list[str] = []
    logs: dict = {}
    config = CompareConfig(track="oval", controllers=("lmpc", "lmpc-id"), use_cache=False)
    result = compare(config, logs=logs, say=messages.append)
    lmpc, ident = result.controllers["lmpc"], result.controllers["lmpc-id"]
    assert lmpc.outcome == "completed" and lmpc.metrics["lateral_error_mean_m"] > 0
    assert ident.outcome == NOT_LEARNED and "consistency check" in (ident.failure or "")
    assert not ident.metrics["completed"] and ident.metrics["steps"] == 0
    assert ident.metrics["lateral_error_mean_m"] is None and "lmpc-id" not in logs
    assert any(m.startswith("warning: lmpc-id not learned") for m in messages)
    assert not any(m == "driving lmpc-id" for m in messages)
    assert "consistency check" in (result.training.models["lmpc-id"].refused or "")
    back = TrackResult.from_json(result.to_json())
    assert back.controllers["lmpc-id"].outcome == NOT_LEARNED
    assert back.training.models["lmpc-id"].refused == result.training.models["lmpc-id"].refused
    write_comparison(tmp_path, result, logs, config.scenario().track)
    assert (
        "- `lmpc-id` did not drive, not learned: the data set [next_obs]"
        in (tmp_path / "table.md").read_text()
    )


def test_a_residual_model_worse_than_no_correction_is_refused_and_that_controller_not_driven(
    builtin_scenario, monkeypatch
):
    """A model that diverges over the horizon (laps ending in a spin) is never used silently."""
    from rkmpc.learning.pipeline import TrainReport

    monkeypatch.setattr(models, "collect", lambda *args, **kwargs: _held_wheel())
    report = TrainReport(
        raw_count=60,
        augmented_count=240,
        train_windows=48,
        holdout_windows=12,
        fit_time_s=0.1,
        multi_step_error=[0.3, 2.0, 4.6],
        no_correction_error=[0.28, 0.28, 0.36],
    )
    monkeypatch.setattr(learn_module, "train_model", lambda *args, **kwargs: (object(), report))
    messages: list[str] = []
    learned, record = learn_models(
        builtin_scenario, ModelPlan(controllers=["rkmpc"], use_cache=False), say=messages.append
    )
    assert "rkmpc" not in learned
    refused = record.models["rkmpc"].refused or ""
    assert "the residual model learned from it is refused" in refused and "(0.3067, 0.36)" in refused
    assert any(m.startswith("warning: rkmpc not learned, its model was refused: ") for m in messages)


@pytest.mark.slow
def test_laps_that_end_in_a_spin_give_low_grip_no_rkmpc_on_yas_marina(shared_tracks):
    """The LMPC's two laps of ``low-grip`` on Yas Marina, through the real F1TENTH sensors, end in a
    spin at 9 % of the lap: the residual model learned from them diverges over the horizon (a
    held-out error in the thousands at 35 steps) and is refused; the LMPC's run stands."""
    from rkmpc.config.loader import load_preset
    from rkmpc.experiments.compare import CompareConfig, compare
    from rkmpc.experiments.results import NOT_LEARNED

    car = load_preset("f1tenth").with_zoo_car("low-grip").with_sensors("f1tenth-real")
    track = str(shared_tracks / "centerlines" / "YasMarina.csv")
    result = compare(CompareConfig(track=track, car=car, controllers=("lmpc", "rkmpc"), use_cache=False))
    assert result.controllers["lmpc"].outcome != NOT_LEARNED
    assert result.controllers["lmpc"].metrics["lateral_error_mean_m"] > 0
    rk = result.controllers["rkmpc"]
    assert rk.outcome == NOT_LEARNED and "is above no correction's" in (rk.failure or "")
