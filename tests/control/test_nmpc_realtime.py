"""The nonlinear MPCs' real-time path without acados: one SQP iteration per step, from a car file.

``configs/f1tenth-realtime.toml`` sets ``[controllers.nmpc] solver = "sqpmethod"`` and
``max_iterations = 1``; every command that reads a car file then drives ``nmpc`` and
``nmpc-dynamic`` that way (``make bench`` times it). The acados real-time iterations are
``tests/control/test_nmpc_acados.py``.
"""

import math
from dataclasses import replace
from pathlib import Path

import pytest

from rkmpc.analysis.metrics import lap_metrics
from rkmpc.config.loader import load_car_config, load_preset
from rkmpc.core.observation import Observation
from rkmpc.sim.build import build_controller
from rkmpc.sim.run import RunSpec, drive
from rkmpc.sim.scenario import Scenario

REALTIME = Path(__file__).resolve().parents[2] / "configs" / "f1tenth-realtime.toml"
NONLINEAR = ("nmpc", "nmpc-dynamic")


@pytest.fixture(scope="module")
def realtime_scenario():
    """The built-in track with the car of ``configs/f1tenth-realtime.toml``."""
    return Scenario.from_car(load_car_config(REALTIME), "builtin")


def test_the_realtime_file_is_the_preset_with_one_sqp_iteration():
    car = load_car_config(REALTIME)
    preset = load_preset("f1tenth")
    nmpc = replace(preset.controllers.nmpc, solver="sqpmethod", max_iterations=1)
    expected = replace(preset, controllers=replace(preset.controllers, nmpc=nmpc))
    assert replace(car, source=None, sha256=None) == expected


@pytest.mark.parametrize("name", NONLINEAR)
def test_the_car_file_selects_one_sqp_iteration(realtime_scenario, name):
    sc = realtime_scenario
    ctrl = build_controller(name, sc)
    assert (ctrl.config.solver, ctrl.config.max_iterations) == ("sqpmethod", 1)
    ctrl.reset()
    s = 5.0
    p = sc.reference.path.position(s)
    obs = Observation(x=float(p[0]), y=float(p[1]), yaw=float(sc.reference.path.heading(s)), speed=1.0)
    for _ in range(3):
        cmd = ctrl.step(obs)
        # One iteration stops at the budget; the iterate is the command, not a fall-back.
        assert ctrl.info.status == "ok", ctrl.info.message
        assert math.isfinite(cmd.speed) and math.isfinite(cmd.steer)
    assert ctrl.fallback_count == 0


@pytest.mark.slow
@pytest.mark.parametrize("name", NONLINEAR)
def test_one_sqp_iteration_laps_the_builtin_track(realtime_scenario, name):
    sc = realtime_scenario
    result = drive(sc, RunSpec(controller=name))
    metrics = lap_metrics(result)
    assert result.outcome == "completed", metrics
    assert metrics["fallback_count"] == 0
    # Within a few centimetres of the path (docs/nmpc.md: 0.0355 m and 0.0111 m mean here).
    assert metrics["lateral_error_mean_m"] < 0.05
    assert metrics["lateral_error_max_m"] < 0.25
