"""What every MPC does with its answer: limit it, remember it, fall back when it fails.

:class:`SpeedFloor` is the lowest speed any MPC may command, tied to the reference
speed of the step; :class:`CommandGuard` holds it with the car's bounds, so that the
MPCs plan with the floor (:meth:`CommandGuard.speed_floor`) and every command they
send, learned corrections included, is clipped to it (:meth:`CommandGuard.apply`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_nonnegative
from rkmpc.vehicle.params import VehicleParams

__all__ = ["CommandGuard", "SpeedFloor"]


@dataclass(frozen=True)
class SpeedFloor:
    """The lowest speed an MPC commands, as a share of the reference speed of the step.

    ``floor(v_r) = min(v_r, max(minimum, fraction * v_r))``: the car may slow down
    below the reference, never stop where the reference moves (a learned speed
    correction as large as the reference would otherwise park the car in the
    slowest corner). The floor never exceeds the reference itself, and where the
    reference is 0 it is 0. The car's own bounds
    (:class:`rkmpc.vehicle.params.DriveParams`) apply on top.

    Parameters
    ----------
    fraction : float
        Share of the reference speed the command keeps at least, in [0, 1]
        (default 0.5; 0 turns the floor off).
    minimum : float
        Smallest floor (m/s), >= 0, for a reference that is slow but moving
        (default 0: the floor is ``fraction * v_r``).
    """

    fraction: float = 0.5
    minimum: float = 0.0

    def __post_init__(self) -> None:
        require_nonnegative(self, "fraction", "minimum")
        if self.fraction > 1.0:
            raise ParameterError(f"SpeedFloor.fraction must be in [0, 1], got {self.fraction!r}")

    def of(self, v_ref: np.ndarray) -> np.ndarray:
        """The floor (m/s) of reference speeds ``v_ref`` (m/s), same shape."""
        v = np.asarray(v_ref, dtype=float)
        return np.minimum(v, np.maximum(self.minimum, self.fraction * v))


class CommandGuard:
    """Input bounds, the steering-rate limit and the fall-back plan of a controller.

    Parameters
    ----------
    vehicle : VehicleParams
        Speed and steering limits.
    dt : float
        Control period (s); the wheel angle may change by ``max_rate * dt`` per step.
    horizon : int
        Length of the plans (steps); a plan older than that is not used.
    floor : SpeedFloor, optional
        The lowest speed command relative to the reference (:class:`SpeedFloor` defaults).

    Attributes
    ----------
    u_min, u_max : numpy.ndarray
        ``[speed (m/s), steer (rad)]`` bounds, shape (2,).
    steer_step_max : float
        Largest change of the steering command per step (rad).
    previous : numpy.ndarray or None
        The last command applied, shape (2,), or None before the first.
    floor : SpeedFloor
        The speed floor.
    """

    def __init__(
        self, vehicle: VehicleParams, dt: float, horizon: int, floor: SpeedFloor | None = None
    ) -> None:
        self.floor = floor if floor is not None else SpeedFloor()
        self.u_min = np.array([vehicle.drive.min_speed, -vehicle.steering.max_angle])
        self.u_max = np.array([vehicle.drive.max_speed, vehicle.steering.max_angle])
        self.steer_step_max = vehicle.steering.max_rate * dt
        self.horizon = horizon
        # The same bounds as floats, for the per-step clipping of two numbers.
        self._lo = (float(self.u_min[0]), float(self.u_min[1]))
        self._hi = (float(self.u_max[0]), float(self.u_max[1]))
        self.reset()

    def reset(self) -> None:
        """Forget the previous command and the plan."""
        self.previous: np.ndarray | None = None
        self._plan: np.ndarray | None = None
        self._age = 0

    def accept(self, plan: np.ndarray) -> np.ndarray:
        """Keep a solved plan (absolute inputs, shape (N, 2)) and return its first input."""
        self._plan = plan
        self._age = 0
        return np.array(plan[0], dtype=float)

    def fallback(self, u_ref: np.ndarray) -> np.ndarray:
        """The last solved plan shifted by one more step, or ``u_ref`` (shape (2,)) once it runs out."""
        self._age += 1
        if self._plan is not None and self._age < self.horizon:
            return np.array(self._plan[self._age], dtype=float)
        return np.array(u_ref, dtype=float)

    def speed_floor(self, v_ref: np.ndarray) -> np.ndarray:
        """Lowest speed (m/s) to plan or command at reference speeds ``v_ref`` (m/s), same shape.

        The :class:`SpeedFloor` of ``v_ref`` within the car's speed bounds; an MPC bounds
        its plan's speeds from below with it, and :meth:`apply` clips the command to it.
        """
        return np.clip(self.floor.of(v_ref), self._lo[0], self._hi[0])

    def apply(self, u: np.ndarray, v_ref: float) -> np.ndarray:
        """Clip ``u`` to the bounds, the speed floor and the steering step; remember it and return it.

        Parameters
        ----------
        u : numpy.ndarray
            Requested command ``[speed (m/s), steer (rad)]``, shape (2,).
        v_ref : float
            Reference speed at the car this step (m/s); the speed is kept at or above
            its :meth:`speed_floor`.
        """
        speed, steer = float(u[0]), float(u[1])
        if self.previous is not None:
            prev = float(self.previous[1])
            steer = min(max(steer, prev - self.steer_step_max), prev + self.steer_step_max)
        # Clip to the bounds as numpy.clip would (NaN stays NaN), on plain floats.
        lo, hi = self._lo, self._hi
        v_lo = float(self.speed_floor(np.asarray(v_ref))) if math.isfinite(v_ref) else lo[0]
        applied = np.array([min(max(speed, v_lo), hi[0]), min(max(steer, lo[1]), hi[1])])
        self.previous = applied
        return applied
