"""train_model's report: the held-out error of a residual model beside that of no correction at all."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.learning.data.augmentation import AugmentConfig, local_frame_windows
from rkmpc.learning.data.residuals import control_residuals
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.pipeline import TrainConfig, TrainReport, train_model


def _report(model: list[float], none: list[float]) -> TrainReport:
    return TrainReport(
        raw_count=100,
        augmented_count=400,
        train_windows=80,
        holdout_windows=20,
        fit_time_s=1.0,
        multi_step_error=model,
        no_correction_error=none,
    )


@pytest.mark.parametrize(
    ("model", "none", "worse"),
    [
        ([0.01, 0.02, 0.04], [0.2, 0.2, 0.2], False),  # a model that corrects
        ([0.01, 0.3, 4.5], [0.27, 0.28, 0.35], True),  # diverges over the horizon (a spin in the laps)
        ([0.01, 0.02, 0.3], [0.2, 0.2, 0.2], True),  # better on average, worse at the last step
        ([0.5, 0.5, 0.1], [0.2, 0.2, 0.2], True),  # better at the last step, worse on average
        ([0.2, 0.2, 0.2], [0.2, 0.2, 0.2], False),  # as good as none: kept
        ([0.01, 0.02], [], False),  # no figure of no correction (another kind): nothing to compare
    ],
)
def test_a_model_worse_than_no_correction_on_average_or_at_the_horizon_is_named(model, none, worse):
    why = _report(model, none).worse_than_no_correction()
    assert (why is not None) is worse
    if worse:
        assert f"{np.mean(model):.4g} mean over {len(model)} steps" in why and f"{none[-1]:.4g}" in why


def test_no_correction_is_the_residual_labels_of_the_held_out_windows(builtin_scenario, builtin_lap):
    # The figure of no correction is the error of taking U_p equal to the command over the same
    # held-out windows: the norm of the residual labels dU there, averaged per horizon step.
    augment = AugmentConfig(ratio=0.2, n_points=5)
    config = TrainConfig(kind="residual", augment=augment, model=KoopmanModel(None))
    wheelbase = builtin_scenario.vehicle.wheelbase
    _, report = train_model(builtin_lap, wheelbase, config, vehicle=builtin_scenario.vehicle_name)
    windows = local_frame_windows(builtin_lap, augment)
    held = windows.indices[report.train_windows :]
    delta = control_residuals(builtin_lap, wheelbase).delta[held]
    expected = np.linalg.norm(delta, axis=-1).mean(axis=0)
    assert report.holdout_windows == len(held) > 0
    np.testing.assert_allclose(report.no_correction_error, expected, rtol=1e-12)
    assert len(report.multi_step_error) == 5 and report.worse_than_no_correction() is None


def test_a_pose_model_has_no_figure_of_no_correction(builtin_scenario, builtin_lap):
    config = TrainConfig(kind="paper", augment=AugmentConfig(ratio=0.2, n_points=5), model=KoopmanModel(None))
    _, report = train_model(builtin_lap, builtin_scenario.vehicle.wheelbase, config)
    assert report.multi_step_error and report.no_correction_error == []
