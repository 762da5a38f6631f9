import math

import numpy as np
import pytest

from rkmpc.control import LMPCConfig, Observation, make_controller
from rkmpc.control.settings import ControllerSettings
from rkmpc.experiments.runs import run_controller
from rkmpc.sim.run import RunSpec


@pytest.mark.parametrize("name", ["pp", "lmpc"])
def test_controller_completes_builtin_lap(builtin_scenario, name):
    result, metrics = run_controller(builtin_scenario, RunSpec(controller=name))
    assert result.outcome == "completed", metrics
    assert metrics["completed"] and metrics["progress"] == 1.0
    assert metrics["lap_time_s"] > 0
    # Tracking quality the baseline must hold on its own built-in track.
    assert metrics["lateral_error_max_m"] < 0.5
    assert metrics["fallback_count"] == 0


def test_lmpc_beats_pure_pursuit_on_builtin(builtin_scenario):
    _, pp = run_controller(builtin_scenario, RunSpec(controller="pp"))
    _, lmpc = run_controller(builtin_scenario, RunSpec(controller="lmpc"))
    assert lmpc["lateral_error_mean_m"] < pp["lateral_error_mean_m"]


def test_factory_rejects_unknown_name(builtin_scenario):
    with pytest.raises(ValueError, match="known"):
        make_controller("nope", builtin_scenario.reference, builtin_scenario.vehicle)


def test_lmpc_solver_failure_falls_back_and_counts(builtin_scenario):
    # An iteration budget of one cannot solve the QP once constraints bind.
    ctrl = make_controller(
        "lmpc",
        builtin_scenario.reference,
        builtin_scenario.vehicle,
        settings=ControllerSettings(lmpc=LMPCConfig(max_iterations=1)),
    )
    ctrl.reset()
    path = builtin_scenario.reference.path
    s = 5.0
    p = path.position(s)
    yaw = float(path.heading(s))
    # Far off the path with a wrong heading: the unconstrained optimum violates bounds.
    obs = Observation(
        x=float(p[0]) + 0.4 * math.sin(yaw), y=float(p[1]) - 0.4 * math.cos(yaw), yaw=yaw + 0.5, speed=3.0
    )
    commands = [ctrl.step(obs) for _ in range(3)]
    assert ctrl.fallback_count >= 1
    assert ctrl.info.status == "iteration_limit"
    assert "QP failed" in ctrl.info.message
    for c in commands:
        assert np.isfinite(c.speed) and np.isfinite(c.steer)
        assert abs(c.steer) <= builtin_scenario.vehicle.steering.max_angle + 1e-12


def test_lmpc_osqp_backend_matches_daqp(builtin_scenario):
    ref, veh = builtin_scenario.reference, builtin_scenario.vehicle
    a = make_controller("lmpc", ref, veh, settings=ControllerSettings(lmpc=LMPCConfig(solver="daqp")))
    b = make_controller("lmpc", ref, veh, settings=ControllerSettings(lmpc=LMPCConfig(solver="osqp")))
    p = ref.path.position(3.0)
    obs = Observation(x=float(p[0]), y=float(p[1]) + 0.1, yaw=float(ref.path.heading(3.0)) + 0.05, speed=2.0)
    ca, cb = a.step(obs), b.step(obs)
    assert ca.steer == pytest.approx(cb.steer, abs=2e-3)
    assert ca.speed == pytest.approx(cb.speed, abs=2e-3)


def test_top_level_factory(builtin_scenario):
    import rkmpc

    ctrl = rkmpc.make_controller("pp", builtin_scenario.reference, builtin_scenario.vehicle)
    assert ctrl.name == "pp"


def test_lmpc_with_factorised_hessian_matches_daqp_factorising_it(builtin_scenario):
    # The LMPC factorises its Hessian with LAPACK; DAQP doing it itself gives the same commands.
    from rkmpc.control.qp import make_qp

    ref, veh = builtin_scenario.reference, builtin_scenario.vehicle
    fast = make_controller("lmpc", ref, veh)
    plain = make_controller("lmpc", ref, veh)
    plain._qp = make_qp("daqp", max_iterations=plain.config.max_iterations)
    path = ref.path
    for s in np.linspace(1.0, 20.0, 12):
        p = path.position(s)
        yaw = float(path.heading(s))
        obs = Observation(
            x=float(p[0]) - 0.1 * math.sin(yaw), y=float(p[1]) + 0.1 * math.cos(yaw), yaw=yaw - 0.1, speed=2.5
        )
        a, b = fast.step(obs), plain.step(obs)
        assert a.speed == pytest.approx(b.speed, rel=1e-9, abs=1e-12)
        assert a.steer == pytest.approx(b.steer, rel=1e-9, abs=1e-12)
