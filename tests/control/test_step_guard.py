"""Every controller checks its observation and its command in one place (the base class's step).

A refused observation (non-finite, or a car too far from the reference) gets the safe stop, a
counted status, and leaves no trace: the valid steps after it are answered exactly as in a run
without it. A controller's exception or non-finite command never leaves ``step``.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.analysis.metrics import LapMetrics, lap_metrics
from rkmpc.control import Command, Controller, Observation, make_controller
from rkmpc.control.base import STATUS_CODES, STATUSES, AdmissibleErrors
from rkmpc.control.nonlinear.nmpc import NMPCConfig
from rkmpc.control.qp import QPResult
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import ParameterError
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.vehicle.registry import make_plant

#: Controllers cheap enough to build here, and whether they need a model made in the test.
CHEAP = ["pp", "lmpc", "lmpc-id", "kmpc", "rkmpc", "rkmpc-paper", "nmpc", "nmpc-dynamic"]


@pytest.fixture(scope="module")
def observations(builtin_scenario):
    """A second of observations of the car driven by the LMPC (open loop for the tests)."""
    sc = builtin_scenario
    ctrl = make_controller("lmpc", sc.reference, sc.vehicle)
    log = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference, SimConfig(max_time=0.6)).log
    fields = ("x", "y", "yaw", "speed", "yaw_rate", "slip_angle", "steer_angle")
    return [Observation(**{f: float(log[f][i]) for f in fields}) for i in range(len(log["t"]))]


@pytest.fixture(scope="module")
def models(builtin_scenario, builtin_lap, small_paper_model):
    """Small models of every learned kind, fitted by least squares only (seconds)."""
    from rkmpc.learning.data.augmentation import AugmentConfig
    from rkmpc.learning.identification import identify
    from rkmpc.learning.koopman.model import KoopmanModel
    from rkmpc.learning.pipeline import TrainConfig, train_model

    sc = builtin_scenario

    def fit(kind):
        config = TrainConfig(kind=kind, augment=AugmentConfig(ratio=0.1), model=KoopmanModel(None))
        return train_model(builtin_lap, sc.vehicle.wheelbase, config, vehicle=sc.vehicle_name)[0]

    return {
        "lmpc-id": identify(builtin_lap, sc.vehicle),
        "rkmpc": fit("residual"),
        "kmpc": fit("koopman"),
        "rkmpc-paper": small_paper_model,
    }


def _build(name, scenario, models):
    options = {"model": models[name]} if name in models else {}
    ctrl = make_controller(name, scenario.reference, scenario.vehicle, **options)
    ctrl.reset()
    return ctrl


def _far(obs):
    return replace(obs, x=obs.x + 1.4e6)


def _turned(obs):
    return replace(obs, yaw=obs.yaw + 2.0)


#: Refused observations: how each is made from a valid one, and the status it gets.
BAD = {
    "nan_x": (lambda o: replace(o, x=math.nan), "invalid_input"),
    "inf_x": (lambda o: replace(o, x=math.inf), "invalid_input"),
    "nan_yaw": (lambda o: replace(o, yaw=math.nan), "invalid_input"),
    "nan_speed": (lambda o: replace(o, speed=math.nan), "invalid_input"),
    "inf_yaw_rate": (lambda o: replace(o, yaw_rate=-math.inf), "invalid_input"),
    "far": (_far, "inadmissible"),
    "turned": (_turned, "inadmissible"),
}


@pytest.mark.parametrize("name", CHEAP)
def test_a_refused_step_stops_the_car_and_changes_nothing(builtin_scenario, models, observations, name):
    sc = builtin_scenario
    clean = _build(name, sc, models)
    expected = [clean.step(o) for o in observations]
    assert clean.status_counts["ok"] == len(observations) or name == "kmpc"
    k = 4
    ctrl = _build(name, sc, models)
    got = [ctrl.step(o) for o in observations[:k]]
    for label, (make_bad, status) in BAD.items():
        stop = ctrl.step(make_bad(observations[k]))
        assert ctrl.info.status == status, label
        assert ctrl.info.message
        # The stop holds the wheel where the last command put it.
        assert stop == Command(0.0, got[-1].steer), label
    got += [ctrl.step(o) for o in observations[k:]]
    assert got == expected, name
    for label, (_, status) in BAD.items():
        assert ctrl.status_counts[status] >= 1, label
    assert ctrl.fallback_count == sum(n for s, n in ctrl.status_counts.items() if s != "ok")
    assert ctrl.fallback_count >= len(BAD)


def test_unmeasured_fields_are_nan_by_design(builtin_scenario, models, observations):
    """NaN yaw rate, slip and wheel angle mean "not measured": refused only by the KMPC, which needs them."""
    sc = builtin_scenario
    unmeasured = replace(observations[0], yaw_rate=math.nan, slip_angle=math.nan, steer_angle=math.nan)
    for name in ("pp", "lmpc", "nmpc-dynamic"):
        ctrl = _build(name, sc, models)
        ctrl.step(unmeasured)
        assert ctrl.info.status == "ok", name
    kmpc = _build("kmpc", sc, models)
    assert kmpc.step(unmeasured) == Command(0.0, 0.0)
    assert kmpc.info.status == "invalid_input" and "yaw_rate" in kmpc.info.message


class _Faulty(Controller):
    """A controller that raises, or answers NaN, when told to."""

    name = "faulty"

    def __init__(self):
        super().__init__()
        self.mode = "ok"

    def _reset(self):
        pass

    def _step(self, observation):
        if self.mode == "raise":
            raise ZeroDivisionError("boom")
        if self.mode == "nan":
            return Command(math.nan, 0.1), "ok", ""
        return Command(1.0, 0.2), "ok", ""


def test_exceptions_and_nonfinite_commands_never_leave_step():
    ctrl = _Faulty()
    obs = Observation(0.0, 0.0, 0.0, 1.0)
    assert ctrl.step(obs) == Command(1.0, 0.2)
    ctrl.mode = "raise"
    assert ctrl.step(obs) == Command(0.0, 0.2)
    assert ctrl.info.status == "exception" and "ZeroDivisionError: boom" in ctrl.info.message
    ctrl.mode = "nan"
    assert ctrl.step(obs) == Command(0.0, 0.2)
    assert ctrl.info.status == "nonfinite_command"
    ctrl.mode = "ok"
    assert ctrl.step(obs) == Command(1.0, 0.2)
    assert dict(ctrl.status_counts) == {"ok": 2, "exception": 1, "nonfinite_command": 1}
    assert ctrl.fallback_count == 2
    ctrl.reset()
    assert ctrl.fallback_count == 0 and not ctrl.status_counts


def test_admissible_limits_scale_with_the_car_and_are_validated():
    assert AdmissibleErrors().position(0.33) == pytest.approx(1.98)
    assert AdmissibleErrors().heading == 1.57
    for bad in ({"position_wheelbases": 0.0}, {"heading": math.nan}, {"heading": -1.0}):
        with pytest.raises(ParameterError):
            AdmissibleErrors(**bad)


def test_qp_failures_are_mapped_to_reasons():
    x = np.zeros(2)
    assert QPResult(x, True, "optimal", 3).reason == "ok"
    assert QPResult(np.full(2, np.nan), True, "optimal", 3).reason == "numerical"
    assert QPResult(x, False, "infeasible", 3).reason == "infeasible"
    assert QPResult(x, False, "iteration limit", 3).reason == "iteration_limit"
    assert QPResult(x, False, "maximum iterations reached", 3).reason == "iteration_limit"
    assert QPResult(x, False, "primal infeasible", 3).reason == "infeasible"
    assert QPResult(x, False, "cycling", 3).reason == "numerical"
    assert set(STATUS_CODES) == set(STATUSES) and STATUS_CODES["ok"] == 0 and STATUS_CODES["fallback"] == 1


def test_an_lmpc_out_of_iterations_says_so(builtin_scenario, observations):
    from rkmpc.control.linear.lmpc import LMPCConfig

    sc = builtin_scenario
    ctrl = make_controller(
        "lmpc", sc.reference, sc.vehicle, settings=ControllerSettings(lmpc=LMPCConfig(max_iterations=1))
    )
    ctrl.reset()
    statuses = set()
    for o in observations:
        ctrl.step(replace(o, yaw=o.yaw + 0.3))
        statuses.add(ctrl.info.status)
    assert "iteration_limit" in statuses


def test_an_nmpc_out_of_iterations_says_so(builtin_scenario, observations):
    sc = builtin_scenario
    ctrl = make_controller(
        "nmpc", sc.reference, sc.vehicle, settings=ControllerSettings(nmpc=NMPCConfig(max_iterations=1))
    )
    ctrl.reset()
    ctrl.step(replace(observations[0], yaw=observations[0].yaw + 0.5))
    assert ctrl.info.status == "iteration_limit"
    assert "Maximum_Iterations_Exceeded" in ctrl.info.message


def test_status_counts_reach_the_metrics_and_old_files_still_read(builtin_scenario):
    sc = builtin_scenario
    ctrl = make_controller("pp", sc.reference, sc.vehicle)
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference, SimConfig(max_time=0.3))
    metrics = lap_metrics(result)
    assert metrics.status_counts == {"ok": metrics.steps}
    assert result.log.metadata["status_counts"] == {"ok": metrics.steps}
    data = metrics.to_json()
    assert LapMetrics.from_json(data) == metrics
    del data["status_counts"]
    assert LapMetrics.from_json(data).status_counts is None
