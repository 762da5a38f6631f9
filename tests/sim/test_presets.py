"""Car presets: one tuned LMPC under every controller built on it, residual settings scaled with the car."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from rkmpc.control import make_controller
from rkmpc.control.learned.residual_config import ResidualMPCConfig
from rkmpc.control.learned.rkmpc import PaperResidualKoopmanMPC, ResidualKoopmanMPC
from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.compare import CompareConfig
from rkmpc.sim.collect import excitation_lateral_accel
from rkmpc.sim.scenario import (
    FULLSIZE_LIMITS,
    VEHICLES,
    fullsize_residual,
    load_scenario,
    residual_settings,
)
from rkmpc.vehicle.params import fullsize

LMPC_BASED = ("lmpc", "lmpc-id", "kmpc", "rkmpc", "rkmpc-paper")


def _lmpc_of(name: str, options: dict) -> LMPCConfig:
    return options["lmpc_config"] if name.startswith("rkmpc") else options["config"]


@pytest.mark.parametrize("vehicle", sorted(VEHICLES))
def test_every_lmpc_based_controller_shares_the_lmpc_of_the_preset(vehicle):
    preset = VEHICLES[vehicle]
    lmpc = preset.options_for("lmpc")["config"]
    for name in LMPC_BASED:
        assert _lmpc_of(name, preset.options_for(name)) == lmpc


def test_fullsize_lmpc_is_the_tuned_one_and_f1tenth_keeps_the_defaults():
    assert VEHICLES["fullsize"].options_for("lmpc")["config"] == LMPCConfig(
        steer_weight=1000.0, steer_rate_weight=1000.0, heading_weight=20.0, speed_lead=0.5
    )
    f1tenth = VEHICLES["f1tenth"]
    assert f1tenth.options_for("lmpc")["config"] == LMPCConfig()
    # The 1:10 car's residual settings are the controllers' own defaults, the very objects.
    assert f1tenth.options_for("rkmpc")["config"] is ResidualKoopmanMPC.default_config
    assert f1tenth.options_for("rkmpc-paper")["config"] is PaperResidualKoopmanMPC.default_config


def test_fullsize_residual_settings_grow_with_the_car():
    small = VEHICLES["f1tenth"].options_for("rkmpc")["config"]
    large = VEHICLES["fullsize"].options_for("rkmpc")["config"]
    paper = VEHICLES["fullsize"].options_for("rkmpc-paper")["config"]
    assert large.max_speed_correction > 5.0 * small.max_speed_correction
    assert paper.steer_weight > 50.0 * PaperResidualKoopmanMPC.default_config.steer_weight
    assert small.lateral_accel_weight == 0.0
    assert large.slip_drift and not small.slip_drift


def test_fullsize_rkmpc_prices_steering_by_speed_at_half_the_scaled_settings_at_top_speed():
    scaled, _ = residual_settings(fullsize(), FULLSIZE_LIMITS)
    cfg = VEHICLES["fullsize"].options_for("rkmpc")["config"]
    assert cfg == fullsize_residual(scaled, fullsize(), FULLSIZE_LIMITS)

    def price(speed: float) -> float:  # steering weight per unit position weight at a planned speed
        gain = speed**2 / fullsize().wheelbase
        return (cfg.steer_weight + cfg.lateral_accel_weight * gain**2) / cfg.position_weight

    top = FULLSIZE_LIMITS.max_speed
    assert price(top) == pytest.approx(0.5 * scaled.steer_weight / scaled.position_weight)
    assert price(0.5 * top) < 0.1 * price(top)  # corners at half the top speed: 1/16 of the price
    assert cfg.steer_weight / cfg.position_weight < 0.01 * price(top)


def test_scaled_by_one_is_the_same_settings_and_otherwise_by_the_rules():
    base = ResidualMPCConfig()
    assert base.scaled(1.0, 1.0) is base
    big = base.scaled(2.0, 4.0)
    assert big.steer_weight == pytest.approx(4.0 * base.steer_weight)
    assert big.speed_weight == pytest.approx(base.speed_weight / 4.0)
    assert big.max_speed_correction == pytest.approx(4.0 * base.max_speed_correction)
    assert big.max_steer_correction == base.max_steer_correction
    priced = replace(base, lateral_accel_weight=1.0).scaled(2.0, 4.0)
    assert priced.lateral_accel_weight == pytest.approx((2.0 / 4.0) ** 4)
    with pytest.raises(ParameterError):
        base.scaled(0.0, 1.0)


def _identity_model():
    """A lifted model whose nominal input is the command itself (``U_p = U``)."""
    return SimpleNamespace(
        A_=np.eye(3), B_=np.zeros((3, 2)), C_=np.zeros((2, 3)), D_=np.eye(2), lift=lambda x: np.asarray(x)
    )


@pytest.mark.filterwarnings("ignore:the built-in track")  # builds the controllers, drives nothing
def test_rkmpc_on_the_fullsize_car_drives_on_the_tuned_lmpc():
    sc = load_scenario("builtin", vehicle="fullsize")
    preset = VEHICLES["fullsize"]
    controller = make_controller(
        "rkmpc", sc.reference, sc.vehicle, **preset.options_for("rkmpc"), model=_identity_model()
    )
    assert controller.lmpc.config == preset.options_for("lmpc")["config"]
    assert controller.config == preset.options_for("rkmpc")["config"]


def test_compare_takes_the_residual_settings_of_the_car_unless_given():
    fullsize = CompareConfig(track="builtin", vehicle="fullsize")
    assert fullsize.residual_config("rkmpc") == VEHICLES["fullsize"].options_for("rkmpc")["config"]
    assert (
        fullsize.residual_config("rkmpc-paper") == VEHICLES["fullsize"].options_for("rkmpc-paper")["config"]
    )
    given = ResidualMPCConfig(max_speed_correction=2.0)
    assert CompareConfig(track="builtin", vehicle="fullsize", rkmpc=given).residual_config("rkmpc") is given
    small = CompareConfig(track="builtin")
    assert small.residual_config("rkmpc") is ResidualKoopmanMPC.default_config


@pytest.mark.filterwarnings("ignore:the built-in track")  # builds the controllers, drives nothing
def test_excitation_asks_twice_the_profile_limit_at_most_the_grip():
    assert excitation_lateral_accel(load_scenario("builtin")) == 8.0
    full = load_scenario("builtin", vehicle="fullsize")
    assert excitation_lateral_accel(full) == pytest.approx(full.vehicle.mu * full.vehicle.gravity)


def test_a_misspelt_track_name_suggests_the_built_in_ones():
    with pytest.raises(ValueError, match=r"unknown track 'bultin'.*did you mean 'builtin'"):
        load_scenario("bultin")
    with pytest.raises(ValueError, match=r"built-in tracks: builtin, oval"):
        load_scenario("monza")


def test_the_full_size_car_on_a_built_in_track_is_warned_about():
    with pytest.warns(UserWarning, match="made at 1:10"):
        load_scenario("builtin", vehicle="fullsize")
