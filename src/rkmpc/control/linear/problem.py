"""The condensed QP of the paper's MPC1 on the linearised kinematic bicycle model (numbers only).

The linearised matrices ``A_k`` have the form ``I + E_k`` with ``E_k`` non-zero
only in the heading column, so any product ``A_k ... A_i`` equals
``I + sum(E_j)``. The condensed prediction matrices are therefore built from
cumulative sums in a few vectorised operations, without a loop over the horizon.

Everything that depends only on the weights and the horizon (tiled bounds,
weights, the rate penalty) is computed once, in :class:`KinematicMPCProblem`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.control.tracking import TrackingCost
    from rkmpc.track.reference import ReferenceHorizon

__all__ = ["KinematicMPCProblem", "Prediction", "condense"]


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
    config : TrackingCost
        Weights and horizon (an LMPC's or KMPC's configuration).
    vehicle : VehicleParams
        Wheelbase and input limits.
    extra_states : int
        States appended after ``[x, y, theta]`` by a richer model (unweighted).
    """

    def __init__(self, config: TrackingCost, vehicle: VehicleParams, extra_states: int = 0) -> None:
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
        speed_bounds: tuple[np.ndarray, np.ndarray],
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
        speed_bounds : tuple of numpy.ndarray
            Lowest and highest speed (m/s) at each step, shape (N,) each
            (:meth:`rkmpc.control.tracking.TrackingController._speed_bounds`: the car's
            limits, the reference plus the margin, the speed floor).

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
        # The speed stays between the floor and the profile (which respects the grip limit) plus a margin.
        lower, upper = speed_bounds
        np.subtract(lower, u_flat[0::2], out=lb[0::2])
        np.subtract(upper, u_flat[0::2], out=ub[0::2])
        d_steer = d[1::2]
        lbA = -self.steer_step_max - d_steer
        ubA = self.steer_step_max - d_steer
        return H, f, lb, ub, lbA, ubA
