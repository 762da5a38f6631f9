"""Reference tracking over a horizon: the cost every MPC shares, and the step they all take.

:class:`TrackingCost` holds the horizon, the period and the weights of the
tracking cost of the paper's MPC1,

.. math::

    \\sum_{k=1}^{N} q_p \\|p_k - p^r_k\\|^2 + q_\\theta (\\theta_k - \\theta^r_k)^2
    + \\sum_{k=0}^{N-1} r_v (v_k - v^r_k)^2 + r_\\delta (\\delta_k - \\delta^r_k)^2
    + w_v (v_k - v_{k-1})^2 + w_\\delta (\\delta_k - \\delta_{k-1})^2,

with the last state weighted ``terminal_factor`` times and the speed bounded
by the profile plus ``speed_margin`` from above and by the
:class:`~rkmpc.control.guard.SpeedFloor` of the profile from below. The configurations of the linear, the
Koopman and the nonlinear MPCs inherit it (do-mpc style: settings shared by
inheritance), so they differ only in their model and solver settings.

:class:`TrackingController` is the step they all take (a template method):
project the car onto the reference (hinted by the previous projection, so it
never jumps across the track), take the reference horizon and its inputs, on
the first step take the car's speed and the feed-forward angle as the command
applied before, let the subclass solve for a plan (:meth:`TrackingController._solve`),
and hand the plan, or the fall-back when the solve failed, to the
:class:`~rkmpc.control.guard.CommandGuard`.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rkmpc.control.base import AdmissibleErrors, Controller
from rkmpc.control.guard import CommandGuard, SpeedFloor
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.core.validation import is_integer, require_nonnegative, require_positive
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference, ReferenceHorizon

__all__ = ["MPC_WEIGHTS", "Solution", "TrackingController", "TrackingCost"]

#: Weights of the tracking cost (all finite and >= 0).
MPC_WEIGHTS = (
    "position_weight",
    "heading_weight",
    "speed_weight",
    "steer_weight",
    "speed_rate_weight",
    "steer_rate_weight",
    "terminal_factor",
)


#: Longest prediction horizon (steps): the condensed QP's matrices grow with its square (a horizon
#: of 10,000 asks for gigabytes and minutes a step); 200 steps are 10 s at the paper's 20 Hz.
MAX_HORIZON = 200
#: Largest cost weight: beyond it the QPs lose their conditioning and every step falls back.
MAX_WEIGHT = 1e8


def check_weights(config: object, *names: str) -> None:
    """ParameterError unless each named weight of ``config`` is in [0, :data:`MAX_WEIGHT`]."""
    for name in names:
        value = getattr(config, name)
        if not (isinstance(value, int | float) and math.isfinite(value) and 0.0 <= value <= MAX_WEIGHT):
            raise ParameterError(
                f"{type(config).__name__}.{name} must be a number in [0, {MAX_WEIGHT:g}], got {value!r}"
            )


@dataclass(frozen=True)
class TrackingCost:
    """Horizon, period and weights of the tracking cost shared by the MPCs.

    Parameters
    ----------
    horizon : int
        Prediction horizon N (steps), 2 to :data:`MAX_HORIZON`.
    dt : float
        Control period T (s), at most 1 s.
    position_weight : float
        Weight of the squared x and y errors (1/m^2 relative units).
    heading_weight : float
        lambda: weight of the squared heading error.
    speed_weight : float
        mu: weight of the squared speed deviation from the reference.
    steer_weight : float
        epsilon: weight of the squared steering deviation from the reference.
    speed_rate_weight, steer_rate_weight : float
        Weights of the squared step-to-step changes of speed and steering (per step,
        not per second, including the change from the command applied before).
    terminal_factor : float
        Multiplier of the state weights at the last step of the horizon.
    speed_margin : float
        Largest speed above the reference speed profile the MPC may command
        (m/s). Without it the kinematic model, in which yaw rate grows with
        speed, accelerates into corners whenever the steering saturates.
    speed_lead : float
        Look-ahead of the reference speed (s): the speed asked for at each step of the horizon
        is the profile's this much later. A car whose speed loop lags the command by a time
        constant ``tau`` reaches a braking point about ``a * tau`` too fast (``a`` the
        deceleration) unless told ``tau`` early; 0 (default) asks for the profile as it is.
        Rounded to whole periods.
    speed_floor : SpeedFloor
        Lowest speed the MPC plans and commands, relative to the reference speed
        (default: half of it, see :class:`~rkmpc.control.guard.SpeedFloor`). Every MPC,
        and the residual MPCs built on the LMPC, keep their commands at or above it,
        learned corrections included.
    """

    horizon: int = 30
    dt: float = 0.05
    position_weight: float = 1.0
    heading_weight: float = 5.0
    speed_weight: float = 0.05
    steer_weight: float = 2.0
    speed_rate_weight: float = 0.05
    steer_rate_weight: float = 0.1
    terminal_factor: float = 1.0
    speed_margin: float = 0.0
    speed_lead: float = 0.0
    speed_floor: SpeedFloor = field(default_factory=SpeedFloor)

    def __post_init__(self) -> None:
        name = type(self).__name__
        if not isinstance(self.speed_floor, SpeedFloor):
            raise ParameterError(f"{name}.speed_floor must be a SpeedFloor, got {self.speed_floor!r}")
        if not is_integer(self.horizon, 2) or self.horizon > MAX_HORIZON:
            raise ParameterError(
                f"{name}.horizon must be an integer from 2 to {MAX_HORIZON}, got {self.horizon!r}"
            )
        require_positive(self, "dt")
        if self.dt > 1.0:
            raise ParameterError(f"{name}.dt must be at most 1 s, got {self.dt!r}")
        check_weights(self, *MPC_WEIGHTS)
        require_nonnegative(self, "speed_margin", "speed_lead")
        if not self.speed_lead <= 10.0:
            raise ParameterError(f"{name}.speed_lead must be at most 10 s, got {self.speed_lead!r}")
        if self.speed_weight + self.speed_rate_weight <= 0 or self.steer_weight + self.steer_rate_weight <= 0:
            raise ParameterError(f"{name}: each input needs a positive weight or rate weight")


def check_iterations(config: object, value: int) -> None:
    """Raise :class:`ParameterError` unless ``value`` (``max_iterations``) is an integer >= 1."""
    if not is_integer(value, 1):
        raise ParameterError(f"{type(config).__name__}.max_iterations must be an integer >= 1, got {value!r}")


@dataclass(frozen=True)
class Solution:
    """What a tracking controller's solver returned for one step.

    Parameters
    ----------
    plan : numpy.ndarray or None
        Absolute inputs ``[v (m/s), delta (rad)]`` over the horizon, shape (N, 2), or None
        when the solve failed (the guard then falls back).
    message : str
        Why it failed; empty on success.
    reason : str
        The failure's status (:data:`~rkmpc.control.base.STATUSES`), when ``plan`` is None.
    """

    plan: np.ndarray | None
    message: str = ""
    reason: str = "fallback"


class TrackingController(Controller):
    """A controller that tracks the reference over a horizon (the template step of every MPC).

    Subclasses implement :meth:`_solve` and may override :meth:`_reference_inputs`,
    :meth:`_first_previous_input` and :meth:`_reset_solver`.

    Parameters
    ----------
    reference : Reference
        Path and speed profile to track.
    vehicle : VehicleParams
        Input limits and steering-rate limit (and whatever the model needs).
    config : TrackingCost
        Horizon, period and weights (a subclass's configuration).
    admissible : AdmissibleErrors, optional
        Largest distance and heading error from the reference to drive at
        (:class:`~rkmpc.control.base.AdmissibleErrors` defaults).
    """

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        config: TrackingCost,
        admissible: AdmissibleErrors | None = None,
    ) -> None:
        super().__init__(reference, vehicle.wheelbase, admissible)
        self.reference = reference
        self.vehicle = vehicle
        self.config = config
        self.dt = config.dt
        self._guard = CommandGuard(vehicle, config.dt, config.horizon, config.speed_floor)
        #: Reference speed at the car's projection at the last step (m/s).
        self.reference_speed = math.nan

    def _reset(self) -> None:
        self.reference_speed = math.nan
        self._guard.reset()
        self._reset_solver()

    def _reset_solver(self) -> None:
        """Forget the solver's state (warm starts); nothing by default."""

    def _reference_inputs(self, ref: ReferenceHorizon) -> np.ndarray:
        """Reference inputs ``[v_r, delta_r]`` over the horizon, shape (N, 2)."""
        n = self.config.horizon
        u_ref = np.empty((n, 2))
        u_ref[:, 0] = ref.v[:n]
        u_ref[:, 1] = ref.delta[:n]
        return u_ref

    def _first_previous_input(self, observation: Observation, u_ref: np.ndarray) -> np.ndarray:
        """The command taken as applied before the first step: the car's speed, the feed-forward angle."""
        return np.array([observation.speed, u_ref[0, 1]])

    def _track(self, observation: Observation) -> tuple[ReferenceHorizon, np.ndarray]:
        """Project the car, take the reference horizon and its inputs; set the previous command once."""
        cfg = self.config
        lead = round(cfg.speed_lead / cfg.dt)
        ahead = self.reference.horizon(self._projected().s, cfg.horizon + lead, cfg.dt)
        ref = ahead.head(cfg.horizon) if lead > 0 else ahead
        u_ref = self._reference_inputs(ref)
        if lead > 0:  # the speed the profile asks for ``speed_lead`` later (s)
            u_ref[:, 0] = ahead.v[lead : lead + cfg.horizon]
        self.reference_speed = float(u_ref[0, 0])
        if self._guard.previous is None:
            self._guard.previous = self._first_previous_input(observation, u_ref)
        return ref, u_ref

    def _speed_bounds(self, u_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lowest and highest speeds (m/s) to plan over the horizon, each shape (N,).

        From above the car's limit and the reference plus ``speed_margin``; from below the
        car's limit and the :class:`~rkmpc.control.guard.SpeedFloor` of the reference, never
        above the upper bound.
        """
        v_ref = u_ref[:, 0]
        upper = np.minimum(self._guard.u_max[0], v_ref + self.config.speed_margin)
        lower = np.minimum(self._guard.speed_floor(v_ref), upper)
        return lower, upper

    @property
    def previous_command(self) -> np.ndarray:
        """The command applied at the previous step, ``[speed (m/s), steer (rad)]`` (set by the first)."""
        previous = self._guard.previous
        if previous is None:
            raise RuntimeError(f"{type(self).__name__}: no command yet; the first step sets it")
        return previous

    @abstractmethod
    def _solve(self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray) -> Solution:
        """Solve for a plan along ``ref``; ``self._guard.previous`` is the command applied before."""

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        ref, u_ref = self._track(observation)
        solution = self._solve(observation, ref, u_ref)
        guard = self._guard
        if solution.plan is not None:
            u = guard.accept(solution.plan)
            status, message = "ok", ""
        else:
            u = guard.fallback(u_ref[0])
            status, message = solution.reason, solution.message
        u = guard.apply(u, self.reference_speed)
        return Command(speed=float(u[0]), steer=float(u[1])), status, message
