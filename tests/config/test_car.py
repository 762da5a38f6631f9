"""CarConfig: the one description of a car, its variants and its record."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from rkmpc.config.car import CarConfig, PlantSettings, TrainingSettings
from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.vehicle.params import f1tenth


def test_variants_replace_one_part_and_keep_the_rest():
    car = load_preset("f1tenth")
    fast = car.at_pace(6.0, 5.0)
    assert fast.limits == car.limits.at_pace(6.0, 5.0) and replace(fast, limits=car.limits) == car
    assert car.at_pace() is car
    assert car.at_pace(max_speed=4.0).limits.lateral_accel == car.limits.lateral_accel
    gym = car.with_zoo_car("gym")
    assert gym.plant == PlantSettings(model="f1tenth", car="gym") and gym.vehicle == car.vehicle
    assert car.with_zoo_car(None) is car and gym.with_zoo_car(None) == car
    trained = car.with_training(seed=3, epochs=5)
    assert trained.training == TrainingSettings(epochs=5, seed=3, data_laps=2, kmpc_samples=50_000)
    assert car.with_training() is car


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: CarConfig(preset="f1tenth", vehicle="f1tenth", file_scale=0.1), "CarConfig.vehicle"),
        (lambda: CarConfig(preset="f1tenth", vehicle=f1tenth(), file_scale=0.0), "CarConfig.file_scale"),
        (
            lambda: CarConfig(preset="f1tenth", vehicle=f1tenth(), file_scale=0.1, limits={}),
            "CarConfig.limits",
        ),
        (lambda: TrainingSettings(seed=-1), r"TrainingSettings\.seed must be an integer >= 0"),
        (lambda: TrainingSettings(data_laps=0), r"TrainingSettings\.data_laps"),
        (lambda: TrainingSettings(kmpc_samples=999), r"TrainingSettings\.kmpc_samples"),
        (lambda: PlantSettings(model="tank"), "unknown plant 'tank'"),
        (lambda: PlantSettings(car="tank"), "unknown zoo car 'tank'"),
        (lambda: PlantSettings(model="fullsize", car="gym"), "needs the f1tenth plant"),
        (lambda: load_preset("fullsize").with_zoo_car("gym"), "needs the f1tenth plant"),
        (lambda: load_preset("f1tenth").with_training(epochs=0), r"TrainingSettings\.epochs"),
    ],
)
def test_a_bad_car_is_refused_naming_the_field(make, match):
    with pytest.raises(ParameterError, match=match):
        make()


def test_the_record_holds_every_value_and_is_json():
    car = load_preset("fullsize").with_training(seed=2)
    record = json.loads(json.dumps(car.to_json(), allow_nan=False))
    assert record["file"] is None and record["sha256"] is None
    assert record["vehicle"]["preset"] == "fullsize" and record["vehicle"]["file_scale"] == 1.0
    assert record["vehicle"]["mass"] == car.vehicle.mass
    assert record["plant"] == {"model": "fullsize", "car": None}
    assert record["limits"]["max_speed"] == 25.0
    assert record["training"]["seed"] == 2
    assert record["controllers"]["rkmpc"]["position_weight"] == 8.0
    assert record["controllers"]["rkmpc"]["slip_drift"] is True
    assert "slip_drift" not in record["controllers"]["rkmpc-paper"]
    assert set(record["controllers"]) == {"lmpc", "rkmpc", "rkmpc-paper", "pp", "nmpc"}
    assert record["ros"]["rate_hz"] == 20.0
