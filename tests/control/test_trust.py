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
