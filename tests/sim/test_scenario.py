"""A scenario: a car (a :class:`CarConfig`) put on a track, what it drives and what models must match."""

from __future__ import annotations

from dataclasses import replace

import pytest

from rkmpc.config.loader import load_preset
from rkmpc.learning.contract import Provenance
from rkmpc.sim.collect import excitation_lateral_accel
from rkmpc.sim.scenario import Scenario, load_scenario
from rkmpc.vehicle.plants.composed import ComposedPlant


def test_load_scenario_is_the_preset_put_on_the_track():
    car = load_preset("f1tenth")
    by_name = load_scenario("builtin")
    from_car = Scenario.from_car(car, "builtin")
    assert by_name.car == from_car.car == car
    assert (
        by_name.limits == car.limits and by_name.vehicle == car.vehicle and by_name.vehicle_name == "f1tenth"
    )
    assert by_name.zoo_car is None and by_name.dt == 0.05
    faster = car.limits.at_pace(5.0, 4.5)
    assert load_scenario("builtin", limits=faster).car == replace(car, limits=faster)


def test_a_zoo_car_is_driven_and_is_in_the_contract():
    sc = load_scenario("oval", car="gym")
    assert sc.car == load_preset("f1tenth").with_zoo_car("gym")
    assert sc.zoo_car is not None and sc.zoo_car.name == "gym"
    assert isinstance(sc.make_plant(), ComposedPlant)
    assert sc.provenance().plant == "gym" and load_scenario("oval").provenance().plant == "f1tenth"


def test_the_provenance_is_what_a_model_must_match():
    sc = load_scenario("builtin", dt=0.04)
    made = sc.provenance()
    assert made == Provenance(vehicle="f1tenth", plant="f1tenth", dt=0.04, wheelbase=0.307, scale=1.0)
    assert sc.describe()["dt"] == 0.04 and sc.describe()["vehicle"] == "f1tenth"


@pytest.mark.filterwarnings("ignore:the built-in track")  # builds the scenario, drives nothing
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
    with pytest.warns(UserWarning, match="made at 1:10"):
        Scenario.from_car(load_preset("fullsize"), "oval")


def test_a_built_in_track_takes_no_scale():
    with pytest.raises(ValueError, match="--scale applies to files"):
        load_scenario("builtin", scale=0.5)
