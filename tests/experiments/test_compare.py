"""The one-track experiment: fault classification and settings validation."""

from __future__ import annotations

import pytest

from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.compare import DEGRADE_THRESHOLD, CompareConfig, fault_effect

NOMINAL = {"completed": True, "lateral_error_mean_m": 0.02}


@pytest.mark.parametrize(
    ("faulted", "outcome", "effect"),
    [
        ({"completed": True, "lateral_error_mean_m": 0.021}, "completed", "completes"),
        (
            {"completed": True, "lateral_error_mean_m": 0.02 * (1 + DEGRADE_THRESHOLD) + 1e-6},
            "completed",
            "degrades",
        ),
        ({"completed": False, "lateral_error_mean_m": 0.05}, "off_track", "leaves the track"),
        ({"completed": False, "lateral_error_mean_m": 0.05}, "timeout", "does not finish"),
    ],
)
def test_fault_effect_classes(faulted, outcome, effect):
    assert fault_effect(NOMINAL, faulted, outcome) == effect


def _car(**training):
    return load_preset("f1tenth").with_training(**training)


@pytest.mark.parametrize(
    "make",
    [
        # The car's training settings (laps of data, seed, samples, epochs) are the car's: refused
        # where the car is made.
        lambda: CompareConfig(track="builtin", car=_car(data_laps=0)),
        lambda: CompareConfig(track="builtin", car=_car(seed=-1)),
        lambda: CompareConfig(track="builtin", car=_car(kmpc_samples=10)),
        lambda: CompareConfig(track="builtin", car=_car(epochs=0)),
        lambda: CompareConfig(track="builtin", controllers=()),
        lambda: CompareConfig(track="builtin", run_laps=0),
        lambda: CompareConfig(track="builtin", controllers=("lmpc", "mpc")),
        lambda: CompareConfig(track="builtin", fault="ice"),
        lambda: CompareConfig(track="builtin", car="f1tenth"),  # type: ignore[arg-type]
    ],
)
def test_compare_config_rejects_bad_settings(make):
    with pytest.raises(ParameterError):
        make()


def test_compare_config_takes_its_seed_and_plan_from_the_car():
    car = _car(seed=3, data_laps=1, kmpc_samples=2000, epochs=2)
    config = CompareConfig(track="builtin", car=car, controllers=("lmpc", "kmpc"))
    plan = config.plan()
    assert config.seed == 3
    assert (plan.seed, plan.laps, plan.excitation_samples, plan.epochs) == (3, 1, 2000, 2)
    assert plan.controllers == ("lmpc", "kmpc")
    assert config.to_json()["car"] == car.to_json()


def test_a_fault_that_cannot_apply_to_the_car_is_refused_before_anything_is_learned(monkeypatch):
    import rkmpc.experiments.compare as compare_mod

    def never(*_args, **_kwargs):
        raise AssertionError("learned before the fault was checked")

    monkeypatch.setattr(compare_mod, "learn_models", never)
    zoo = CompareConfig(track="builtin", car=load_preset("f1tenth").with_zoo_car("gym"), fault="friction")
    with pytest.raises(ParameterError, match="fault 'friction' cannot apply to plant ComposedPlant"):
        compare_mod.compare(zoo)
    sensed = load_preset("f1tenth").with_sensors("f1tenth-real")
    real = CompareConfig(track="builtin", car=sensed, fault="heavy")
    real.check_fault(real.scenario())  # a fault of the car applies inside the real sensors
