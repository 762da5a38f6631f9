"""The out-of-distribution guard of the residual MPCs, against hand-computed trusts."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.control.learned.trust import CorrectionTrust, TrustConfig
from rkmpc.core.errors import ParameterError

X_MIN = np.array([0.0, -1.0])
X_MAX = np.array([4.0, 1.0])  # spans 4 and 2


def _trust(**settings) -> CorrectionTrust:
    identity = np.eye(2)
    return CorrectionTrust(identity, identity, identity, X_MIN, X_MAX, TrustConfig(**settings))


def test_inside_the_training_range_trust_is_full() -> None:
    guard = _trust()
    assert guard.judge(np.array([2.0, 0.0])) == 1.0
    assert guard.faded == {"range": 0, "error": 0}


def test_trust_fades_linearly_outside_the_range() -> None:
    guard = _trust(range_margin=0.05, range_fade=0.25)
    # 0.3 of the span beyond (1.2 m/s past a 4 m/s span): 1 - (0.3 - 0.05) / 0.25 = 0.
    assert guard.judge(np.array([5.2, 0.0])) == pytest.approx(0.0)
    # 0.15 of the second feature's span below: 1 - (0.15 - 0.05) / 0.25 = 0.6.
    assert guard.judge(np.array([2.0, -1.3])) == pytest.approx(0.6)
    # Within the margin: still full.
    assert guard.judge(np.array([4.1, 0.0])) == 1.0
    assert guard.faded == {"range": 2, "error": 0}


def test_growing_prediction_errors_fade_the_correction() -> None:
    guard = _trust(error_low=0.1, error_high=0.3, error_smoothing=0.5)
    x = np.array([2.0, 0.0])
    assert guard.judge(x) == 1.0
    guard.expect(x, np.zeros(2))  # identity model: predicts x again
    assert guard.judge(x) == 1.0 and guard.error == 0.0
    guard.expect(x, np.zeros(2))
    # Off by 0.8 m/s on a 4 m/s span: e = 0.2, smoothed 0.1 -> trust 1 (at error_low).
    assert guard.judge(np.array([2.8, 0.0])) == pytest.approx(1.0)
    guard.expect(x, np.zeros(2))
    # Again 0.2: smoothed 0.15 -> (0.3 - 0.15) / 0.2 = 0.75.
    assert guard.judge(np.array([2.8, 0.0])) == pytest.approx(0.75)
    assert guard.faded["error"] == 1
    guard.reset()
    assert guard.error == 0.0 and guard.steps == 0


def test_disabled_guard_only_counts() -> None:
    guard = _trust(enabled=False)
    assert guard.judge(np.array([9.0, 0.0])) == 1.0
    assert guard.faded["range"] == 1


def test_settings_are_validated() -> None:
    with pytest.raises(ParameterError, match="error_high must exceed"):
        TrustConfig(error_low=0.3, error_high=0.2)
    with pytest.raises(ParameterError, match="error_smoothing"):
        TrustConfig(error_smoothing=1.5)
    with pytest.raises(ParameterError, match="min_span"):
        TrustConfig(min_span=1.5)
    with pytest.raises(ParameterError, match="min_span"):
        TrustConfig(min_span=float("nan"))


def test_a_feature_that_hardly_varied_is_judged_against_its_size() -> None:
    # Speed held at 3.5 m/s (spread 0.02: an oval at the profile's top speed), yaw rate through 0.
    identity = np.eye(2)
    x_min, x_max = np.array([3.49, -1.0]), np.array([3.51, 1.0])
    x = np.array([3.5, 0.0])
    noisy = np.array([3.53, 0.0])  # 0.03 m/s of speed noise

    def error_after_one_noisy_step(config: TrustConfig) -> float:
        guard = CorrectionTrust(identity, identity, identity, x_min, x_max, config)
        guard.judge(x)
        guard.expect(x, np.zeros(2))
        guard.judge(noisy)
        return guard.error

    # The spread alone: 0.03 / 0.02 = 1.5 of the span, smoothed by 0.2 -> 0.3, past error_high.
    assert error_after_one_noisy_step(TrustConfig(min_span=0.0)) == pytest.approx(0.3)
    # Floored at 0.2 * 3.51 = 0.702 m/s: 0.03 / 0.702 * 0.2.
    assert error_after_one_noisy_step(TrustConfig(min_span=0.2)) == pytest.approx(0.03 / 0.702 * 0.2)
    # The yaw rate's range holds 0: its span (2) is above 0.2 * 1 and is kept.
    guard = CorrectionTrust(identity, identity, identity, x_min, x_max, TrustConfig(min_span=0.2))
    assert guard.judge(np.array([3.5, 1.3])) == pytest.approx(1.0 - (0.15 - 0.05) / 0.25)
