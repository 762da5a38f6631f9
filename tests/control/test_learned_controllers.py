import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from rkmpc.analysis.metrics import lap_metrics
from rkmpc.control import Observation, make_controller
from rkmpc.control.learned.adaptation import AdaptationConfig
from rkmpc.control.learned.residual_config import RKMPCConfig
from rkmpc.control.learned.rkmpc import PaperResidualKoopmanMPC, ResidualKoopmanMPC
from rkmpc.control.learned.trust import TrustConfig
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.runs import run_controller
from rkmpc.learning.data.augmentation import AugmentConfig
from rkmpc.learning.identification import identify
from rkmpc.learning.pipeline import TrainConfig, train_model
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.collect import collect, collect_excitation
from rkmpc.sim.run import RunSpec
from rkmpc.vehicle.registry import make_plant

# The module trains four models (about 10 s) and drives laps with them.
pytestmark = pytest.mark.slow


def _train(data, wheelbase, kind, epochs, ratio=0.3):
    model = recipe_of_kind(kind).koopman().default_model(seed=0, epochs=epochs)
    return train_model(
        data, wheelbase, TrainConfig(kind=kind, augment=AugmentConfig(ratio=ratio), model=model)
    )


@pytest.fixture(scope="module")
def learned(builtin_scenario):
    sc = builtin_scenario
    data = collect(sc, laps=2)
    L = sc.vehicle.wheelbase
    residual, report = _train(data, L, "residual", epochs=60)
    paper, _ = _train(data, L, "paper", epochs=5)
    excitation = collect_excitation(sc, n_samples=3000)
    koopman, _ = _train(excitation, L, "koopman", epochs=5, ratio=0.1)
    return {
        "data": data,
        "report": report,
        "lmpc-id": identify(data, sc.vehicle),
        "rkmpc": residual,
        "rkmpc-paper": paper,
        "kmpc": koopman,
    }


def test_training_report_counts(learned):
    report = learned["report"]
    assert report.raw_count == len(learned["data"])
    assert report.augmented_count == 35 * round(0.3 * (report.raw_count - 34))
    assert len(report.multi_step_error) > 0


def test_identification_finds_the_plant_servo(learned):
    ident = learned["lmpc-id"]
    # The plant's servo time constant is 0.158 s; the car understeers.
    assert ident.servo_time_constant == pytest.approx(0.158, rel=0.05)
    # The plant's servo is the nominal one: no fitted structure predicts the held-out wheel angle
    # better, so the nominal lag is kept (and said); the understeer gradient is identified.
    assert (ident.servo_structure, ident.servo_delay, ident.servo_rate_limit) == ("nominal", 0.0, None)
    assert [w.split(":")[0] for w in ident.warnings] == ["servo"]
    assert ident.status == "identified" and ident.understeer_gradient > 0.003
    assert ident.error_ratio < 0.5  # the held-out yaw rate, K against K = 0


@pytest.mark.parametrize("name", ["lmpc-id", "kmpc", "rkmpc", "rkmpc-paper"])
def test_short_closed_loop_runs(builtin_scenario, learned, name):
    sc = builtin_scenario
    ctrl = make_controller(name, sc.reference, sc.vehicle, model=learned[name])
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference, SimConfig(max_time=3.0))
    commands = np.column_stack([result.log["cmd_speed"], result.log["cmd_steer"]])
    assert np.all(np.isfinite(commands[:-1]))
    assert np.all(np.abs(commands[:-1, 1]) <= sc.vehicle.steering.max_angle + 1e-9)
    assert result.progress > 0.05
    if name != "kmpc":  # the five-epoch KMPC may leave a tight track; the others must not
        assert result.outcome == "timeout"


def test_rkmpc_and_lmpc_id_beat_lmpc_on_builtin(builtin_scenario, learned):
    sc = builtin_scenario
    _, lmpc = run_controller(sc, RunSpec("lmpc"))
    _, lmpc_id = run_controller(sc, RunSpec("lmpc-id"), model=learned["lmpc-id"])
    _, rkmpc = run_controller(sc, RunSpec("rkmpc"), model=learned["rkmpc"])
    assert rkmpc["completed"] and lmpc_id["completed"]
    for key in ("lateral_error_mean_m", "heading_error_mean_rad", "steer_rate_mean_rad_s"):
        assert rkmpc[key] < 0.8 * lmpc[key], key
    # Since lmpc-id models the servo's delay and rate and the wheel reference's drift (issue 11)
    # it tracks the built-in track about as well as rkmpc (0.017 against 0.018 m): both must beat
    # the LMPC clearly; which of the two is ahead is a result, reported, not asserted.
    assert lmpc_id["lateral_error_mean_m"] < 0.8 * lmpc["lateral_error_mean_m"]
    assert lmpc_id["heading_error_mean_rad"] < 0.8 * lmpc["heading_error_mean_rad"]


def test_rkmpc_without_measured_wheel_angle_falls_back_to_lmpc(builtin_scenario, learned):
    sc = builtin_scenario
    ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, learned["rkmpc"])
    lmpc = make_controller("lmpc", sc.reference, sc.vehicle)
    p = sc.reference.path.position(4.0)
    obs = Observation(
        x=float(p[0]),
        y=float(p[1]),
        yaw=float(sc.reference.path.heading(4.0)),
        speed=2.0,
        yaw_rate=0.1,
        steer_angle=math.nan,
    )
    cmd, base = ctrl.step(obs), lmpc.step(obs)
    assert ctrl.info.status == "guard" and ctrl.fallback_count == 1
    assert cmd.steer == pytest.approx(base.steer) and cmd.speed == pytest.approx(base.speed)


def test_lap_metrics_of_learned_run_are_complete(builtin_scenario, learned):
    sc = builtin_scenario
    ctrl = make_controller("rkmpc", sc.reference, sc.vehicle, model=learned["rkmpc"])
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference, SimConfig(max_time=2.0))
    metrics = lap_metrics(result)
    assert metrics["solve_ms_mean"] > 0 and metrics["fallback_count"] == 0


def _observations(sc, n=10):
    path = sc.reference.path
    for s in np.linspace(1.0, 15.0, n):
        p = path.position(s)
        yaw = float(path.heading(s))
        yield Observation(
            x=float(p[0]) + 0.05 * math.sin(yaw),
            y=float(p[1]) - 0.05 * math.cos(yaw),
            yaw=yaw + 0.05,
            speed=2.0,
            yaw_rate=0.2,
            steer_angle=0.05,
        )


def test_rkmpc_factorised_qps_match_daqp_factorising_them(builtin_scenario, learned):
    # Both QPs of RKMPC have Hessians that change every step and are factorised with LAPACK;
    # with DAQP factorising them itself, the commands are the same.
    from rkmpc.control.qp import make_qp

    sc = builtin_scenario
    fast = make_controller("rkmpc", sc.reference, sc.vehicle, model=learned["rkmpc"])
    plain = make_controller("rkmpc", sc.reference, sc.vehicle, model=learned["rkmpc"])
    plain._qp = make_qp("daqp", max_iterations=plain.config.max_iterations)
    plain.lmpc._qp = make_qp("daqp", max_iterations=plain.lmpc.config.max_iterations)
    for obs in _observations(sc):
        a, b = fast.step(obs), plain.step(obs)
        assert fast.info.status == plain.info.status == "ok"
        assert a.speed == pytest.approx(b.speed, rel=1e-9, abs=1e-12)
        assert a.steer == pytest.approx(b.steer, rel=1e-9, abs=1e-12)


def test_kmpc_gradient_equals_the_textbook_formula(builtin_scenario, learned):
    # KMPC assembles its gradient from precomputed, doubled terms; check it against the plain formula.
    from rkmpc.control.learned.lifted import reference_in_local_frame
    from rkmpc.learning.features import KMPC_STATE

    sc = builtin_scenario
    ctrl = make_controller("kmpc", sc.reference, sc.vehicle, model=learned["kmpc"])
    seen = []
    update = ctrl._qp.update

    def spy(**kwargs):
        seen.append(kwargs["f"].copy())
        update(**kwargs)

    ctrl._qp.update = spy
    p, n = ctrl.problem, ctrl.config.horizon
    for obs in _observations(sc, n=4):
        previous = None if ctrl._guard.previous is None else ctrl._guard.previous.copy()
        ctrl.step(obs)
        if previous is None:
            continue
        ref = sc.reference.horizon(ctrl.projection.s, n, ctrl.config.dt)
        u_ref = np.column_stack([ref.v[:n], ref.delta[:n]]).ravel()
        local = reference_in_local_frame(ref, obs).ravel()
        d0 = np.zeros(2 * n)
        d0[:2] = previous
        z0 = learned["kmpc"].lift(KMPC_STATE.of_observation(obs))
        f = 2.0 * (ctrl._MtQ @ (ctrl._Mz @ z0 - local) - p.r_diag * u_ref - p.D.T @ (p.w_rate * d0))
        np.testing.assert_allclose(seen[-1], f, rtol=1e-12, atol=1e-12)
    assert len(seen) == 3


def test_trust_guard_fades_the_correction_outside_the_training_range(builtin_scenario, learned):
    sc = builtin_scenario
    model = learned["rkmpc"]
    cfg = replace(ResidualKoopmanMPC.default_config, trust=TrustConfig())
    ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, model, config=cfg)
    lmpc = make_controller("lmpc", sc.reference, sc.vehicle)
    p = sc.reference.path.position(4.0)
    span = model.x_max_[0] - model.x_min_[0]
    fast = float(model.x_max_[0] + 0.5 * span)  # half a span faster than any training speed
    obs = Observation(
        x=float(p[0]),
        y=float(p[1]),
        yaw=float(sc.reference.path.heading(4.0)),
        speed=fast,
        yaw_rate=0.0,
        steer_angle=0.0,
    )
    cmd, base = ctrl.step(obs), lmpc.step(obs)
    assert ctrl.trust is not None and ctrl.trust.trust == 0.0
    assert ctrl.diagnostics()["trust_faded_range"] == 1.0
    assert cmd.steer == pytest.approx(base.steer) and cmd.speed == pytest.approx(base.speed)


def test_adaptation_learns_on_the_car_and_stays_finite(builtin_scenario, learned):
    sc = builtin_scenario
    cfg = replace(ResidualKoopmanMPC.default_config, adaptation=AdaptationConfig(enabled=True))
    ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, learned["rkmpc"], config=cfg)
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference, SimConfig(max_time=3.0))
    assert result.diagnostics["rls_updates"] > 40
    commands = np.column_stack([result.log["cmd_speed"], result.log["cmd_steer"]])
    assert np.all(np.isfinite(commands[:-1]))
    assert result.outcome == "timeout"


def test_steering_rate_weight_smooths_the_correction(builtin_scenario, learned):
    # The weight acts on the step-to-step change of the steering CORRECTION (not of the whole
    # command: on this car it even lets the command move more, see issue 11's note).
    sc = builtin_scenario
    changes = []
    for weight in (0.0, 20.0):
        cfg = replace(ResidualKoopmanMPC.default_config, steer_rate_weight=weight)
        ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, learned["rkmpc"], config=cfg)
        plant = make_plant("f1tenth")
        p = sc.reference.path.position(0.0)
        plant.reset(float(p[0]), float(p[1]), float(sc.reference.path.heading(0.0)), 2.0)
        corrections = []
        for _ in range(120):
            command = ctrl.step(plant.observe())
            corrections.append(ctrl.last_correction[1])
            plant.step(command, sc.dt)
        changes.append(float(np.mean(np.abs(np.diff(corrections)))))
    assert changes[1] < changes[0]


def _on_the_line_at(sc, s: float) -> Observation:
    """The car on the reference line at arc length ``s``, heading along it at 2 m/s, wheels straight."""
    p = sc.reference.path.position(s)
    return Observation(
        x=float(p[0]),
        y=float(p[1]),
        yaw=float(sc.reference.path.heading(s)),
        speed=2.0,
        yaw_rate=0.0,
        steer_angle=0.0,
    )


def test_steering_rate_weight_pulls_the_first_correction_to_the_last_one(builtin_scenario, learned):
    # w (d_0 - d_last)^2: with a weight that dominates every other term, the first steering
    # correction stays at the one applied last (the linear term reaches the QP), not at 0.
    sc = builtin_scenario
    obs = _on_the_line_at(sc, 4.0)
    firsts = []
    for last in (0.05, -0.05):
        cfg = replace(
            ResidualKoopmanMPC.default_config, steer_rate_weight=1e6, trust=TrustConfig(enabled=False)
        )
        ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, learned["rkmpc"], config=cfg)
        ctrl.last_correction = np.array([0.0, last])
        ctrl.step(obs)
        firsts.append(float(ctrl.last_correction[1]))
    assert firsts == pytest.approx([0.05, -0.05], abs=1e-3)


def test_lateral_acceleration_weight_prices_steering_by_the_planned_speed(builtin_scenario, learned):
    # The residual Hessian gains 2 * w * (v_k**2 / L)**2 on the k-th steering correction, nothing else.
    sc = builtin_scenario
    obs = _on_the_line_at(sc, 4.0)
    hessians, plans = [], []
    for weight in (0.0, 0.003):
        cfg = replace(ResidualKoopmanMPC.default_config, lateral_accel_weight=weight)
        ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, learned["rkmpc"], config=cfg)
        ctrl.lmpc.step(obs)
        pred = ctrl.lmpc.last_prediction
        assert pred is not None
        H, _ = ctrl._residual_qp(obs, pred, pred.plan.reshape(-1))
        hessians.append(H.copy())
        plans.append(pred.plan.copy())
    np.testing.assert_allclose(plans[0], plans[1])
    extra = hessians[1] - hessians[0]
    gain = plans[0][:, 0] ** 2 / sc.vehicle.wheelbase
    np.testing.assert_allclose(np.diag(extra)[1::2], 2.0 * 0.003 * gain**2, rtol=1e-9)
    np.testing.assert_allclose(extra - np.diag(np.diag(extra)), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.diag(extra)[0::2], 0.0, atol=1e-12)
    assert gain.max() > 5.0  # the planned speeds make the term matter


def test_lateral_acceleration_weight_must_not_be_negative():
    with pytest.raises(ParameterError, match="lateral_accel_weight"):
        replace(ResidualKoopmanMPC.default_config, lateral_accel_weight=-1.0)


def test_rkmpc_paper_refuses_a_speed_priced_steering_weight(builtin_scenario):
    # rkmpc-paper's settings have no speed-priced steering; rkmpc's, which have, are refused by it.
    with pytest.raises(TypeError, match="lateral_accel_weight"):
        replace(PaperResidualKoopmanMPC.default_config, lateral_accel_weight=0.01)
    sc = builtin_scenario
    paper = PaperResidualKoopmanMPC.default_config
    cfg = RKMPCConfig(
        heading_weight=paper.heading_weight,
        speed_weight=paper.speed_weight,
        steer_weight=paper.steer_weight,
        lateral_accel_weight=0.01,
    )
    model = SimpleNamespace(A_=np.eye(3), B_=np.zeros((3, 2)), C_=np.eye(3), lift=np.asarray)
    with pytest.raises(ParameterError, match="rkmpc-paper takes a ResidualMPCConfig, got RKMPCConfig"):
        PaperResidualKoopmanMPC(sc.reference, sc.vehicle, model, config=cfg)
