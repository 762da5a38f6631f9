"""Pure pursuit with a speed-dependent look-ahead, tracking the speed profile."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rkmpc.control.base import Controller
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference


@dataclass(frozen=True)
class PurePursuitConfig:
    """Look-ahead law of pure pursuit.

    The look-ahead distance, measured from the rear axle along the path, is
    ``clip(min_lookahead + lookahead_gain * speed, min_lookahead, max_lookahead)``.

    Parameters
    ----------
    min_lookahead : float
        Look-ahead at standstill (m).
    lookahead_gain : float
        Extra look-ahead per unit speed (s).
    max_lookahead : float
        Upper bound of the look-ahead (m).
    """

    min_lookahead: float = 0.5
    lookahead_gain: float = 0.25
    max_lookahead: float = 3.0

    def __post_init__(self) -> None:
        if not (self.min_lookahead > 0 and self.max_lookahead >= self.min_lookahead):
            raise ParameterError("PurePursuitConfig needs 0 < min_lookahead <= max_lookahead")
        if not self.lookahead_gain >= 0:
            raise ParameterError("PurePursuitConfig.lookahead_gain must be >= 0")


class PurePursuit(Controller):
    """Geometric pure pursuit on the reference path, speed from the speed profile.

    Parameters
    ----------
    reference : Reference
        Path and speed profile.
    vehicle : VehicleParams
        Wheelbase, rear-axle offset and steering limit.
    config : PurePursuitConfig, optional
        Look-ahead law.
    """

    name = "pp"
    settings_field = "pp"

    def __init__(
        self, reference: Reference, vehicle: VehicleParams, config: PurePursuitConfig | None = None
    ) -> None:
        super().__init__(reference, vehicle.wheelbase)
        self.reference = reference
        self.vehicle = vehicle
        self.config = config if config is not None else PurePursuitConfig()

    def _reset(self) -> None:
        pass

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        cfg = self.config
        veh = self.vehicle
        cos_yaw, sin_yaw = math.cos(observation.yaw), math.sin(observation.yaw)
        rear_x = observation.x - veh.lr * cos_yaw
        rear_y = observation.y - veh.lr * sin_yaw
        proj = self._projected()
        speed = max(observation.speed, 0.0)
        lookahead = min(
            max(cfg.min_lookahead + cfg.lookahead_gain * speed, cfg.min_lookahead), cfg.max_lookahead
        )
        goal = self.reference.path.position(proj.s + lookahead + veh.lr)
        dx, dy = float(goal[0]) - rear_x, float(goal[1]) - rear_y
        # Goal in the car frame; alpha is its bearing from the heading.
        local_x = cos_yaw * dx + sin_yaw * dy
        local_y = -sin_yaw * dx + cos_yaw * dy
        dist_sq = max(local_x * local_x + local_y * local_y, 1e-9)
        steer = math.atan(2.0 * veh.wheelbase * local_y / dist_sq)
        limit = veh.steering.max_angle
        steer = min(max(steer, -limit), limit)
        v_ref = float(self.reference.profile.speed(proj.s))
        return Command(speed=v_ref, steer=steer), "ok", ""
