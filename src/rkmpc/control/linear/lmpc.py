"""Linear MPC on the linearised kinematic bicycle model (the paper's MPC1).

At each step the kinematic model is linearised along the time-indexed
reference (paper Eq. 2-3), the deviation dynamics are condensed into a dense
QP in the input deviations (:mod:`rkmpc.control.linear.problem`), and the QP is
solved by a backend of :mod:`rkmpc.control.qp` that was set up once and is only
updated. The QP's Hessian changes at every step, so it is factorised with
LAPACK rather than by the QP solver (see :class:`rkmpc.control.qp.DaqpQP`).

With ``linearisation = "plan"`` the model is linearised instead about the previous step's plan,
shifted by one step and rolled out from the measured pose (the linear time-varying MPC of a
real-time iteration); ``"plan-midpoint"`` rolls the plan out with each step's positions advanced
along the heading at the middle of the step, second-order accurate where forward Euler is first
(:func:`roll_out`). The prediction then has an affine part, carried as a constant state: a 1
appended to the initial deviation and one more column of ``Phi``, as the identified LMPC carries
its constant state (:mod:`rkmpc.control.linear.lmpc_id`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from rkmpc.control.linear.problem import KinematicMPCProblem, Prediction
from rkmpc.control.qp import QP_SOLVERS, make_qp
from rkmpc.control.tracking import Solution, TrackingController, TrackingCost, check_iterations
from rkmpc.core.angles import wrap_scalar
from rkmpc.core.observation import Observation
from rkmpc.core.validation import require_choice
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference, ReferenceHorizon

__all__ = ["LINEARISATIONS", "LMPCConfig", "LinearMPC", "roll_out"]

#: Where :class:`LinearMPC` linearises the kinematic model (:attr:`LMPCConfig.linearisation`).
LINEARISATIONS = ("reference", "plan", "plan-midpoint")


@dataclass(frozen=True)
class LMPCConfig(TrackingCost):
    """Weights, horizon and solver of the linear MPC.

    The stage cost is the paper's MPC1,
    ``(x-x_r)^2 + (y-y_r)^2 + heading*(theta-theta_r)^2 + speed*(v-v_r)^2 +
    steer*(delta-delta_r)^2``, plus a penalty on the change of each input from
    one step to the next (per step, not per second), which the baseline needs
    to stay smooth on the real plant. The horizon, period and weights are
    those of :class:`rkmpc.control.tracking.TrackingCost`.

    Parameters
    ----------
    solver : str
        QP backend, ``"daqp"`` (default) or ``"osqp"``.
    max_iterations : int
        QP iteration budget per step; a solve that exceeds it falls back.
    linearisation : str
        Where the kinematic model is linearised: ``"reference"`` (default), along the time-indexed
        reference as the paper's MPC1 (Eq. 2-3); ``"plan"``, about the previous step's plan shifted
        by one step and rolled out from the measured pose, with the affine term (along the reference
        on the first step and after a failed solve); ``"plan-midpoint"``, the same with the plan rolled
        out by the midpoint rule (:func:`roll_out`). The forward-Euler roll-out of ``"plan"`` predicts
        a car in a corner outside the arc it drives, and the LMPC steers into corners earlier to undo
        that: most of what ``"plan"`` gains (``docs/design.md``). The LMPC, ``lmpc-id`` (its pose
        rows; its servo is linear) and the baselines of ``rkmpc`` and ``rkmpc-paper`` read it;
        ``kmpc``, which shares these settings, has no kinematic model to linearise.
    """

    solver: str = "daqp"
    max_iterations: int = 200
    linearisation: str = "reference"

    def __post_init__(self) -> None:
        super().__post_init__()
        check_iterations(self, self.max_iterations)
        require_choice(self, "solver", QP_SOLVERS)
        require_choice(self, "linearisation", LINEARISATIONS)

    @property
    def about_plan(self) -> bool:
        """Whether the model is linearised about the previous plan (either roll-out rule)."""
        return self.linearisation != "reference"

    @property
    def midpoint(self) -> bool:
        """Whether the plan is rolled out by the midpoint rule (:func:`roll_out`)."""
        return self.linearisation == "plan-midpoint"


class LinearMPC(TrackingController):
    """The paper's linear MPC (MPC1) on the kinematic bicycle model.

    Parameters
    ----------
    reference : Reference
        The path and speed profile to track.
    vehicle : VehicleParams
        Wheelbase and actuator limits.
    config : LMPCConfig, optional
        Weights, horizon and solver.

    Attributes
    ----------
    last_plan : numpy.ndarray or None
        Absolute inputs ``[v, delta]`` of the last successful solve, shape (N, 2).
    last_prediction : Prediction or None
        The prediction of the last step (for controllers built on top of the LMPC).
    """

    name = "lmpc"
    settings_field = "lmpc"
    #: Model states after ``[x, y, theta]`` (subclasses with richer models).
    extra_states = 0
    config: LMPCConfig

    def __init__(
        self, reference: Reference, vehicle: VehicleParams, config: LMPCConfig | None = None
    ) -> None:
        super().__init__(reference, vehicle, config if config is not None else LMPCConfig())
        self.problem = KinematicMPCProblem(self.config, vehicle, extra_states=self.extra_states)
        # The Hessian follows the reference: factorised by LAPACK, not by the solver, at every step.
        self._qp = make_qp(self.config.solver, max_iterations=self.config.max_iterations, factorize=True)
        self.last_plan: np.ndarray | None = None
        self.last_prediction: Prediction | None = None

    def _reset_solver(self) -> None:
        self.last_plan = None
        self.last_prediction = None

    def _solve(self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray) -> Solution:
        n = self.config.horizon
        xi0, Phi, Gamma = self._prediction(observation, ref, u_ref)
        problem = self.problem
        H, f, lb, ub, lbA, ubA = problem.qp_numbers(
            xi0, u_ref, self.previous_command, Phi, Gamma, self._speed_bounds(u_ref)
        )
        if not self._qp.is_setup:
            self._qp.setup(H, f, lb, ub, problem.A_rate, lbA, ubA)
        else:
            self._qp.update(H=H, f=f, lb=lb, ub=ub, lbA=lbA, ubA=ubA)
        result = self._qp.solve()
        solved = result.solved and bool(np.isfinite(result.x).all())
        plan = u_ref + result.x.reshape(n, 2) if solved else u_ref.copy()
        self.last_prediction = Prediction(
            xi0=xi0, Phi=Phi, Gamma=Gamma, u_ref=u_ref, plan=plan, solved=solved, reference=ref
        )
        self.last_plan = plan if solved else None
        if solved:
            return Solution(plan, "")
        return Solution(None, f"QP failed: {result.status}", result.reason)

    def kinematic_prediction(self) -> Prediction | None:
        """The last step's plan with the kinematic model's prediction (for a residual MPC on top).

        A residual MPC (:mod:`rkmpc.control.learned.residual_base`) corrects the plan through the
        kinematic model's input channel, so it needs the pose deviations predicted by the kinematic
        model along the reference. Linearised along the reference, that is the LMPC's own
        prediction; linearised about its plan, or with a richer model
        (:class:`~rkmpc.control.linear.lmpc_id.IdentifiedLMPC`), it is the plan with the kinematic
        prediction along the reference (:meth:`_along_reference`). None before the first step.
        """
        last = self.last_prediction
        if last is None or not self.config.about_plan:
            return last
        return self._along_reference(last, last.u_ref)

    def _along_reference(self, last: Prediction, u_ref: np.ndarray) -> Prediction:
        """``last`` with the pose deviation and the kinematic ``Phi, Gamma`` along the reference.

        Linearised at the reference inputs ``u_ref`` (``[v_r, delta_r]``, shape (N, 2)), as the
        nominal LMPC predicts (no affine part, no servo, no understeer): the input channel a
        residual model's ``U_p`` lives in.
        """
        n = self.config.horizon
        ref = last.reference
        Phi, Gamma = self.problem.prediction_matrices(ref.theta[:n], u_ref[:, 0], u_ref[:, 1])
        return replace(last, xi0=last.xi0[:3].copy(), Phi=Phi, Gamma=Gamma, u_ref=u_ref)

    def residual_applied(self, command: np.ndarray) -> None:
        """A residual MPC on top sent ``command`` (``[speed, steer]``) after this step's plan.

        The nominal LMPC keeps planning from its own last command, as ``rkmpc`` was tuned with; a
        baseline whose model runs the servo from the commands sent overrides this.
        """

    def _prediction(
        self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Initial deviation and condensed prediction ``(xi0, Phi, Gamma)`` of the model."""
        n = self.config.horizon
        xi0 = np.array(
            [
                observation.x - ref.x[0],
                observation.y - ref.y[0],
                wrap_scalar(observation.yaw - ref.theta[0]),
            ]
        )
        if not self.config.about_plan:
            Phi, Gamma = self.problem.prediction_matrices(ref.theta[:n], u_ref[:, 0], u_ref[:, 1])
            return xi0, Phi, Gamma
        return self._about_plan(observation, xi0, ref, u_ref)

    def _about_plan(
        self, observation: Observation, xi0: np.ndarray, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(xi0, 1)`` and ``([Phi, a], Gamma)`` linearised about the previous plan, shifted a step.

        The plan's inputs ``U_bar`` (the last one held) are rolled out from the measured pose with
        the kinematic model (:func:`roll_out`), giving ``X_bar``. Linearised there, the deviations from
        the reference are ``X = (X_bar - X_r) + Gamma ((U - U_r) - (U_bar - U_r))``: with ``xi0`` the
        measured deviation, the affine column is ``a = X_bar - X_r - Phi xi0 - Gamma (U_bar - U_r)``.
        Without a plan (the first step, after a failed solve) ``U_bar`` is the reference's and
        ``a`` is zero.
        """
        n, T = self.config.horizon, self.config.dt
        if self.last_plan is None:
            Phi, Gamma = self.problem.prediction_matrices(ref.theta[:n], u_ref[:, 0], u_ref[:, 1])
            return np.append(xi0, 1.0), np.column_stack([Phi, np.zeros(3 * n)]), Gamma
        u_bar = np.vstack([self.last_plan[1:], self.last_plan[-1:]])
        speed, steer = u_bar[:, 0], u_bar[:, 1]
        start = (observation.x, observation.y, ref.theta[0] + xi0[2])
        turns = T * speed * np.tan(steer) / self.vehicle.wheelbase
        theta, x_bar = roll_out(start, speed, turns, T, ref, midpoint=self.config.midpoint)
        Phi, Gamma = self.problem.prediction_matrices(theta, speed, steer)
        affine = x_bar.reshape(-1) - Phi @ xi0 - Gamma @ (u_bar - u_ref).reshape(-1)
        return np.append(xi0, 1.0), np.column_stack([Phi, affine]), Gamma


def roll_out(
    start: tuple[float, float, float],
    speed: np.ndarray,
    turns: np.ndarray,
    dt: float,
    ref: ReferenceHorizon,
    *,
    midpoint: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """A plan's pose, rolled out from ``start``, and its deviation from ``ref``.

    Forward Euler by default, as the linear model is discretised: each step moves ``dt * speed``
    along the heading at its start. With ``midpoint`` it moves along the heading at the middle of
    the step (the start's plus half the step's turn). For a constant turn that is the direction of
    the arc's chord: the steps are chords of a circle larger than the car's by a relative
    ``turn^2 / 24``. Forward Euler's steps start half a turn too early and end outside the car's
    circle by about ``dt * speed * turn / 2`` each.

    Parameters
    ----------
    start : tuple of float
        ``(x, y, theta)`` at step 0 (m, m, rad; the heading in the reference's continuous angle).
    speed, turns : numpy.ndarray
        The plan's speed (m/s) and heading change (rad) of each step, shape (N,).
    dt : float
        The period (s).
    ref : ReferenceHorizon
        The reference the deviations are taken from.
    midpoint : bool
        Advance the positions along each step's middle heading instead of its first.

    Returns
    -------
    theta : numpy.ndarray
        Headings (rad) of steps 0..N-1, shape (N,): where the model is linearised.
    deviation : numpy.ndarray
        ``[x, y, theta]`` of steps 1..N less the reference's, shape (N, 3).
    """
    n = len(speed)
    heading = np.empty(n + 1)
    heading[0] = start[2]
    heading[1:] = heading[0] + np.cumsum(turns)
    theta = heading[:n]
    course = theta + 0.5 * turns if midpoint else theta
    deviation = np.empty((n, 3))
    deviation[:, 0] = start[0] + np.cumsum(dt * speed * np.cos(course)) - ref.x[1 : n + 1]
    deviation[:, 1] = start[1] + np.cumsum(dt * speed * np.sin(course)) - ref.y[1 : n + 1]
    deviation[:, 2] = heading[1:] - ref.theta[1 : n + 1]
    return theta, deviation
