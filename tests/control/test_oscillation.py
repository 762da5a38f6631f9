"""The damper of the correction's limit cycle (``RKMPCConfig.oscillation``)."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from rkmpc.control import Observation
from rkmpc.control.learned.oscillation import OscillationConfig, OscillationDamper
from rkmpc.control.learned.residual_config import RKMPCConfig
from rkmpc.control.learned.rkmpc import ResidualKoopmanMPC
from rkmpc.core.errors import ParameterError

# A servo of 3.2 rad/s at 20 Hz: the floor is 0.1 * 3.2 * 0.05 = 0.016 rad per step.
MAX_RATE, DT = 3.2, 0.05


def _damper(**changes: object) -> OscillationDamper:
    config = replace(
        OscillationConfig(
            enabled=True, window_steps=10, rate_ratio=4.0, rate_floor=0.1, persist_steps=1, hold_steps=5
        ),
        **changes,
    )
    return OscillationDamper(config, MAX_RATE, DT)


@pytest.mark.parametrize(
    "changes",
    [
        {"enabled": 1},
        {"window_steps": 1},
        {"window_steps": 2.5},
        {"hold_steps": -1},
        {"persist_steps": 0},
        {"rate_ratio": 0.0},
        {"rate_floor": 0.0},
        {"rate_floor": 1.5},
        {"damping_weight": -1.0},
        {"damping_weight": float("nan")},
    ],
)
def test_bad_settings_are_refused_by_name(changes):
    name = next(iter(changes))
    with pytest.raises(ParameterError, match=name):
        OscillationConfig(**changes)  # type: ignore[arg-type]


def test_a_correction_that_swings_while_the_baseline_holds_is_damped_then_released():
    damper = _damper()
    for k in range(10):  # a window's worth: the correction swings by 0.04 rad a step
        assert damper.weight == 0.0
        damper.observe(0.1, 0.02 * (-1) ** k)
    damper.observe(0.1, 0.02)  # the window is full: 0.04 > max(4 * 0, 0.016)
    assert damper.weight == damper.config.damping_weight
    assert damper.onsets == 1
    # It stops swinging: the window's mean stays above the floor for 5 more steps (each re-arms
    # the hold), then the damping lasts `hold_steps` (5) steps: 10 damped in all.
    for j in range(15):
        damper.observe(0.1, 0.02)
        assert (damper.weight > 0.0) == (j < 9)
    assert (damper.steps, damper.onsets) == (10, 1)
    damper.reset()
    assert (damper.steps, damper.onsets, damper.weight) == (0, 0, 0.0)


def test_a_burst_shorter_than_persist_steps_is_left_alone_a_longer_one_is_damped():
    damper = _damper(window_steps=4, persist_steps=8)
    swing = [0.02 * (-1) ** k for k in range(9)]  # the window is full after 5 observations
    for c in swing + [swing[-1]] * 30:  # above the floor on 5 steps and 2 more as it empties
        damper.observe(0.1, c)
    assert damper.onsets == 0
    for k in range(12):  # above it on 10 steps in a row
        damper.observe(0.1, 0.02 * (-1) ** k)
    assert damper.onsets == 1 and damper.weight > 0.0


def test_a_correction_that_moves_with_a_moving_baseline_is_left_alone():
    damper = _damper()
    for k in range(50):  # the LMPC's command swings by 0.1 rad a step, the correction by 0.04
        damper.observe(0.05 * (-1) ** k, 0.02 * (-1) ** k)
    assert (damper.steps, damper.onsets, damper.weight) == (0, 0, 0.0)


def test_small_swings_under_the_floor_are_left_alone():
    damper = _damper()
    for k in range(50):  # 0.01 rad a step < 0.016
        damper.observe(0.1, 0.005 * (-1) ** k)
    assert damper.onsets == 0


def test_by_default_once_it_rang_it_damps_until_reset():
    damper = OscillationDamper(OscillationConfig(enabled=True, window_steps=4, persist_steps=2), MAX_RATE, DT)
    for k in range(6):
        damper.observe(0.0, 0.05 * (-1) ** k)
    for _ in range(5000):  # calm for 250 s
        damper.observe(0.0, 0.0)
    assert (damper.onsets, damper.weight) == (1, 100.0)
    damper.reset()
    assert damper.weight == 0.0


def test_switched_off_it_never_acts():
    damper = _damper(enabled=False)
    for k in range(50):
        damper.observe(0.1, 0.1 * (-1) ** k)
    assert (damper.steps, damper.onsets, damper.weight) == (0, 0, 0.0)


def _model() -> SimpleNamespace:
    """A residual model of a car that is exactly kinematic: ``U_p = U``, on the 5 rkmpc features."""
    return SimpleNamespace(
        A_=0.5 * np.eye(5), B_=np.zeros((5, 2)), C_=np.zeros((2, 5)), D_=np.eye(2), lift=lambda x: x
    )


def _first_correction(sc, swinging: bool) -> tuple[float, ResidualKoopmanMPC]:
    damper = OscillationConfig(enabled=True, window_steps=4, persist_steps=1, damping_weight=50.0)
    config = replace(RKMPCConfig(), oscillation=damper)
    ctrl = ResidualKoopmanMPC(sc.reference, sc.vehicle, _model(), config=config)
    for k in range(6):
        ctrl.oscillation.observe(0.0, (0.05 if swinging else 0.0) * (-1) ** k)
    ctrl.last_correction = np.array([0.0, 0.05])
    p = sc.reference.path.position(3.0)
    obs = Observation(
        x=float(p[0]),
        y=float(p[1]) + 0.05,
        yaw=float(sc.reference.path.heading(3.0)),
        speed=2.0,
        yaw_rate=0.0,
        slip_angle=0.0,
        steer_angle=0.0,
    )
    ctrl.lmpc.step(obs)
    pred = ctrl.lmpc.last_prediction
    assert pred is not None
    plan = pred.plan.reshape(-1)
    ctrl._guard.previous = plan[:2].copy()
    ctrl.step(obs)
    return float(ctrl.last_correction[1]), ctrl


def test_while_damped_the_residual_qp_keeps_the_correction_near_the_last_one(builtin_scenario):
    free, ctrl_free = _first_correction(builtin_scenario, swinging=False)
    damped, ctrl_damped = _first_correction(builtin_scenario, swinging=True)
    assert ctrl_free.oscillation.onsets == 0 and ctrl_damped.oscillation.onsets == 1
    # The last correction was +0.05 rad: the damped QP stays closer to it.
    assert abs(damped - 0.05) < abs(free - 0.05) - 1e-3
    diagnostics = ctrl_damped.diagnostics()
    assert diagnostics["oscillation_onsets"] == 1.0
    assert diagnostics["oscillation_damped_steps"] == 2.0  # the last swinging step and this one


def test_off_by_default_and_absent_from_the_record():
    assert RKMPCConfig().oscillation.enabled is False
    with pytest.raises(ParameterError, match="oscillation"):
        RKMPCConfig(oscillation={"enabled": True})  # type: ignore[arg-type]
