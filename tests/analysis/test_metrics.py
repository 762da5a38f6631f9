"""lap_metrics on hand-made step logs, checked against hand computation; LapMetrics as a mapping."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rkmpc.analysis.metrics import METRIC_KEYS, LapMetrics, lap_metrics
from rkmpc.sim.closed_loop import SimResult, log_columns
from rkmpc.sim.log import StepLog

STATE_NAMES = ("x", "y", "yaw", "v", "beta", "yaw_rate", "delta")
COLUMNS = log_columns(STATE_NAMES)
LAP = 10.0  # lap length (m)
DT = 0.1

# First lap: five steps, chosen by hand.
T = [0.0, 0.1, 0.2, 0.3, 0.4]
PROGRESS = [0.0, 2.5, 5.0, 7.5, 10.0]  # the last row lies exactly on the line: still the first lap
LATERAL = [0.1, -0.3, 0.2, 0.0, -0.2]
HEADING = [0.01, -0.02, 0.03, -0.04, 0.0]
WHEEL = [0.0, 0.1, 0.05, 0.05, -0.05]
SOLVE_S = [0.001, 0.002, 0.004, 0.003, 0.005]
SPEED = [2.0, 2.0, 3.0, 3.0, 1.0]
YAW_RATE = [0.1, -0.5, 0.4, 0.2, 3.0]

# Rows after the line (a second lap): large errors that must not count.
T2 = [0.5, 0.6]
PROGRESS2 = [12.5, 15.0]
LATERAL2 = [5.0, -6.0]
HEADING2 = [1.0, -1.5]
WHEEL2 = [0.4, -0.4]
SPEED2 = [10.0, 10.0]
YAW_RATE2 = [5.0, -5.0]


def _log(t, progress, lateral, heading, wheel, solve_s, speed, yaw_rate) -> StepLog:
    log = StepLog(COLUMNS, capacity=2)
    for values in zip(t, progress, lateral, heading, wheel, solve_s, speed, yaw_rate, strict=True):
        row = dict.fromkeys(COLUMNS, 0.0)
        row.update(
            zip(
                (
                    "t",
                    "progress",
                    "lateral_error",
                    "heading_error",
                    "wheel_angle",
                    "solve_time_s",
                    "state_v",
                    "state_yaw_rate",
                ),
                values,
                strict=True,
            )
        )
        row["s"] = row["progress"] % LAP
        row["status"] = 0.0
        row["cmd_steer"] = 2.0 * row["wheel_angle"]  # a servo that halves the command
        log.append(np.array([row[c] for c in COLUMNS]))
    return log


def _first_lap_log() -> StepLog:
    return _log(T, PROGRESS, LATERAL, HEADING, WHEEL, SOLVE_S, SPEED, YAW_RATE)


def _result(log: StepLog, **kwargs) -> SimResult:
    settings = {"outcome": "completed", "progress": 1.0, "lap_length": LAP, "lap_times": [0.4]}
    settings.update(kwargs)
    return SimResult(log=log, **settings)


def test_every_field_against_hand_computation():
    m = lap_metrics(_result(_first_lap_log(), fallback_count=2))
    assert isinstance(m, LapMetrics)
    assert m.completed is True
    assert m.progress == 1.0
    assert m.lap_time_s == pytest.approx(0.4)
    assert m.lateral_error_mean_m == pytest.approx((0.1 + 0.3 + 0.2 + 0.0 + 0.2) / 5)
    assert m.lateral_error_max_m == pytest.approx(0.3)
    assert m.heading_error_mean_rad == pytest.approx((0.01 + 0.02 + 0.03 + 0.04 + 0.0) / 5)
    # |diff| of the wheel angle: 0.1, 0.05, 0, 0.1 over dt = 0.1 s.
    assert m.steer_rate_mean_rad_s == pytest.approx((1.0 + 0.5 + 0.0 + 1.0) / 4)
    # The commanded angle moves twice as much: the rate of the command, not of the wheel.
    assert m.command_rate_mean_rad_s == pytest.approx(2.0 * (1.0 + 0.5 + 0.0 + 1.0) / 4)
    assert m.solve_ms_mean == pytest.approx(3.0)
    assert m.solve_ms_p99 == pytest.approx(4.0 + 0.96 * 1.0)  # linear interpolation at rank 0.99 * 4
    assert m.solve_ms_max == pytest.approx(5.0)
    assert m.fallback_count == 2 and isinstance(m.fallback_count, int)
    assert m.steps == 5 and isinstance(m.steps, int)
    # max |v * yaw_rate| = |1.0 * 3.0|
    assert m.lateral_accel_max_m_s2 == pytest.approx(3.0)
    for key in METRIC_KEYS:
        value = m[key]
        assert value is None or isinstance(value, bool | int | float)


def test_rows_after_the_first_lap_are_excluded_from_the_errors():
    log = _log(
        T + T2,
        PROGRESS + PROGRESS2,
        LATERAL + LATERAL2,
        HEADING + HEADING2,
        WHEEL + WHEEL2,
        [*SOLVE_S, 0.003, 0.003],
        SPEED + SPEED2,
        YAW_RATE + YAW_RATE2,
    )
    m = lap_metrics(_result(log, progress=1.5, outcome="timeout", lap_times=[0.4]), laps=2)
    first = lap_metrics(_result(_first_lap_log()))
    assert m.lateral_error_mean_m == pytest.approx(first.lateral_error_mean_m)
    assert m.lateral_error_max_m == pytest.approx(0.3)
    assert m.heading_error_mean_rad == pytest.approx(first.heading_error_mean_rad)
    assert m.steer_rate_mean_rad_s == pytest.approx(first.steer_rate_mean_rad_s)
    assert m.lateral_accel_max_m_s2 == pytest.approx(3.0)
    # The run's own counters cover every step.
    assert m.steps == 7
    assert m.completed is False
    assert m.progress == pytest.approx(0.75)
    assert m.lap_time_s == pytest.approx(0.4)


def test_solve_times_cover_the_first_lap_only():
    log = _log(
        T + T2,
        PROGRESS + PROGRESS2,
        LATERAL + LATERAL2,
        HEADING + HEADING2,
        WHEEL + WHEEL2,
        [*SOLVE_S, 0.05, 0.08],
        SPEED + SPEED2,
        YAW_RATE + YAW_RATE2,
    )
    m = lap_metrics(_result(log, progress=1.5, outcome="timeout"), laps=2)
    assert m.solve_ms_max == pytest.approx(5.0)
    assert m.solve_ms_mean == pytest.approx(3.0)


def test_non_finite_solve_times_are_left_out():
    solve = [0.001, math.nan, 0.004, math.nan, 0.003]
    m = lap_metrics(_result(_log(T, PROGRESS, LATERAL, HEADING, WHEEL, solve, SPEED, YAW_RATE)))
    assert m.solve_ms_mean == pytest.approx(8.0 / 3.0)
    assert m.solve_ms_max == pytest.approx(4.0)
    assert m.steps == 5


def test_run_cut_short():
    n = 3  # off the track after three steps
    log = _log(T[:n], PROGRESS[:n], LATERAL[:n], HEADING[:n], WHEEL[:n], SOLVE_S[:n], SPEED[:n], YAW_RATE[:n])
    m = lap_metrics(_result(log, outcome="off_track", progress=0.5, lap_times=[]))
    assert m.completed is False
    assert m.progress == pytest.approx(0.5)
    assert m.lap_time_s is None
    assert m.steps == 3
    assert m.lateral_error_mean_m == pytest.approx(0.2)
    assert m.lateral_error_max_m == pytest.approx(0.3)
    assert m.steer_rate_mean_rad_s == pytest.approx((1.0 + 0.5) / 2)
    # Progress is a fraction of the laps asked for, never above 1.
    assert lap_metrics(_result(log, outcome="off_track", progress=0.5, lap_times=[]), laps=2).progress == (
        pytest.approx(0.25)
    )
    assert lap_metrics(_result(log, progress=1.02)).progress == 1.0


def test_run_without_steps():
    log = StepLog(COLUMNS)
    m = lap_metrics(_result(log, outcome="diverged", progress=0.0, lap_times=[]))
    assert m.steps == 0 and m.completed is False and m.progress == 0.0
    for key in (
        "lap_time_s",
        "lateral_error_mean_m",
        "lateral_error_max_m",
        "heading_error_mean_rad",
        "steer_rate_mean_rad_s",
        "solve_ms_mean",
        "solve_ms_p99",
        "solve_ms_max",
        "lateral_accel_max_m_s2",
    ):
        assert m[key] is None, key


def test_lateral_accel_is_none_without_the_plant_state():
    columns = log_columns(("x", "y", "yaw", "speed"))  # a plant without v / yaw_rate states
    log = StepLog(columns)
    for k in range(3):
        row = dict.fromkeys(columns, 0.0)
        row.update(t=0.1 * k, progress=float(k), lateral_error=0.1 * k, solve_time_s=0.001)
        log.append(np.array([row[c] for c in columns]))
    m = lap_metrics(_result(log))
    assert m.lateral_accel_max_m_s2 is None
    assert m.lateral_error_max_m == pytest.approx(0.2)


def test_mapping_behaviour():
    m = lap_metrics(_result(_first_lap_log()))
    assert m["lateral_error_mean_m"] == m.lateral_error_mean_m
    assert list(m) == list(METRIC_KEYS)
    assert len(m) == len(METRIC_KEYS) == 14
    as_dict = dict(m)
    assert list(as_dict) == list(METRIC_KEYS)
    assert as_dict["steps"] == 5 and as_dict["completed"] is True
    assert "lap_time_s" in m and "nope" not in m
    with pytest.raises(KeyError, match="nope"):
        m["nope"]
    with pytest.raises(KeyError):
        m["to_json"]  # an attribute, not a metric
    assert m.get("nope") is None
    assert dict(m.items()) == as_dict


def test_json_round_trip():
    m = lap_metrics(_result(_first_lap_log(), fallback_count=1))
    data = m.to_json()
    # The table's metrics in order, then the steps by status (not a table column).
    assert list(data) == [*METRIC_KEYS, "status_counts"]
    assert LapMetrics.from_json(data) == m
    assert LapMetrics.from_json(json.loads(json.dumps(data))) == m
    assert LapMetrics.from_json({**data, "extra": 1}) == m
    short = lap_metrics(_result(StepLog(COLUMNS), outcome="timeout", progress=0.0, lap_times=[]))
    assert LapMetrics.from_json(json.loads(json.dumps(short.to_json()))) == short
    with pytest.raises(KeyError):
        LapMetrics.from_json({k: v for k, v in data.items() if k != "steps"})


def test_results_written_before_the_command_rate_still_load():
    data = lap_metrics(_result(_first_lap_log())).to_json()
    del data["command_rate_mean_rad_s"]
    old = LapMetrics.from_json(data)
    assert old.command_rate_mean_rad_s is None
    assert old.lateral_error_mean_m == data["lateral_error_mean_m"]
