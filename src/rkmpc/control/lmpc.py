"""Linear MPC on the linearised kinematic bicycle model (the paper's MPC1).

At each step the kinematic model is linearised along the time-indexed
reference (paper Eq. 2-3), the deviation dynamics are condensed into a dense
QP in the input deviations, and the QP is solved by a backend of
:mod:`rkmpc.control.qp` that was set up once and is only updated.

The linearised matrices ``A_k`` have the form ``I + E_k`` with ``E_k`` non-zero
only in the heading column, so any product ``A_k ... A_i`` equals
``I + sum(E_j)``. The condensed prediction matrices are therefore built from
cumulative sums in a few vectorised operations, without a loop over the horizon.

Everything that depends only on the weights and the horizon (tiled bounds,
weights, the rate penalty) is computed once; a step builds the prediction, the
QP numbers and the command with a few dozen small numpy operations. The QP's
Hessian changes at every step, so it is factorised with LAPACK rather than by
the QP solver (see :class:`rkmpc.control.qp.DaqpQP`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rkmpc._validation import require_nonnegative, require_positive
from rkmpc.control.base import Command, Controller, Observation
from rkmpc.control.guard import CommandGuard
from rkmpc.control.qp import make_qp
from rkmpc.errors import ParameterError
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference, ReferenceHorizon


def wrap_angle(angle: float) -> float:
    """Wrap an angle (rad) to ``[-pi, pi)``."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


#: Weights shared by the MPC configurations (all finite and >= 0).
MPC_WEIGHTS = (
    "position_weight",
    "heading_weight",
    "speed_weight",
    "steer_weight",
    "speed_rate_weight",
    "steer_rate_weight",
    "terminal_factor",
)


@dataclass(frozen=True)
class LMPCConfig:
    """Weights, horizon and solver of the linear MPC.

    The stage cost is the paper's MPC1,
    ``(x-x_r)^2 + (y-y_r)^2 + heading*(theta-theta_r)^2 + speed*(v-v_r)^2 +
    steer*(delta-delta_r)^2``, plus a penalty on the change of each input from
    one step to the next (per step, not per second), which the baseline needs
    to stay smooth on the real plant.

    Parameters
    ----------
    horizon : int
        Prediction horizon N (steps).
    dt : float
        Control period T (s).
    position_weight : float
        Weight of the squared x and y errors (1/m^2 relative units).
    heading_weight : float
        lambda: weight of the squared heading error.
    speed_weight : float
        mu: weight of the squared speed deviation.
    steer_weight : float
        epsilon: weight of the squared steering deviation.
    speed_rate_weight, steer_rate_weight : float
        Weights of the squared step-to-step changes of speed and steering.
    terminal_factor : float
        Multiplier of the state weights at the last step of the horizon.
    speed_margin : float
        Largest speed above the reference speed profile the MPC may command
        (m/s). Without it the kinematic model, in which yaw rate grows with
        speed, accelerates into corners whenever the steering saturates.
    solver : str
        QP backend, ``"daqp"`` (default) or ``"osqp"``.
    max_iterations : int
        QP iteration budget per step; a solve that exceeds it falls back.
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
    solver: str = "daqp"
    max_iterations: int = 200

    def __post_init__(self) -> None:
        if self.horizon < 2:
            raise ParameterError(f"LMPCConfig.horizon must be >= 2, got {self.horizon}")
        require_positive(self, "dt")
        require_nonnegative(self, *MPC_WEIGHTS)
        if self.speed_weight + self.speed_rate_weight <= 0 or self.steer_weight + self.steer_rate_weight <= 0:
            raise ParameterError("LMPCConfig: each input needs a positive weight or rate weight")
        if self.max_iterations < 1:
            raise ParameterError(f"LMPCConfig.max_iterations must be >= 1, got {self.max_iterations}")


@dataclass(frozen=True)
class Prediction:
    """What the MPC predicted at its last step (for controllers built on top of it).

    Parameters
    ----------
    xi0 : numpy.ndarray
        Initial deviation from the reference, shape (nx,).
    Phi, Gamma : numpy.ndarray
        Condensed prediction of the deviations, shapes (N*nx, nx) and (N*nx, 2N).
    u_ref : numpy.ndarray
        Reference inputs, shape (N, 2).
    plan : numpy.ndarray
        Planned absolute inputs, shape (N, 2).
    solved : bool
        Whether the QP was solved.
    reference : ReferenceHorizon
        The reference horizon the step tracked.
    """

    xi0: np.ndarray
    Phi: np.ndarray
    Gamma: np.ndarray
    u_ref: np.ndarray
    plan: np.ndarray
    solved: bool
    reference: ReferenceHorizon


def condense(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Condensed prediction of a time-varying linear system.

    For ``xi_{k+1} = A_k xi_k + B_k u_k``, returns ``Phi`` (N*nx, nx) and block
    lower-triangular ``Gamma`` (N*nx, N*nu) with ``[xi_1; ...; xi_N] = Phi xi_0 + Gamma U``.

    Parameters
    ----------
    A : numpy.ndarray
        Shape (N, nx, nx).
    B : numpy.ndarray
        Shape (N, nx, nu).
    """
    n, nx, nu = B.shape
    Phi = np.empty((n, nx, nx))
    # Row block k of Gamma: columns of the inputs 0..k (the later ones stay zero).
    Gamma = np.zeros((n, nx, n * nu))
    np.copyto(Phi[0], A[0])
    Gamma[0, :, :nu] = B[0]
    for k in range(1, n):
        np.matmul(A[k], Phi[k - 1], out=Phi[k])
        np.matmul(A[k], Gamma[k - 1, :, : k * nu], out=Gamma[k, :, : k * nu])
        Gamma[k, :, k * nu : (k + 1) * nu] = B[k]
    return Phi.reshape(n * nx, nx), Gamma.reshape(n * nx, n * nu)


class KinematicMPCProblem:
    """The condensed QP of MPC1 for one reference horizon (numbers only, no solver).

    Decision variables are the input deviations ``[dv_0, ddelta_0, dv_1, ...]``
    from the reference inputs, shape (2N,).

    Parameters
    ----------
    config : LMPCConfig
        Weights and horizon.
    vehicle : VehicleParams
        Wheelbase and input limits.
    extra_states : int
        States appended after ``[x, y, theta]`` by a richer model (unweighted).
    """

    def __init__(self, config: LMPCConfig, vehicle: VehicleParams, extra_states: int = 0) -> None:
        n = config.horizon
        self.config = config
        self.vehicle = vehicle
        self.n = n
        w_state = np.array(
            [config.position_weight, config.position_weight, config.heading_weight] + [0.0] * extra_states
        )
        q = np.tile(w_state, n)
        q[-len(w_state) :] *= config.terminal_factor
        self.q_diag = q
        self.r_diag = np.tile([config.speed_weight, config.steer_weight], n)
        self.w_rate = np.tile([config.speed_rate_weight, config.steer_rate_weight], n)
        # D maps U to [u_0, u_1 - u_0, ..., u_{N-1} - u_{N-2}].
        D = np.eye(2 * n) - np.eye(2 * n, k=-2)
        self.D = D
        self.DtWD = D.T @ (self.w_rate[:, None] * D)
        self.R_plus_rate = np.diag(self.r_diag) + self.DtWD
        # Doubled weights: scaling by two is exact, so 2 (a + b) is assembled as 2a + 2b.
        self._q2 = 2.0 * q
        self._w2 = 2.0 * self.w_rate
        self._R2 = 2.0 * self.R_plus_rate
        # Steering-rate constraint rows: the steering entries of D U.
        self.A_rate = D[1::2, :].copy()
        self.steer_step_max = vehicle.steering.max_rate * config.dt
        self.u_min = np.array([vehicle.drive.min_speed, -vehicle.steering.max_angle])
        self.u_max = np.array([vehicle.drive.max_speed, vehicle.steering.max_angle])
        #: Input bounds over the horizon, shape (2N,).
        self.U_min = np.tile(self.u_min, n)
        self.U_max = np.tile(self.u_max, n)
        # Causality mask of Gamma seen as (step k, state, input column 2i + j): i <= k.
        self._causal = np.repeat(np.tril(np.ones((n, n))), 2, axis=1)[:, None, :]
        # Phi of a model whose A_k are all the identity (the heading column is filled per step).
        self._phi_identity = np.tile(np.eye(3), (n, 1, 1))

    def prediction_matrices(
        self, theta_r: np.ndarray, v_r: np.ndarray, delta_r: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Condensed prediction ``X = Phi @ xi0 + Gamma @ U`` along the reference.

        Parameters
        ----------
        theta_r, v_r, delta_r : numpy.ndarray
            Reference heading (rad), speed (m/s) and wheel angle (rad), shape (N,).

        Returns
        -------
        Phi : numpy.ndarray
            Shape (3N, 3).
        Gamma : numpy.ndarray
            Shape (3N, 2N), block lower triangular.
        """
        n = self.n
        T, L = self.config.dt, self.vehicle.wheelbase
        # The non-trivial entries of linearize_discrete's A_k and B_k, with the same arithmetic.
        sin_t, cos_t = np.sin(theta_r), np.cos(theta_r)
        ca = np.cumsum(-v_r * sin_t * T)
        cb = np.cumsum(v_r * cos_t * T)
        B2 = np.empty((n, 2))
        B2[:, 0] = np.tan(delta_r) * T / L
        B2[:, 1] = v_r * T / (L * np.cos(delta_r) ** 2)
        b2 = B2.reshape(2 * n)
        # Row k of block row r of Gamma, G[k, r], maps all inputs (column 2i + j: input j at
        # step i) to state r of step k+1: B_i plus the sums of the heading columns of A_{i+1..k}.
        # The speed column of B_i holds cos/sin(theta_i) T in x/y, its steering column nothing.
        G = np.empty((n, 3, 2 * n))
        np.subtract(ca[:, None], np.repeat(ca, 2), out=G[:, 0])
        G[:, 0] *= b2
        G[:, 0, 0::2] += cos_t * T
        np.subtract(cb[:, None], np.repeat(cb, 2), out=G[:, 1])
        G[:, 1] *= b2
        G[:, 1, 0::2] += sin_t * T
        G[:, 2] = b2
        # Causality: input i only affects the states after it.
        G *= self._causal
        Gamma = G.reshape(3 * n, 2 * n)
        Phi = self._phi_identity.copy()
        Phi[:, 0, 2] = ca
        Phi[:, 1, 2] = cb
        return Phi.reshape(3 * n, 3), Gamma

    def qp_numbers(
        self,
        xi0: np.ndarray,
        u_ref: np.ndarray,
        u_prev: np.ndarray,
        Phi: np.ndarray,
        Gamma: np.ndarray,
    ) -> tuple[np.ndarray, ...]:
        """Hessian, gradient and bounds of the condensed QP.

        Parameters
        ----------
        xi0 : numpy.ndarray
            Initial deviation ``[x-x_r, y-y_r, theta-theta_r]``, shape (3,).
        u_ref : numpy.ndarray
            Reference inputs ``[v_r, delta_r]``, shape (N, 2).
        u_prev : numpy.ndarray
            Previously applied input, shape (2,).
        Phi, Gamma : numpy.ndarray
            From :meth:`prediction_matrices`.

        Returns
        -------
        tuple
            ``(H, f, lb, ub, lbA, ubA)``.
        """
        # H = 2 (Gamma' Q Gamma + R + D' W D), f = 2 (Gamma' Q Phi xi0 + D' W d).
        # Q Gamma scales rows of the C-ordered Gamma; BLAS reads its transpose in place.
        GtQ2 = (self._q2[:, None] * Gamma).T
        H = GtQ2 @ Gamma
        H += self._R2
        # Rate offsets d: reference changes, and the jump from the previous input.
        u_flat = u_ref.reshape(-1)
        d = np.empty(2 * self.n)
        np.subtract(u_flat[:2], u_prev, out=d[:2])
        np.subtract(u_flat[2:], u_flat[:-2], out=d[2:])
        # D' (2 W d), with D' the transposed first difference: (D' v)_i = v_i - v_{i+2}.
        rate = self._w2 * d
        rate[:-2] -= rate[2:]
        f = GtQ2 @ (Phi @ xi0)
        f += rate
        lb = self.U_min - u_flat
        ub = self.U_max - u_flat
        # The speed may not exceed the profile (which respects the grip limit) by more than a margin.
        np.minimum(ub[0::2], self.config.speed_margin, out=ub[0::2])
        np.minimum(lb[0::2], ub[0::2], out=lb[0::2])
        d_steer = d[1::2]
        lbA = -self.steer_step_max - d_steer
        ubA = self.steer_step_max - d_steer
        return H, f, lb, ub, lbA, ubA


class LinearMPC(Controller):
    """The paper's linear MPC (MPC1) on the kinematic bicycle model.

    Parameters
    ----------
    reference : Reference
        The path and speed profile to track.
    vehicle : VehicleParams
        Wheelbase and actuator limits.
    config : LMPCConfig, optional
        Weights, horizon and solver.
    """

    name = "lmpc"
    #: Model states after ``[x, y, theta]`` (subclasses with richer models).
    extra_states = 0

    def __init__(
        self, reference: Reference, vehicle: VehicleParams, config: LMPCConfig | None = None
    ) -> None:
        super().__init__()
        self.reference = reference
        self.vehicle = vehicle
        self.config = config if config is not None else LMPCConfig()
        self.problem = KinematicMPCProblem(self.config, vehicle, extra_states=self.extra_states)
        # The Hessian follows the reference: factorised by LAPACK, not by the solver, at every step.
        self._qp = make_qp(self.config.solver, max_iterations=self.config.max_iterations, factorize=True)
        self._guard = CommandGuard(vehicle, self.config.dt, self.config.horizon)
        self._s_hint: float | None = None
        #: Last predicted absolute input sequence, shape (N, 2), and reference horizon.
        self.last_plan: np.ndarray | None = None
        #: The prediction of the last step, or None before the first.
        self.last_prediction: Prediction | None = None

    def _reset(self) -> None:
        self._s_hint = None
        self._guard.reset()
        self.last_plan = None
        self.last_prediction = None

    def solve_plan(self, observation: Observation) -> tuple[np.ndarray, np.ndarray, bool, str]:
        """Solve MPC1 for this observation without applying anything.

        Returns
        -------
        plan : numpy.ndarray
            Absolute inputs ``[v, delta]`` over the horizon, shape (N, 2).
        u_ref : numpy.ndarray
            Reference inputs over the horizon, shape (N, 2).
        solved : bool
            Whether the QP solver succeeded.
        status : str
            The solver's status.
        """
        cfg = self.config
        n = cfg.horizon
        proj = self.reference.project(observation.x, observation.y, self._s_hint)
        self._s_hint = proj.s
        ref = self.reference.horizon(proj.s, n, cfg.dt)
        u_ref = self._reference_inputs(ref)
        guard = self._guard
        if guard.previous is None:
            # First step: the car is taken to hold its speed and the feed-forward angle.
            guard.previous = np.array([observation.speed, u_ref[0, 1]])
        xi0, Phi, Gamma = self._prediction(observation, ref, u_ref)
        problem = self.problem
        H, f, lb, ub, lbA, ubA = problem.qp_numbers(xi0, u_ref, guard.previous, Phi, Gamma)
        if not self._qp.is_setup:
            self._qp.setup(H, f, lb, ub, problem.A_rate, lbA, ubA)
        else:
            self._qp.update(H=H, f=f, lb=lb, ub=ub, lbA=lbA, ubA=ubA)
        result = self._qp.solve()
        solved = result.solved and bool(np.isfinite(result.x).all())
        plan = u_ref + result.x.reshape(n, 2) if solved else u_ref.copy()
        self.last_prediction = Prediction(
            xi0=xi0,
            Phi=Phi,
            Gamma=Gamma,
            u_ref=u_ref,
            plan=plan,
            solved=solved,
            reference=ref,
        )
        return plan, u_ref, solved, result.status

    def _reference_inputs(self, ref: ReferenceHorizon) -> np.ndarray:
        """Reference inputs ``[v_r, delta_r]`` over the horizon, shape (N, 2)."""
        n = self.config.horizon
        u_ref = np.empty((n, 2))
        u_ref[:, 0] = ref.v[:n]
        u_ref[:, 1] = ref.delta[:n]
        return u_ref

    def _prediction(
        self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Initial deviation and condensed prediction ``(xi0, Phi, Gamma)`` of the model."""
        n = self.config.horizon
        xi0 = np.array(
            [
                observation.x - ref.x[0],
                observation.y - ref.y[0],
                wrap_angle(observation.yaw - ref.theta[0]),
            ]
        )
        Phi, Gamma = self.problem.prediction_matrices(ref.theta[:n], u_ref[:, 0], u_ref[:, 1])
        return xi0, Phi, Gamma

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        plan, u_ref, solved, status = self.solve_plan(observation)
        if solved:
            u = self._guard.accept(plan)
            flag, message = "ok", ""
        else:
            u = self._guard.fallback(u_ref[0])
            flag, message = "fallback", f"QP failed: {status}"
        u = self._guard.apply(u)
        self.last_plan = plan if solved else None
        return Command(speed=float(u[0]), steer=float(u[1])), flag, message
