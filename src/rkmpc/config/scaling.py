"""How the residual MPC's settings of the 1:10 car carry over to a car of another size and pace.

The full-size preset (``presets/fullsize.toml``) writes out numbers made by these two rules; a test
recomputes them, so the file and the rules cannot drift apart. A new car can be given its first
settings the same way.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TypeVar

from rkmpc.control.learned.residual_config import ResidualMPCConfig, RKMPCConfig
from rkmpc.track.speed_profile import SpeedLimits
from rkmpc.vehicle.params import VehicleParams

__all__ = ["carry_over", "speed_priced"]

C = TypeVar("C", bound=ResidualMPCConfig)


def carry_over(
    config: C, tuned_on: VehicleParams, tuned_limits: SpeedLimits, car: VehicleParams, limits: SpeedLimits
) -> C:
    """``config``, tuned for ``tuned_on`` at ``tuned_limits``, carried over to ``car`` at ``limits``.

    :meth:`ResidualMPCConfig.scaled` with the ratios of the wheelbases and of the speed profiles'
    top speeds.
    """
    length = car.wheelbase / tuned_on.wheelbase
    speed = limits.max_speed / tuned_limits.max_speed
    scaled: C = config.scaled(length, speed)
    return scaled


def speed_priced(
    scaled: RKMPCConfig,
    car: VehicleParams,
    limits: SpeedLimits,
    *,
    position_weight: float,
    top_price: float,
    floor: float,
) -> RKMPCConfig:
    """Speed-priced steering with the slip drift: the full-size car's ``rkmpc`` settings.

    At ``limits.max_speed`` a steering correction costs ``top_price`` times the scaled steering
    weight; below it the price falls with the fourth power of the planned speed down to ``floor``
    (the steering weight). The prediction carries the sideways drift of the slip angle.
    """
    gain = limits.max_speed**2 / car.wheelbase  # lateral acceleration per wheel angle, (m/s^2)/rad
    top = top_price * scaled.steer_weight
    return replace(
        scaled,
        position_weight=position_weight,
        steer_weight=floor,
        slip_drift=True,
        lateral_accel_weight=(top - floor) / gain**2,
    )
