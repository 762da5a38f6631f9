"""nmpc-id: the dynamic NMPC on identified tyres and servo, one SQP iteration per period."""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.control.nonlinear.models import dynamic_ode, tyre_force
from rkmpc.control.nonlinear.nmpc_id import IdentifiedDynamicNMPC
from rkmpc.control.registry import make_controller
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import IdentificationWarning, ParameterError
from rkmpc.core.observation import Observation
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.learning.tyre_model import AxleCurve, IdentifiedTyres
from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.tyres import LinearTyre, PacejkaTyre, TyreModel


def _model(wheel: str = "measured", delay: float = 0.0, servo: str = "identified") -> IdentifiedModel:
    tyres = IdentifiedTyres(
        structure="linear",
        front=AxleCurve.linear(4.0),
        rear=AxleCurve.linear(6.0),
        status="identified",
        status_reason="test",
        fitted_on="slip_angle",
        wheel=wheel,
        servo=servo,
        n_samples=500,
        folds=5,
    )
    structure = "delay-lag" if delay else "lag"
    return IdentifiedModel(0.1, 0.01, 0.9, 0.9, 500, structure, delay, status="identified", tyres=tyres)


def test_the_casadi_force_laws_are_the_tyres_own():
    vehicle = f1tenth()
    for tyre in (PacejkaTyre(vehicle.tyre_front), LinearTyre(4.7)):
        for alpha in (-0.2, 0.03, 0.15):
            assert float(tyre_force(tyre, alpha, 17.0)) == pytest.approx(tyre.build()(alpha, 17.0, 1.0))

    class Cubic(TyreModel):
        def build(self):  # pragma: no cover - never called
            raise NotImplementedError

    with pytest.raises(ParameterError, match="no CasADi force law for the tyre model Cubic"):
        tyre_force(Cubic(), 0.1, 1.0)


def test_the_dynamic_model_takes_the_tyres_given():
    vehicle = f1tenth()
    x = np.array([0.0, 0.0, 0.1, 3.0, 0.02, 0.8, 0.1])
    u = np.array([3.2, 0.12])
    nominal = np.asarray(dynamic_ode(vehicle)(x, u)).ravel()
    same = np.asarray(
        dynamic_ode(vehicle, tyres=(PacejkaTyre(vehicle.tyre_front), PacejkaTyre(vehicle.tyre_rear)))(x, u)
    )
    np.testing.assert_allclose(same.ravel(), nominal)
    stiff = np.asarray(dynamic_ode(vehicle, tyres=(LinearTyre(40.0), LinearTyre(40.0)))(x, u)).ravel()
    assert not np.allclose(stiff[4:6], nominal[4:6])  # side slip and yaw rate answer the tyres
    np.testing.assert_allclose(stiff[[0, 1, 2, 3, 6]], nominal[[0, 1, 2, 3, 6]])


def test_nmpc_id_is_the_real_time_dynamic_nmpc_on_the_identified_model(builtin_scenario):
    sc = builtin_scenario
    with pytest.raises(ParameterError, match="needs model="):
        make_controller("nmpc-id", sc.reference, sc.vehicle)
    with pytest.raises(ParameterError, match="with tyres"):
        IdentifiedDynamicNMPC(sc.reference, sc.vehicle, replace(_model(), tyres=None))
    model = _model(delay=0.02)
    ctrl = make_controller("nmpc-id", sc.reference, sc.vehicle, settings=ControllerSettings(), model=model)
    assert isinstance(ctrl, IdentifiedDynamicNMPC)
    assert (ctrl.config.solver, ctrl.config.max_iterations) == ("sqpmethod", 1)
    assert ctrl.vehicle.steering.time_constant == pytest.approx(0.12)  # the lag with the delay folded in
    # Its model holds the identified linear tyres (mu folded in).
    x, u = np.array([0.0, 0.0, 0.0, 3.0, 0.01, 0.5, 0.1]), np.array([3.0, 0.1])
    expected = dynamic_ode(ctrl.vehicle, ctrl.min_speed, tyres=(LinearTyre(4.0), LinearTyre(6.0)))(x, u)
    np.testing.assert_allclose(np.asarray(ctrl._ode()(x, u)), np.asarray(expected))
    path = sc.reference.path
    p = path.position(5.0)
    obs = Observation(x=float(p[0]), y=float(p[1]), yaw=float(path.heading(5.0)), speed=3.0, yaw_rate=0.4)
    command = ctrl.step(obs)
    assert math.isfinite(command.speed) and math.isfinite(command.steer)
    # Without a side-slip measurement the state starts from the rear tyres' steady state.
    state = ctrl._initial_state(obs, obs.yaw)
    assert state[4] == pytest.approx(
        math.atan(sc.vehicle.lr * 0.4 / state[3] - state[3] * 0.4 / (9.81 * 6.0)), rel=1e-3
    )


def test_a_wheel_run_from_commands_ignores_the_measured_one(builtin_scenario):
    sc = builtin_scenario
    obs = Observation(x=0.0, y=0.0, yaw=0.0, speed=3.0, steer_angle=0.2)
    measured = IdentifiedDynamicNMPC(sc.reference, sc.vehicle, _model("measured"))
    commands = IdentifiedDynamicNMPC(sc.reference, sc.vehicle, _model("commands"))
    assert measured._wheel_measurement(obs) == 0.2
    assert math.isnan(commands._wheel_measurement(obs))
    # The wheel is run through the servo the tyres were identified with.
    servos = {
        source: IdentifiedDynamicNMPC(sc.reference, sc.vehicle, _model("commands", 0.03, source)).servo
        for source in ("identified", "lag", "nominal")
    }
    assert (servos["identified"].delay, servos["identified"].time_constant) == (0.03, 0.1)
    assert (servos["lag"].delay, servos["lag"].time_constant) == (0.0, 0.1)
    assert (servos["nominal"].delay, servos["nominal"].time_constant) == (0.0, 0.158)


@pytest.mark.slow
def test_nmpc_id_learns_from_two_laps_and_beats_the_lmpc_on_the_gym_car():
    from rkmpc.experiments.runs import run_controller
    from rkmpc.learning.learn import learn
    from rkmpc.learning.recipes import recipe_for
    from rkmpc.sim.collect import collect
    from rkmpc.sim.run import RunSpec
    from rkmpc.sim.scenario import load_scenario

    sc = load_scenario("builtin", car="gym")
    data = collect(sc, controller="lmpc", laps=2, seed=0)
    recipe = recipe_for("nmpc-id")
    assert recipe is not None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentificationWarning)
        learned = learn(recipe, data, made_for=replace(sc.provenance(), scale=None), vehicle=sc.vehicle)
    model = learned.model
    assert isinstance(model, IdentifiedModel) and model.tyres is not None
    assert model.tyres.status == "identified"  # the gym's linear tyres are not the nominal Pacejka ones
    _, lmpc = run_controller(sc, RunSpec("lmpc"))
    _, nmpc_id = run_controller(sc, RunSpec("nmpc-id"), model=model)
    assert nmpc_id["completed"] and nmpc_id["fallback_count"] == 0
    assert nmpc_id["lateral_error_mean_m"] < 0.8 * lmpc["lateral_error_mean_m"]
