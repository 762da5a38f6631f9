"""``lmpc-id``: the linear MPC with a physically identified model.

The baseline a skeptical expert asks for before any neural network: the same
LMPC (weights, horizon, QP) whose kinematic model is extended with what two
laps of data identify physically (see :mod:`rkmpc.learning.identification`):

* the steering servo as a lag state ``delta_w`` behind a pure delay ``d``,
  exactly discretised under held commands
  (:func:`rkmpc.learning.servo_fit.lag_delay_weights`):
  ``delta_w(k+1) = a delta_w(k) + sum_j w_j delta_cmd(k-j)``, ``a = exp(-T / tau)``.
  With ``d = m T + f``, the commands sent in the last ``m`` (or ``m + 1`` when
  ``f > 0``) periods that have not reached the wheel yet are extra states, a
  shift register: the QP knows that its first moves act only after the delay,
  and that the commands already sent will still arrive. A command's
  feed-forward is the wheel reference ``m`` periods later, when it arrives.
  Folding the delay into a longer lag (``tau + d``) would be simpler, and on the
  built-in track it is within a few per cent of the delay states while the lag
  dominates; but a lag lets every planned command act at once, only slower,
  and when the delay dominates (0.12 s delay, 0.03 s lag) it doubled the mean
  lateral error (0.040 against 0.019 m).
* a wheel rate limit, when one was identified: the steering commands may then
  change by at most ``min(R, vehicle.steering.max_rate) T`` per period (the guard's
  and the QP's steering-step limit). Commands faster than the wheel can follow
  would only leave the linear model's validity.
* the understeer gradient ``K``: the path curvature the wheel angle produces is
  ``tan(delta_w) / (L + K v^2)``, so steady cornering needs the feed-forward
  ``delta_r = atan((L + K v_r^2) kappa_r)``; both come from
  :mod:`rkmpc.learning.identification`, the model the fit identifies ``K`` in.

The wheel states are deviations from the wheel reference of their step, which
moves on by ``delta_r(k+1) - delta_r(k)`` each step whatever the car does; a
last, constant state (always 1) carries that drift into the prediction, so the
known part of the wheel trajectory is predicted exactly.

When identification kept the nominal servo (its warnings say why), ``lmpc-id``
drives with the car's nominal lag, without delay or extra rate limit.

A servo identified from the yaw rate (``model.fitted_on == "yaw_rate"``, a car without a
steering sensor) is the steering as the yaw rate sees it: the servo and the chassis's own lag in
building up yaw together. Its wheel state is the one the kinematic model must be given to turn
like the car, so ``lmpc-id`` runs it from the commands even when a wheel angle is measured (the
measured wheel leads it by the chassis's lag).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from rkmpc.control.linear.lmpc import LinearMPC, LMPCConfig, roll_out
from rkmpc.control.linear.problem import Prediction, condense
from rkmpc.core.angles import wrap_scalar
from rkmpc.core.observation import Observation
from rkmpc.estimation.steering import SteeringModel, WheelAnglePropagator
from rkmpc.learning.identification import IdentifiedModel, effective_wheelbase, steady_state_steer
from rkmpc.learning.servo_fit import delay_periods
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference, ReferenceHorizon


class IdentifiedLMPC(LinearMPC):
    """LMPC on the kinematic model plus an identified servo (lag, delay, rate limit) and understeer.

    Parameters
    ----------
    reference : Reference
        Path and speed profile.
    vehicle : VehicleParams
        Wheelbase and limits.
    model : IdentifiedModel
        Identified servo and understeer gradient.
    config : LMPCConfig, optional
        The LMPC's weights (the same as the plain LMPC by default).

    Notes
    -----
    The model's states are the pose deviations, the wheel angle, the commands still on
    their way to the wheel and the constant 1 (:meth:`_model`); only the pose is weighted,
    so the QP gets the pose rows of the condensed prediction alone, the size of the plain
    LMPC's.
    """

    name = "lmpc-id"
    takes_model = True

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        model: IdentifiedModel,
        config: LMPCConfig | None = None,
    ) -> None:
        dt = (config if config is not None else LMPCConfig()).dt
        self.model = model
        servo = SteeringModel.from_identified(model, vehicle.steering.max_angle)
        self._wheel = WheelAnglePropagator(servo, dt)
        self._a = self._wheel.a
        self._w = self._wheel.weights
        self._shift = delay_periods(model.servo_delay, dt)
        super().__init__(reference, with_rate_limit(vehicle, model.servo_rate_limit), config)

    def _reset_solver(self) -> None:
        super()._reset_solver()
        self._wheel.reset()

    def _wheel_reference(self, ref: ReferenceHorizon) -> np.ndarray:
        """The steady-state wheel angle along the horizon (rad), shape (N + 1,)."""
        L, K = self.vehicle.wheelbase, self.model.understeer_gradient
        return steady_state_steer(np.tan(ref.delta) / L, ref.v, L, K)

    def _reference_inputs(self, ref: ReferenceHorizon) -> np.ndarray:
        # A command reaches the wheel m whole periods later: its feed-forward is the wheel
        # reference there (held at the end of the horizon).
        n = self.config.horizon
        ahead = np.minimum(np.arange(n) + self._shift, n)
        return np.column_stack([ref.v[:n], self._wheel_reference(ref)[ahead]])

    def _prediction(
        self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xi0, A, B = self._model(observation, ref, u_ref)
        Phi, Gamma = condense(A, B)
        if self.config.about_plan and self.last_plan is not None:
            Phi, Gamma = self._about_plan_id(xi0, (A, B), (Phi, Gamma), ref, u_ref, self.last_plan)
        n, nx = self.config.horizon, len(xi0)
        Phi = Phi.reshape(n, nx, nx)[:, :3].reshape(3 * n, nx)
        Gamma = np.ascontiguousarray(Gamma.reshape(n, nx, 2 * n)[:, :3].reshape(3 * n, 2 * n))
        return xi0, Phi, Gamma

    def _about_plan_id(
        self,
        xi0: np.ndarray,
        model: tuple[np.ndarray, np.ndarray],
        condensed: tuple[np.ndarray, np.ndarray],
        ref: ReferenceHorizon,
        u_ref: np.ndarray,
        plan: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``Phi, Gamma`` of every state, the pose rows linearised about ``plan`` shifted a step.

        The wheel and the commands on their way are linear in the commands: the model along the
        reference (``model``, its ``A, B``; ``condensed``, its ``Phi, Gamma``) gives the wheel
        angles of the shifted plan ``U_bar`` exactly. The pose is rolled out from the measured
        one with those wheel angles and the plan's speeds (heading rate
        ``v tan(delta_w) / (L + K v^2)``), the pose rows of ``A, B`` are linearised there, and the
        roll-out's offset from the new linear prediction goes into the constant state's column,
        as :meth:`LinearMPC._about_plan` does for the kinematic model.
        """
        n, nx, T = self.config.horizon, len(xi0), self.config.dt
        L, K = self.vehicle.wheelbase, self.model.understeer_gradient
        u_bar = np.vstack([plan[1:], plan[-1:]])
        du_bar = (u_bar - u_ref).reshape(-1)
        Phi, Gamma = condensed
        states = (Phi @ xi0 + Gamma @ du_bar).reshape(n, nx)
        wheel_ref = self._wheel_reference(ref)
        wheel = wheel_ref[:n] + np.concatenate([[xi0[3]], states[:-1, 3]])
        speed = u_bar[:, 0]
        l_eff = effective_wheelbase(L, K, speed)
        start = (ref.x[0] + xi0[0], ref.y[0] + xi0[1], ref.theta[0] + xi0[2])
        turns = T * speed * np.tan(wheel) / l_eff
        theta, pose = roll_out(start, speed, turns, T, ref, midpoint=self.config.midpoint)
        A, B = (m.copy() for m in model)
        A[:, 0, 2] = -speed * np.sin(theta) * T
        A[:, 1, 2] = speed * np.cos(theta) * T
        A[:, 2, 3] = speed * T / (l_eff * np.cos(wheel) ** 2)
        B[:, 0, 0] = np.cos(theta) * T
        B[:, 1, 0] = np.sin(theta) * T
        B[:, 2, 0] = np.tan(wheel) * T * (L - K * speed * speed) / (l_eff * l_eff)
        Phi, Gamma = condense(A, B)
        linear = (Phi @ xi0 + Gamma @ du_bar).reshape(n, nx)[:, :3]
        Phi.reshape(n, nx, nx)[:, :3, -1] += pose - linear
        return Phi, Gamma

    def kinematic_prediction(self) -> Prediction | None:
        """The last plan with the plain kinematic model's pose prediction along the reference.

        At the path's own inputs ``[v_r, delta_r]``, as the nominal LMPC predicts (no servo, no
        understeer): the input channel a residual model's ``U_p`` lives in
        (:meth:`LinearMPC._along_reference`).
        """
        last = self.last_prediction
        if last is None:
            return None
        n, ref = self.config.horizon, last.reference
        return self._along_reference(last, np.column_stack([ref.v[:n], ref.delta[:n]]))

    def residual_applied(self, command: np.ndarray) -> None:
        # The wheel state runs from the commands the car was sent, the correction included.
        self._guard.previous = np.array(command, dtype=float).reshape(2)

    def _model(
        self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Initial state ``xi0`` and the model ``(A, B)`` of every state along the reference.

        Advances the wheel-angle estimate by one step: call once per step.
        """
        n, T = self.config.horizon, self.config.dt
        L, K = self.vehicle.wheelbase, self.model.understeer_gradient
        v = u_ref[:, 0]
        wheel_ref = self._wheel_reference(ref)
        delta = wheel_ref[:n]
        theta = ref.theta[:n]
        previous = self._guard.previous
        # A servo fitted to the yaw rate's response holds the chassis's yaw lag as well: a measured
        # wheel angle is not its state, so its own wheel is run from the commands.
        measured = math.nan if self.model.fitted_on == "yaw_rate" else observation.steer_angle
        wheel = self._wheel.step(None if previous is None else float(previous[1]), measured)
        # States: pose deviations, the wheel angle, the commands u_{k-1}, ..., u_{k-p} still on
        # their way, each as its deviation from the wheel reference of the step it reaches the
        # wheel (m - j), the coordinates the input deviations of the QP have too, and 1.
        pending = len(self._w) - 1
        nx = 5 + pending
        arrives = np.maximum(self._shift - np.arange(1, pending + 1), 0)
        xi0 = np.empty(nx)
        xi0[:3] = (
            observation.x - ref.x[0],
            observation.y - ref.y[0],
            wrap_scalar(observation.yaw - ref.theta[0]),
        )
        xi0[3] = wheel - delta[0]
        xi0[4:-1] = self._wheel.past_commands[:pending] - wheel_ref[arrives]
        xi0[-1] = 1.0
        l_eff = effective_wheelbase(L, K, v)
        A = np.zeros((n, nx, nx))
        A[:, 0, 0] = A[:, 1, 1] = A[:, 2, 2] = 1.0
        A[:, 0, 2] = -v * np.sin(theta) * T
        A[:, 1, 2] = v * np.cos(theta) * T
        A[:, 2, 3] = v * T / (l_eff * np.cos(delta) ** 2)
        A[:, 3, 3] = self._a
        A[:, 3, 4:-1] = self._w[1:]
        # The shift register: u_{k-j} becomes u_{(k+1)-(j+1)}.
        A[:, 5:-1, 4:-2] = np.eye(max(pending - 1, 0))
        # The constant state: the wheel reference moves on, delta_r(k) - delta_r(k+1), and the
        # command held over the first f seconds of a period had the reference of the one before.
        drift = wheel_ref[:n] - wheel_ref[1:]
        drift[1:] -= self._w[self._shift + 1 :].sum() * (wheel_ref[1:n] - wheel_ref[: n - 1])
        A[:, 3, -1] = drift
        A[:, -1, -1] = 1.0
        B = np.zeros((n, nx, 2))
        B[:, 0, 0] = np.cos(theta) * T
        B[:, 1, 0] = np.sin(theta) * T
        B[:, 2, 0] = np.tan(delta) * T * (L - K * v * v) / (l_eff * l_eff)
        B[:, 3, 1] = self._w[0]
        if pending:
            B[:, 4, 1] = 1.0
        return xi0, A, B


def with_rate_limit(vehicle: VehicleParams, rate_limit: float | None) -> VehicleParams:
    """``vehicle`` with its steering rate limited to ``rate_limit`` (rad/s) too, when that is tighter."""
    if rate_limit is None or rate_limit >= vehicle.steering.max_rate:
        return vehicle
    return replace(vehicle, steering=replace(vehicle.steering, max_rate=rate_limit))
