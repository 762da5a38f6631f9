import math

import numpy as np
import pytest

from rkmpc.analysis.metrics import lap_metrics
from rkmpc.control.linear.lmpc import LinearMPC
from rkmpc.control.nonlinear.nmpc import DynamicNMPC, KinematicNMPC, NMPCConfig
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation
from rkmpc.sim.closed_loop import simulate
from rkmpc.vehicle.registry import make_plant


def _off_path_observation(scenario, s=5.0, offset=0.4, yaw_error=0.5, speed=3.0):
    path = scenario.reference.path
    p = path.position(s)
    yaw = float(path.heading(s))
    return Observation(
        x=float(p[0]) + offset * math.sin(yaw),
        y=float(p[1]) - offset * math.cos(yaw),
        yaw=yaw + yaw_error,
        speed=speed,
    )


def _on_path_observation(scenario, s=5.0):
    path = scenario.reference.path
    p = path.position(s)
    return Observation(
        x=float(p[0]),
        y=float(p[1]),
        yaw=float(path.heading(s)),
        speed=float(scenario.reference.profile.speed(s)),
    )


@pytest.mark.slow
def test_kinematic_nmpc_laps_builtin_and_tracks_like_lmpc(builtin_scenario):
    sc = builtin_scenario
    lmpc = lap_metrics(
        simulate(make_plant("f1tenth"), LinearMPC(sc.reference, sc.vehicle), sc.track, sc.reference)
    )
    ctrl = KinematicNMPC(sc.reference, sc.vehicle)
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference)
    nmpc = lap_metrics(result)
    assert result.outcome == "completed", nmpc
    assert nmpc["fallback_count"] == 0
    assert nmpc["lateral_error_mean_m"] <= 1.5 * lmpc["lateral_error_mean_m"]
    assert nmpc["lateral_error_max_m"] < 0.5
    assert ctrl.step_count == nmpc["steps"]


@pytest.mark.slow
def test_dynamic_nmpc_laps_builtin(builtin_scenario):
    sc = builtin_scenario
    ctrl = DynamicNMPC(sc.reference, sc.vehicle)
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference)
    metrics = lap_metrics(result)
    assert result.outcome == "completed", metrics
    assert metrics["lateral_error_max_m"] < 0.5
    # A few fall-backs under a loaded machine (CPU-time budget) are tolerated, not many.
    assert metrics["fallback_count"] <= 0.05 * metrics["steps"]


@pytest.mark.parametrize("cls", [KinematicNMPC, DynamicNMPC])
def test_forced_failure_falls_back_and_continues(builtin_scenario, cls):
    sc = builtin_scenario
    ctrl = cls(sc.reference, sc.vehicle, NMPCConfig(max_iterations=1))
    ctrl.reset()
    obs = _off_path_observation(sc)
    commands = []
    for i in range(4):
        commands.append(ctrl.step(obs))
        assert ctrl.info.status == "iteration_limit"
        assert "Maximum_Iterations_Exceeded" in ctrl.info.message
        assert ctrl.fallback_count == i + 1
    assert ctrl.step_count == 4
    veh = sc.vehicle
    prev = None
    for c in commands:
        assert np.isfinite(c.speed) and np.isfinite(c.steer)
        assert veh.drive.min_speed <= c.speed <= veh.drive.max_speed
        assert abs(c.steer) <= veh.steering.max_angle + 1e-12
        if prev is not None:
            assert abs(c.steer - prev) <= veh.steering.max_rate * ctrl.config.dt + 1e-12
        prev = c.steer


def test_tiny_cpu_budget_falls_back(builtin_scenario):
    sc = builtin_scenario
    ctrl = KinematicNMPC(sc.reference, sc.vehicle, NMPCConfig(max_cpu_time=1e-6))
    ctrl.reset()
    cmd = ctrl.step(_off_path_observation(sc))
    # A CPU-time budget (off by default: results must not depend on the machine) is a budget.
    assert ctrl.info.status == "iteration_limit" and "CpuTime" in ctrl.info.message
    assert ctrl.fallback_count == 1
    assert np.isfinite(cmd.speed) and np.isfinite(cmd.steer)


def test_solver_exception_falls_back_to_shifted_plan(builtin_scenario):
    sc = builtin_scenario
    ctrl = KinematicNMPC(sc.reference, sc.vehicle)
    ctrl.reset()
    obs = _on_path_observation(sc)
    ctrl.step(obs)
    assert ctrl.info.status == "ok"
    plan = ctrl.last_plan.copy()

    def broken(**kwargs):
        raise RuntimeError("boom")

    ctrl._solver = broken
    cmd = ctrl.step(obs)
    # The NMPC catches its solver's exception itself and falls back to its shifted plan.
    assert ctrl.info.status == "exception"
    assert "boom" in ctrl.info.message
    assert ctrl.fallback_count == 1
    assert cmd.speed == pytest.approx(plan[1, 0])
    assert cmd.steer == pytest.approx(plan[1, 1])


@pytest.mark.parametrize("cls", [KinematicNMPC, DynamicNMPC])
def test_first_prediction_respects_bounds(builtin_scenario, cls):
    sc = builtin_scenario
    ctrl = cls(sc.reference, sc.vehicle)
    ctrl.reset()
    obs = _off_path_observation(sc, offset=0.2, yaw_error=0.3, speed=2.0)
    cmd = ctrl.step(obs)
    assert ctrl.info.status == "ok", ctrl.info.message
    plan, states = ctrl.last_plan, ctrl.last_states
    n, dt = ctrl.config.horizon, ctrl.config.dt
    assert plan.shape == (n, 2) and states.shape == (n + 1, ctrl.nx)
    veh = sc.vehicle
    tol = 1e-6
    proj = sc.reference.project(obs.x, obs.y)
    v_ref = sc.reference.horizon(proj.s, n, dt).v[:n]
    assert np.all(plan[:, 0] >= veh.drive.min_speed - tol)
    assert np.all(plan[:, 0] <= np.minimum(veh.drive.max_speed, v_ref) + tol)
    assert np.all(np.abs(plan[:, 1]) <= veh.steering.max_angle + tol)
    # Steering rate, including the step from the input taken as applied before: the feed-forward
    # angle, as the observation has no measured wheel angle.
    d_ref0 = sc.reference.horizon(proj.s, n, dt).delta[0]
    steer = np.concatenate([[d_ref0], plan[:, 1]])
    assert np.all(np.abs(np.diff(steer)) <= veh.steering.max_rate * dt + tol)
    # The predicted states start at the observation and follow the model.
    assert states[0, :2] == pytest.approx([obs.x, obs.y])
    assert math.isclose(math.remainder(states[0, 2] - obs.yaw, 2 * math.pi), 0.0, abs_tol=1e-9)
    np.testing.assert_allclose(ctrl.predict(states[0], plan), states, atol=1e-5)
    assert cmd.speed == pytest.approx(plan[0, 0]) and cmd.steer == pytest.approx(plan[0, 1])


def test_sqp_rti_variant_runs(builtin_scenario):
    sc = builtin_scenario
    ctrl = KinematicNMPC(sc.reference, sc.vehicle, NMPCConfig(solver="sqpmethod", max_iterations=1))
    ctrl.reset()
    obs = _on_path_observation(sc)
    for _ in range(3):
        cmd = ctrl.step(obs)
        assert ctrl.info.status == "ok", ctrl.info.message
        assert np.isfinite(cmd.speed) and np.isfinite(cmd.steer)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"horizon": 1},
        {"dt": 0.0},
        {"solver": "snopt"},
        {"max_iterations": 0},
        {"hessian": "bfgs"},
        {"max_cpu_time": -1.0},
        {"steer_weight": 0.0, "steer_rate_weight": 0.0},
        {"substeps": 0},
    ],
)
def test_config_validation(kwargs):
    with pytest.raises(ParameterError):
        NMPCConfig(**kwargs)
