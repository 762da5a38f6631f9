"""Whether a log's speed command set the car's speed, and its repair (issue 25).

:func:`speed_command_check` compares the speed reached at the end of each period with the speed
commanded for it; :func:`with_measured_speed_commands` replaces the command by what a first-order
speed loop needed. The real car's DS3 run commands 5 m/s while it drives 1.3 m/s: the CSV import
replaces its command and says so; DS2's command did set the speed and is kept.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.logs import FRICTION_MAPS, import_csv_log
from rkmpc.learning.data.quality.speed_command import (
    TRACKING_RANGE,
    speed_command_check,
    with_measured_speed_commands,
)
from rkmpc.vehicle.params import f1tenth

DT = 0.05
TAU = 0.2  # s, the speed loop's lag


def driven(command_speed: np.ndarray, v0: float, tau: float = TAU) -> TransitionDataset:
    """A car on a straight line whose speed follows ``command_speed`` through a first-order lag."""
    a = math.exp(-DT / tau)
    n = len(command_speed)
    v = np.empty(n + 1)
    v[0] = v0
    for k, u in enumerate(command_speed):
        v[k + 1] = u + (v[k] - u) * a
    x = np.concatenate([[0.0], np.cumsum(v[:-1] * DT)])
    obs = np.column_stack(
        [x, np.zeros(n + 1), np.zeros(n + 1), v, np.zeros(n + 1), *[np.full(n + 1, np.nan)] * 2]
    )
    steer = 0.1 * np.sin(np.arange(n) / 10.0)
    return TransitionDataset(
        obs=obs[:-1],
        command=np.column_stack([command_speed, steer]),
        next_obs=obs[1:],
        dt=DT,
        episode=np.zeros(n, dtype=int),
    )


def steps(n: int = 400, seed: int = 0) -> np.ndarray:
    """Speed commands (m/s): random levels from 0.8 to 4 m/s, held 0.5 to 2 s."""
    rng = np.random.default_rng(seed)
    out = np.empty(n)
    k = 0
    while k < n:
        hold = int(rng.integers(10, 41))
        out[k : k + hold] = rng.uniform(0.8, 4.0)
        k += hold
    return out


def test_a_speed_that_follows_its_command_tracks():
    check = speed_command_check(driven(steps(), v0=1.0))
    assert check.tracks and check.samples > 350 and not check.replaced
    assert TRACKING_RANGE[0] <= check.ratio <= TRACKING_RANGE[1]
    assert check.ratio == pytest.approx(1.0, abs=0.05)
    assert check.message() is None


def test_a_constant_5_m_s_command_at_1_3_m_s_does_not_track():
    # The radio drove the car at 1.3 m/s; the logged command is a constant 5 m/s cap.
    n = 300
    data = driven(np.full(n, 1.3), v0=1.3)
    data = replace(data, command=np.column_stack([np.full(n, 5.0), data.command[:, 1]]))
    check = speed_command_check(data)
    assert not check.tracks and check.samples == n
    assert check.ratio == pytest.approx(1.3 / 5.0, abs=1e-9)
    kept = check.message()
    assert kept is not None and "reached 0.26 times the speed commanded" in kept
    assert f"median of {n} transitions" in kept and "kept as recorded" in kept
    replaced = replace(check, replaced=True).message()
    assert replaced is not None and "replaced by the measured speed" in replaced


def test_without_transitions_commanded_and_driven_the_check_has_nothing_to_say():
    data = driven(np.full(50, 0.2), v0=0.2)  # below 0.5 m/s commanded
    check = speed_command_check(data)
    assert math.isnan(check.ratio) and check.samples == 0 and check.tracks and check.message() is None


@pytest.mark.parametrize("tau", [0.1, 0.2, 0.5])
def test_the_measured_command_inverts_a_first_order_lag_exactly(tau):
    command = steps(seed=3)
    data = driven(command, v0=0.5, tau=tau)
    repaired = with_measured_speed_commands(data, tau)
    np.testing.assert_allclose(repaired.command[:, 0], command, rtol=0, atol=1e-9)
    # Only the speed command is replaced: the steering and the observations are the data's.
    np.testing.assert_array_equal(repaired.command[:, 1], data.command[:, 1])
    np.testing.assert_array_equal(repaired.obs, data.obs)
    np.testing.assert_array_equal(repaired.next_obs, data.next_obs)


def test_the_measured_command_is_held_at_or_above_zero():
    data = driven(np.full(40, 3.0), v0=3.0)
    obs = data.next_obs.copy()
    obs[10, 3] = 0.5  # a drop no lag of 0.2 s follows from 3 m/s in 0.05 s: a negative command
    data = TransitionDataset(data.obs, data.command, obs, DT, data.episode)
    repaired = with_measured_speed_commands(data, TAU)
    assert repaired.command[10, 0] == 0.0 and (repaired.command[:, 0] >= 0).all()


# ---------------------------------------------------------------------------- the real logs


@pytest.fixture(scope="module")
def imports(real_logs):
    """DS2 and DS3 imported with the preset (speed_command "auto") and as recorded."""
    recorded = replace(FRICTION_MAPS, speed_command="recorded")
    return {
        run: (
            import_csv_log(real_logs / run, f1tenth(), FRICTION_MAPS),
            import_csv_log(real_logs / run, f1tenth(), recorded),
        )
        for run in ("DS2", "DS3")
    }


def test_the_ds3_import_replaces_the_speed_command_and_says_so(imports):
    auto, recorded = imports["DS3"]
    check = auto.report.speed_command
    assert check is not None and check.replaced and not check.tracks
    assert check.ratio == pytest.approx(0.26, abs=0.02) and check.samples > 2000
    said = [w for w in auto.report.warnings if "speed command did not set the speed" in w]
    assert len(said) == 1 and "replaced by the measured speed" in said[0]
    assert auto.data.metadata["speed_command"]["replaced"] is True
    # As recorded, the command is the 5 m/s cap; replaced, what the speed loop needed.
    assert np.median(recorded.data.command[:, 0]) > 4.0
    expected = with_measured_speed_commands(recorded.data, f1tenth().drive.time_constant)
    np.testing.assert_allclose(auto.data.command, expected.command)
    assert np.median(auto.data.command[:, 0]) == pytest.approx(np.median(auto.data.obs[:, 3]), rel=0.1)
    # Kept as recorded on request, the report still warns.
    kept = [w for w in recorded.report.warnings if "speed command did not set the speed" in w]
    assert len(kept) == 1 and "kept as recorded" in kept[0]


def test_the_ds2_import_keeps_the_speed_command_it_tracked(imports):
    auto, recorded = imports["DS2"]
    check = auto.report.speed_command
    assert check is not None and check.tracks and not check.replaced
    assert check.ratio == pytest.approx(1.0, abs=0.1)
    assert not any("speed command" in w for w in auto.report.warnings)
    np.testing.assert_array_equal(auto.data.command, recorded.data.command)
    assert auto.data.metadata["speed_command"]["replaced"] is False
