"""Sensor profiles: what a simulated car measures, and how badly (``docs/sensors.md``).

A :class:`SensorProfile` composes a localiser, a wheel-speed sensor and a yaw-rate gyro
(:mod:`rkmpc.vehicle.sensors.components`) and says whether the wheel angle and the side-slip
are measured; :meth:`SensorProfile.wrap` puts it around any plant, zoo cars included.
Named profiles: :func:`get_sensor_profile` (``ideal``, ``no-steer``, ``f1tenth-real``).
"""

from rkmpc.vehicle.sensors.components import Localiser, WheelSpeedSensor, YawRateSensor
from rkmpc.vehicle.sensors.profile import SensedPlant, SensorProfile
from rkmpc.vehicle.sensors.profiles import (
    SENSOR_PROFILES,
    f1tenth_real,
    get_sensor_profile,
    sensor_profile_names,
)

__all__ = [
    "SENSOR_PROFILES",
    "Localiser",
    "SensedPlant",
    "SensorProfile",
    "WheelSpeedSensor",
    "YawRateSensor",
    "f1tenth_real",
    "get_sensor_profile",
    "sensor_profile_names",
]
