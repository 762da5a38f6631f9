import math

import numpy as np
import pytest

from rkmpc.analysis.metrics import METRIC_KEYS, lap_metrics
from rkmpc.control.base import Controller
from rkmpc.core.errors import ParameterError, PlantIntegrationError
from rkmpc.core.observation import Command, Observation
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.log import StepLog
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.registry import make_plant


class ConstantSteer(Controller):
    """Drives at fixed speed and wheel angle: leaves any track sooner or later."""

    name = "constant"

    def __init__(self, speed, steer):
        super().__init__()
        self.command = Command(speed=speed, steer=steer)

    def _reset(self):
        pass

    def _step(self, observation: Observation):
        return self.command, "ok", ""


def test_leaving_the_track_is_an_outcome_not_an_exception(builtin_scenario):
    sc = builtin_scenario
    result = simulate(make_plant("f1tenth"), ConstantSteer(3.0, 0.3), sc.track, sc.reference, SimConfig())
    assert result.outcome == "off_track"
    assert not result.completed
    assert 0.0 < result.progress < 1.0
    metrics = lap_metrics(result)
    assert metrics["completed"] is False
    assert metrics["lap_time_s"] is None
    assert set(METRIC_KEYS) <= set(metrics)
    # The last logged step is outside the track.
    assert result.log["track_margin"][-1] < 0


def test_log_has_every_step_and_column(builtin_scenario):
    sc = builtin_scenario
    plant = make_plant("f1tenth")
    result = simulate(plant, ConstantSteer(1.0, 0.0), sc.track, sc.reference, SimConfig(max_time=1.0))
    log = result.log
    assert result.outcome in ("timeout", "off_track")
    assert len(log) == 21 or result.outcome == "off_track"
    for col in (
        "t",
        "x",
        "yaw",
        "cmd_speed",
        "cmd_steer",
        "wheel_angle",
        "x_r",
        "theta_r",
        "v_r",
        "delta_r",
        "lateral_error",
        "heading_error",
        "solve_time_s",
        "status",
    ):
        assert col in log.columns
    assert any(c.startswith("state_") for c in log.columns)
    np.testing.assert_allclose(np.diff(log["t"]), 0.05, atol=1e-9)
    assert np.all(log["cmd_speed"][:-1] == 1.0)


def test_log_round_trip(tmp_path, builtin_scenario):
    sc = builtin_scenario
    result = simulate(
        make_plant("f1tenth"), ConstantSteer(1.0, 0.0), sc.track, sc.reference, SimConfig(max_time=0.5)
    )
    path = tmp_path / "log.csv"
    result.log.to_csv(path)
    back = StepLog.from_csv(path)
    assert back.columns == result.log.columns
    np.testing.assert_allclose(back.as_array(), result.log.as_array(), rtol=1e-8, equal_nan=True)
    assert back.metadata["outcome"] == result.outcome
    assert not list(tmp_path.glob(".*tmp"))


def test_lap_time_and_start_line_crossing(builtin_scenario):
    from rkmpc.control import make_controller

    sc = builtin_scenario
    ctrl = make_controller("lmpc", sc.reference, sc.vehicle)
    # Start just before the line: the lap is counted across it.
    cfg = SimConfig(start_s=sc.reference.path.length - 2.0)
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference, cfg)
    assert result.completed
    assert len(result.lap_times) == 1
    expected = sc.reference.profile.lap_time
    assert result.lap_times[0] == pytest.approx(expected, rel=0.15)


def test_sim_config_validation():
    with pytest.raises(ParameterError):
        SimConfig(dt=0.0)
    with pytest.raises(ParameterError):
        SimConfig(laps=0)
    assert math.isclose(SimConfig().dt, 0.05)


class FailingPlant(DynamicPlant):
    """The 1:10 plant, except that its integration fails from ``fail_at`` seconds on."""

    def __init__(self, fail_at: float) -> None:
        self.fail_at = fail_at
        super().__init__()

    def _advance(self, duration, setpoint):
        if self.time >= self.fail_at:
            raise PlantIntegrationError(f"fake integration failure at t={self.time:.2f} s", self.time)
        super()._advance(duration, setpoint)


def test_plant_failure_is_an_outcome_with_its_message(builtin_scenario):
    from rkmpc.control import make_controller

    sc = builtin_scenario
    controller = make_controller("lmpc", sc.reference, sc.vehicle)
    result = simulate(FailingPlant(fail_at=2.0), controller, sc.track, sc.reference, SimConfig())
    assert result.outcome == "plant_failure"
    assert not result.completed
    assert result.failure == "fake integration failure at t=2.00 s"
    assert result.log.metadata["failure"] == result.failure
    assert result.log.metadata["outcome"] == "plant_failure"
    # The run stopped at the failing step, part of the way round, with every step before it logged.
    assert result.log["t"][-1] == pytest.approx(2.0)
    assert len(result.log) == 41
    assert 0.0 < result.progress < 1.0
    metrics = lap_metrics(result)
    assert metrics["completed"] is False
    assert metrics["lateral_error_mean_m"] is not None


def test_a_run_that_ends_normally_records_no_failure(builtin_scenario):
    sc = builtin_scenario
    result = simulate(
        make_plant("f1tenth"), ConstantSteer(1.0, 0.0), sc.track, sc.reference, SimConfig(max_time=0.5)
    )
    assert result.failure is None
    assert result.log.metadata["failure"] is None


def test_a_time_limit_beyond_max_steps_is_refused_before_the_run(builtin_scenario):
    # Issue 13: a track x1e9 ran for ~5e11 s of simulated time with no output.
    sc = builtin_scenario
    with pytest.raises(ParameterError, match=r"simulate: the time limit of 1e\+09 s would allow .* steps"):
        simulate(
            make_plant("f1tenth"), ConstantSteer(1.0, 0.0), sc.track, sc.reference, SimConfig(max_time=1e9)
        )
