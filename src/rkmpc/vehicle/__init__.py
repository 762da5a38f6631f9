"""Vehicle models: parameters, the paper's kinematic model, tyres and simulated plants."""

from rkmpc.vehicle.friction import CircularRegion, FrictionChange, FrictionSchedule
from rkmpc.vehicle.kinematic import (
    KINEMATIC_INPUT_NAMES,
    KINEMATIC_STATE_NAMES,
    kinematic_rhs,
    kinematic_step,
    linearize_discrete,
)
from rkmpc.vehicle.params import (
    DriveParams,
    PacejkaParams,
    SteeringParams,
    VehicleParams,
    f1tenth,
    fullsize,
)
from rkmpc.vehicle.plants.base import ActuatedPlant, Plant
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.plants.fullsize import FullSizePlant
from rkmpc.vehicle.registry import PLANTS, make_plant
from rkmpc.vehicle.sensors import SensorProfile, get_sensor_profile, sensor_profile_names
from rkmpc.vehicle.tyres import pacejka_lateral_force, pacejka_lateral_force_array
from rkmpc.vehicle.wrappers import NoiseStd, ObservationNoise, PlantWrapper

__all__ = [
    "KINEMATIC_INPUT_NAMES",
    "KINEMATIC_STATE_NAMES",
    "PLANTS",
    "ActuatedPlant",
    "CircularRegion",
    "DriveParams",
    "DynamicPlant",
    "FrictionChange",
    "FrictionSchedule",
    "FullSizePlant",
    "NoiseStd",
    "ObservationNoise",
    "PacejkaParams",
    "Plant",
    "PlantWrapper",
    "SensorProfile",
    "SteeringParams",
    "VehicleParams",
    "f1tenth",
    "fullsize",
    "get_sensor_profile",
    "kinematic_rhs",
    "kinematic_step",
    "linearize_discrete",
    "make_plant",
    "pacejka_lateral_force",
    "pacejka_lateral_force_array",
    "sensor_profile_names",
]
