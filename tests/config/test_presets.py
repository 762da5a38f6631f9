"""The packaged car presets: their values, the scaling rules that made the full-size ones, one LMPC under all.

``rkmpc/config/presets/fullsize.toml`` writes out numbers made by :mod:`rkmpc.config.scaling` from
the 1:10 car's settings; the tests here recompute every one of them, so the file and the rules
cannot drift apart, and check that each preset gives the values the code computed before the
presets became files.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from rkmpc.config.loader import PRESETS, load_preset
from rkmpc.config.scaling import carry_over, speed_priced
from rkmpc.control import make_controller
from rkmpc.control.learned.lateral_guard import LateralGuardConfig
from rkmpc.control.learned.oscillation import OscillationConfig
from rkmpc.control.learned.residual_config import PAPER_RESIDUAL, ResidualMPCConfig, RKMPCConfig
from rkmpc.control.learned.rkmpc import PaperResidualKoopmanMPC, ResidualKoopmanMPC
from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import ParameterError
from rkmpc.core.registry import UnknownNameError
from rkmpc.experiments.compare import CompareConfig
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.sim.build import build_controller
from rkmpc.track.speed_profile import SpeedLimits
from rkmpc.vehicle.params import f1tenth, fullsize

LMPC_BASED = ("lmpc", "lmpc-id", "kmpc", "rkmpc", "rkmpc-paper")

#: The speed-profile limits the code gave each car before the presets were files.
F1TENTH_LIMITS = SpeedLimits(
    lateral_accel=4.0, brake_decel=2.5, accel=2.5, max_speed=3.5, min_speed=0.5, curvature_rate=1.0
)
FULLSIZE_LIMITS = SpeedLimits(
    lateral_accel=5.0, brake_decel=2.5, accel=2.0, max_speed=25.0, min_speed=2.0, curvature_rate=0.05
)


def _identity_model(nx: int) -> SimpleNamespace:
    """A lifted model whose nominal input is the command itself (``U_p = U``)."""
    return SimpleNamespace(
        A_=np.eye(nx), B_=np.zeros((nx, 2)), C_=np.zeros((2, nx)), D_=np.eye(2), lift=lambda x: np.asarray(x)
    )


def _state_model(nx: int) -> SimpleNamespace:
    """A lifted model that outputs its state (rkmpc-paper's: ``y = z``)."""
    return SimpleNamespace(
        A_=np.eye(nx), B_=np.zeros((nx, 2)), C_=np.eye(nx), D_=np.zeros((nx, 2)), lift=lambda x: np.asarray(x)
    )


#: A stand-in model for every learned controller (nothing is driven).
MODELS = {
    "lmpc-id": IdentifiedModel(0.158, 0.005, 1.0, 1.0, 100),
    "kmpc": _state_model(6),
    "rkmpc": _identity_model(5),
    "rkmpc-paper": _state_model(3),
}


def _lmpc_of(controller) -> LMPCConfig:
    return controller.lmpc.config if controller.name.startswith("rkmpc") else controller.config


# ---------------------------------------------------------------------------- the presets' values


def test_the_presets_are_the_two_cars():
    assert list(PRESETS) == ["f1tenth", "fullsize"]
    with pytest.raises(UnknownNameError, match="unknown car preset 'kart'; known: f1tenth, fullsize"):
        load_preset("kart")
    f1, full = load_preset("f1tenth"), load_preset("fullsize")
    assert (f1.preset, f1.vehicle, f1.file_scale, f1.plant.model, f1.plant.car) == (
        "f1tenth",
        f1tenth(),
        0.1,
        "f1tenth",
        None,
    )
    assert (full.preset, full.vehicle, full.file_scale, full.plant.model) == (
        "fullsize",
        fullsize(),
        1.0,
        "fullsize",
    )
    assert load_preset("f1tenth") is f1  # read once


def test_the_f1tenth_preset_keeps_the_limits_and_the_controllers_defaults():
    car = load_preset("f1tenth")
    limits = car.limits
    assert (
        limits.lateral_accel,
        limits.brake_decel,
        limits.accel,
        limits.max_speed,
        limits.min_speed,
        limits.curvature_rate,
    ) == (4.0, 2.5, 2.5, 3.5, 0.5, 1.0)
    assert limits == F1TENTH_LIMITS
    # The 1:10 car's settings are the controllers' own defaults, but rkmpc's: its preset tunes it
    # (on the built-in track and the oval) with the slip drift, heavier position and heading weights,
    # the lateral guard, the oscillation damper and the retimed reference.
    assert car.controllers == replace(ControllerSettings(), rkmpc=car.controllers.rkmpc)
    assert car.controllers.lmpc == LMPCConfig()
    assert car.controllers.rkmpc == replace(
        RKMPCConfig(),
        position_weight=2.0,
        heading_weight=3.0,
        slip_drift=True,
        slip_velocity_limit=0.5,
        lateral_guard=LateralGuardConfig(enabled=True),
        oscillation=OscillationConfig(enabled=True),
        retimed=True,
    )
    assert ResidualKoopmanMPC.default_config == RKMPCConfig()
    assert car.controllers.rkmpc_paper == PaperResidualKoopmanMPC.default_config == PAPER_RESIDUAL
    assert car.controllers.rkmpc.lateral_accel_weight == 0.0


def test_the_fullsize_preset_gives_the_tuned_values():
    car = load_preset("fullsize")
    assert car.limits == FULLSIZE_LIMITS
    assert car.controllers.lmpc == LMPCConfig(
        steer_weight=1000.0, steer_rate_weight=1000.0, heading_weight=20.0, speed_lead=0.5
    )
    assert car.controllers.rkmpc == replace(
        RKMPCConfig(),
        position_weight=8.0,
        steer_weight=2.0,
        speed_weight=0.6915484944565736,
        max_speed_correction=7.142857142857143,
        lateral_accel_weight=0.009577639650827769,
        slip_drift=True,
    )
    assert car.controllers.rkmpc_paper == replace(
        PAPER_RESIDUAL,
        heading_weight=5.0,
        speed_weight=6.915484944565736,
        steer_weight=352830.8645186601,
        max_speed_correction=7.142857142857143,
    )
    assert type(car.controllers.rkmpc_paper) is ResidualMPCConfig
    pp = car.controllers.pp
    assert (pp.min_lookahead, pp.lookahead_gain, pp.max_lookahead) == (3.0, 0.8, 40.0)


# ---------------------------------------------------------------------------- the scaling rules


def _close(a: float, b: float) -> bool:
    return a == b or abs(a - b) <= 1e-12 * max(1.0, abs(a), abs(b))  # a == b: equal infinities


def _assert_same_settings(computed, preset) -> None:
    """Every numeric field equal to 1e-12 (relative), the others exactly."""
    assert type(computed) is type(preset)
    for name, value in vars(preset).items():
        mine = getattr(computed, name)
        if isinstance(value, float):
            assert _close(mine, value), (name, mine, value)
        else:
            assert mine == value, (name, mine, value)


def test_the_scaling_rules_recompute_the_fullsize_preset_from_the_f1tenth_one():
    small, large = load_preset("f1tenth"), load_preset("fullsize")
    args = (small.vehicle, small.limits, large.vehicle, large.limits)
    # From the controllers' defaults: the 1:10 preset's own tuning of rkmpc (weights, guard) is not
    # carried over; the full-size car was tuned on its own tracks.
    scaled = carry_over(RKMPCConfig(), *args)
    priced = speed_priced(scaled, large.vehicle, large.limits, position_weight=8.0, top_price=4.0, floor=2.0)
    _assert_same_settings(priced, large.controllers.rkmpc)
    _assert_same_settings(carry_over(small.controllers.rkmpc_paper, *args), large.controllers.rkmpc_paper)


def test_carried_over_to_the_same_car_the_settings_are_the_same_objects():
    car = load_preset("f1tenth")
    settings = car.controllers.rkmpc
    assert carry_over(settings, car.vehicle, car.limits, car.vehicle, car.limits) is settings
    paper = car.controllers.rkmpc_paper
    assert carry_over(paper, car.vehicle, car.limits, car.vehicle, car.limits) is paper


def test_fullsize_residual_settings_grow_with_the_car():
    small = load_preset("f1tenth").controllers
    large = load_preset("fullsize").controllers
    assert large.rkmpc.max_speed_correction > 5.0 * small.rkmpc.max_speed_correction
    assert large.rkmpc_paper.steer_weight > 50.0 * PaperResidualKoopmanMPC.default_config.steer_weight
    assert small.rkmpc.lateral_accel_weight == 0.0 and large.rkmpc.lateral_accel_weight > 0.0
    assert large.rkmpc.slip_drift and small.rkmpc.slip_drift
    assert small.rkmpc.lateral_guard.enabled and not large.rkmpc.lateral_guard.enabled


def test_fullsize_rkmpc_prices_steering_by_speed_at_half_the_scaled_settings_at_top_speed():
    small, large = load_preset("f1tenth"), load_preset("fullsize")
    scaled = carry_over(RKMPCConfig(), small.vehicle, small.limits, large.vehicle, large.limits)
    cfg = large.controllers.rkmpc

    def price(speed: float) -> float:  # steering weight per unit position weight at a planned speed
        gain = speed**2 / fullsize().wheelbase
        return (cfg.steer_weight + cfg.lateral_accel_weight * gain**2) / cfg.position_weight

    top = FULLSIZE_LIMITS.max_speed
    assert price(top) == pytest.approx(0.5 * scaled.steer_weight / scaled.position_weight)
    assert price(0.5 * top) < 0.1 * price(top)  # corners at half the top speed: 1/16 of the price
    assert cfg.steer_weight / cfg.position_weight < 0.01 * price(top)


def test_scaled_by_one_is_the_same_settings_and_otherwise_by_the_rules():
    base = RKMPCConfig()
    assert base.scaled(1.0, 1.0) is base
    big = base.scaled(2.0, 4.0)
    assert type(big) is RKMPCConfig
    assert big.steer_weight == pytest.approx(4.0 * base.steer_weight)
    assert big.speed_weight == pytest.approx(base.speed_weight / 4.0)
    assert big.max_speed_correction == pytest.approx(4.0 * base.max_speed_correction)
    assert big.max_steer_correction == base.max_steer_correction
    priced = replace(base, lateral_accel_weight=1.0).scaled(2.0, 4.0)
    assert priced.lateral_accel_weight == pytest.approx((2.0 / 4.0) ** 4)
    paper = PAPER_RESIDUAL.scaled(2.0, 4.0)
    assert type(paper) is ResidualMPCConfig and paper.steer_weight == pytest.approx(
        4.0 * PAPER_RESIDUAL.steer_weight
    )
    with pytest.raises(ParameterError):
        base.scaled(0.0, 1.0)


# ---------------------------------------------------------------------------- one LMPC under all


@pytest.mark.parametrize("vehicle", sorted(PRESETS))
@pytest.mark.filterwarnings("ignore:the built-in track")  # builds the controllers, drives nothing
def test_every_lmpc_based_controller_shares_the_lmpc_of_the_preset(vehicle):
    car = load_preset(vehicle)
    from rkmpc.sim.scenario import Scenario

    scenario = Scenario.from_car(car, "builtin")
    lmpc = car.controllers.lmpc
    for name in LMPC_BASED:
        controller = make_controller(
            name, scenario.reference, scenario.vehicle, settings=car.controllers, model=MODELS.get(name)
        )
        assert _lmpc_of(controller) == lmpc, name


@pytest.mark.filterwarnings("ignore:the built-in track")  # builds the controllers, drives nothing
def test_rkmpc_on_the_fullsize_car_drives_on_the_tuned_lmpc():
    from rkmpc.sim.scenario import load_scenario

    sc = load_scenario("builtin", vehicle="fullsize")
    car = load_preset("fullsize")
    assert sc.car == car
    controller = build_controller("rkmpc", sc, _identity_model(5))
    assert controller.lmpc.config == car.controllers.lmpc
    assert controller.config == car.controllers.rkmpc
    paper = build_controller("rkmpc-paper", sc, _state_model(3))
    assert paper.config == car.controllers.rkmpc_paper


def test_compare_takes_the_residual_settings_of_the_car_unless_given():
    car = load_preset("fullsize")
    config = CompareConfig(track="builtin", car=car)
    assert config.car.controllers.rkmpc == car.controllers.rkmpc
    assert config.car.controllers.rkmpc_paper == car.controllers.rkmpc_paper
    given = RKMPCConfig(max_speed_correction=2.0)
    mine = replace(car, controllers=replace(car.controllers, rkmpc=given))
    assert CompareConfig(track="builtin", car=mine).car.controllers.rkmpc is given
    small = CompareConfig(track="builtin")
    assert small.car.controllers.rkmpc == load_preset("f1tenth").controllers.rkmpc
    # rkmpc's settings are not rkmpc-paper's: given the wrong kind, the car refuses them.
    with pytest.raises(
        ParameterError, match=r"rkmpc_paper \(\[controllers\.rkmpc-paper\]\) must be a ResidualMPCConfig"
    ):
        replace(car.controllers, rkmpc_paper=given)
    with pytest.raises(ParameterError, match=r"must be a RKMPCConfig"):
        replace(car.controllers, rkmpc=PAPER_RESIDUAL)
