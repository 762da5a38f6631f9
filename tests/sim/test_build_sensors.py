"""What a car's sensors change in a scenario (issue 25): the plant it drives and the controller it builds.

With ideal sensors :func:`~rkmpc.sim.build.build_controller` returns the bare controller and
:meth:`Scenario.make_plant` the bare plant; with a real car's (``f1tenth-real``: no wheel angle,
a late jumpy localiser) the plant is seen through them (:class:`SensedPlant`) and the controller
is stepped with the state estimator's states (:class:`EstimatedController`), whose wheel angle
follows the steering model the controller's model was trained with (:func:`steering_of`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.config.loader import load_preset
from rkmpc.control.estimated import EstimatedController
from rkmpc.control.learned.rkmpc import ResidualKoopmanMPC
from rkmpc.control.linear.lmpc import LinearMPC
from rkmpc.control.linear.lmpc_id import IdentifiedLMPC
from rkmpc.core.observation import Command
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.estimation.labels import ESTIMATION_KEY
from rkmpc.estimation.steering import SteeringModel
from rkmpc.learning.data.augmentation import AugmentConfig
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.learn import learn
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.sim.build import build_controller, make_estimator, steering_of
from rkmpc.sim.scenario import Scenario
from rkmpc.vehicle.sensors import SensedPlant, get_sensor_profile

REAL = "f1tenth-real"


@pytest.fixture(scope="module")
def real_scenario():
    """The built-in track with the f1tenth car and a real F1TENTH car's sensors."""
    return Scenario.from_car(load_preset("f1tenth").with_sensors(REAL), "builtin")


def identified() -> IdentifiedModel:
    """An identified model whose servo differs from the car's nominal one in every parameter."""
    return IdentifiedModel(
        servo_time_constant=0.07,
        understeer_gradient=0.002,
        servo_fit_r2=0.9,
        understeer_fit_r2=0.8,
        n_samples=600,
        servo_structure="delay-lag-rate",
        servo_delay=0.1,
        servo_rate_limit=6.0,
        status="identified",
        fitted_on="yaw_rate",
    )


def least_squares_residual(scenario: Scenario, lap) -> KoopmanModel:
    """A residual model in milliseconds (least squares, no lifting network) of one LMPC lap."""
    return learn(
        recipe_of_kind("residual"),
        lap,
        made_for=scenario.provenance(),
        vehicle=scenario.vehicle,
        model=KoopmanModel(None),
        augment=AugmentConfig(ratio=0.2),
    ).model


# ---------------------------------------------------------------------------- steering_of


def test_without_a_model_the_wheel_angle_follows_the_nominal_servo(builtin_scenario):
    vehicle = builtin_scenario.vehicle
    assert steering_of(None, vehicle) == SteeringModel.nominal(vehicle)


def test_an_identified_model_is_its_own_steering_model(builtin_scenario):
    vehicle = builtin_scenario.vehicle
    model = identified()
    steering = steering_of(model, vehicle)
    assert steering == SteeringModel.from_identified(model, vehicle.steering.max_angle)
    assert (steering.delay, steering.time_constant, steering.rate_limit) == (0.1, 0.07, 6.0)
    assert steering.max_angle == vehicle.steering.max_angle and steering.structure == "delay-lag-rate"


def test_a_koopman_model_trained_on_estimated_data_gives_the_steering_it_recorded(
    builtin_scenario, builtin_lap
):
    vehicle = builtin_scenario.vehicle
    residual = least_squares_residual(builtin_scenario, builtin_lap)
    # Trained on data that measured the wheel angle: nothing recorded, the nominal servo.
    assert ESTIMATION_KEY not in residual.metadata_["data_metadata"]
    assert steering_of(residual, vehicle) == SteeringModel.nominal(vehicle)
    recorded = SteeringModel(time_constant=0.09, max_angle=0.4, delay=0.05, source="identified (delay-lag)")
    model = KoopmanModel(None)
    model.metadata_ = {"data_metadata": {ESTIMATION_KEY: {"steering": recorded.describe()}}}
    assert steering_of(model, vehicle) == recorded


def test_a_model_with_odd_metadata_falls_back_to_the_nominal_servo(builtin_scenario):
    vehicle = builtin_scenario.vehicle
    for metadata in (None, {}, {"data_metadata": []}, {"data_metadata": {ESTIMATION_KEY: "smoothed"}}):
        model = KoopmanModel(None)
        model.metadata_ = metadata
        assert steering_of(model, vehicle) == SteeringModel.nominal(vehicle)


# ---------------------------------------------------------------------------- build_controller


def test_with_ideal_sensors_the_controller_is_the_bare_one(builtin_scenario):
    assert builtin_scenario.car.sensors.is_ideal
    controller = build_controller("lmpc", builtin_scenario)
    assert isinstance(controller, LinearMPC) and not isinstance(controller, EstimatedController)


def test_with_a_real_cars_sensors_the_controller_is_stepped_with_estimates(real_scenario):
    controller = build_controller("lmpc", real_scenario)
    assert isinstance(controller, EstimatedController) and isinstance(controller.inner, LinearMPC)
    assert controller.name == "lmpc" and controller.dt == real_scenario.dt
    estimator = controller.estimator
    assert estimator.steering == SteeringModel.nominal(real_scenario.vehicle)
    assert estimator.config == replace(real_scenario.car.estimator, control_period=real_scenario.dt)


def test_the_estimator_takes_the_cars_settings_at_the_scenarios_period():
    tuned = EstimatorConfig(position_std=0.12, max_rejections=3, control_period=0.1)
    car = replace(load_preset("f1tenth").with_sensors(REAL), estimator=tuned)
    scenario = Scenario.from_car(car, "builtin", dt=0.04)
    controller = build_controller("lmpc", scenario)
    assert isinstance(controller, EstimatedController)
    config = controller.estimator.config
    assert (config.position_std, config.max_rejections, config.control_period) == (0.12, 3, 0.04)
    assert make_estimator(scenario).config == config


def test_lmpc_id_on_a_real_car_propagates_the_wheel_angle_through_its_identified_servo(real_scenario):
    model = identified()
    controller = build_controller("lmpc-id", real_scenario, model)
    assert isinstance(controller, EstimatedController) and isinstance(controller.inner, IdentifiedLMPC)
    steering = controller.estimator.steering
    assert steering == SteeringModel.from_identified(model, real_scenario.vehicle.steering.max_angle)


def test_rkmpc_on_a_real_car_uses_the_steering_its_model_was_trained_with(
    builtin_scenario, builtin_lap, real_scenario
):
    recorded = SteeringModel(
        time_constant=0.09, max_angle=0.4189, delay=0.05, source="identified (delay-lag)"
    )
    model = least_squares_residual(builtin_scenario, builtin_lap)
    model.metadata_["data_metadata"][ESTIMATION_KEY] = {"steering": recorded.describe()}
    controller = build_controller("rkmpc", real_scenario, model)
    assert isinstance(controller, EstimatedController) and isinstance(controller.inner, ResidualKoopmanMPC)
    assert controller.estimator.steering == recorded


# ---------------------------------------------------------------------------- make_plant


def test_the_plant_is_seen_through_the_cars_sensors(builtin_scenario, real_scenario):
    bare = builtin_scenario.make_plant(3)
    assert not isinstance(bare, SensedPlant)
    plant = real_scenario.make_plant(3)
    assert isinstance(plant, SensedPlant) and plant.seed == 3
    assert plant.profile == get_sensor_profile(REAL)
    assert type(plant.plant) is type(bare)
    plant.reset(0.0, 0.0, 0.0, 2.0)
    plant.step(Command(2.0, 0.1), 0.05)
    obs = plant.observe()
    assert math.isnan(obs.steer_angle) and math.isnan(obs.slip_angle)
    assert np.isfinite([obs.x, obs.y, obs.yaw, obs.speed, obs.yaw_rate]).all()


def test_the_sensors_seed_makes_the_plants_observations_reproducible(real_scenario):
    def drive(seed: int) -> list[tuple[float, ...]]:
        plant = real_scenario.make_plant(seed)
        plant.reset(0.0, 0.0, 0.0, 2.0)
        out = []
        for _ in range(20):
            plant.step(Command(2.0, 0.05), 0.05)
            o = plant.observe()
            out.append((o.x, o.y, o.speed, o.yaw_rate))
        return out

    assert drive(1) == drive(1) and drive(1) != drive(2)


def test_a_zoo_car_is_wrapped_with_the_sensors_too():
    car = load_preset("f1tenth").with_zoo_car("gym").with_sensors(REAL)
    scenario = Scenario.from_car(car, "builtin")
    plant = scenario.make_plant(0)
    bare = Scenario.from_car(load_preset("f1tenth").with_zoo_car("gym"), "builtin").make_plant(0)
    assert isinstance(plant, SensedPlant) and type(plant.plant) is type(bare)
