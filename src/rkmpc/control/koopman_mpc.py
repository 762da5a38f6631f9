"""KMPC: a linear MPC on a Koopman model of the full vehicle dynamics.

The model (trained on random-excitation data, see
:mod:`rkmpc.learning.excitation`) lifts ``[x, y, theta, speed, yaw_rate,
wheel_angle]`` with the pose in the car's own frame, and takes the command
``[v, delta]`` as input. Each step the car is at the local origin, so only the
lifted initial state and the reference change: the QP's Hessian and constraint
matrix are fixed at construction and only its gradient and bounds are updated.
The cost and constraints are the LMPC's (same weights and horizon).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rkmpc.control.base import Command, Controller, Observation
from rkmpc.control.guard import CommandGuard
from rkmpc.control.lifted import lifted_prediction
from rkmpc.control.lmpc import KinematicMPCProblem, LMPCConfig
from rkmpc.control.qp import make_qp
from rkmpc.control.rkmpc import LiftedModel, reference_in_local_frame
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference

#: State features of the KMPC model, pose in the car's frame first.
KMPC_FEATURES = ("x", "y", "yaw", "speed", "yaw_rate", "steer_angle")


def kmpc_features(observation: Observation) -> np.ndarray:
    """The KMPC model's state at the local origin: ``[0, 0, 0, speed, yaw_rate, steer_angle]``."""
    return np.array([0.0, 0.0, 0.0, observation.speed, observation.yaw_rate, observation.steer_angle])


class KoopmanMPC(Controller):
    """Linear MPC on a lifted (Koopman) model of the whole car (``kmpc``).

    Parameters
    ----------
    reference : Reference
        Path and speed profile.
    vehicle : VehicleParams
        Input limits.
    model : LiftedModel
        Lifted linear model on :data:`KMPC_FEATURES` with input the command; its
        ``C_`` maps the lifted state back to those features.
    config : LMPCConfig, optional
        Weights, horizon and solver (the LMPC's by default).
    """

    name = "kmpc"

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        model: LiftedModel,
        config: LMPCConfig | None = None,
    ) -> None:
        super().__init__()
        self.reference = reference
        self.vehicle = vehicle
        self.model = model
        self.config = config if config is not None else LMPCConfig()
        self.problem = KinematicMPCProblem(self.config, vehicle)
        n = self.config.horizon
        self._Mz, self._Mu = lifted_prediction(model.A_, model.B_, model.C_[:3], None, n, first=1)
        p = self.problem
        MtQ = self._Mu.T * p.q_diag
        self._MtQ = MtQ
        self._H = 2.0 * (MtQ @ self._Mu + np.diag(p.r_diag) + p.DtWD)
        # Doubled gradient terms (2 (a - b - c) is assembled as 2a - 2b - 2c, exactly):
        # only the first input's rate penalty involves the previous command.
        self._MtQ2 = 2.0 * MtQ
        self._r2 = 2.0 * p.r_diag
        self._w2_first = 2.0 * p.w_rate[:2]
        self._qp = make_qp(self.config.solver, max_iterations=self.config.max_iterations)
        self._guard = CommandGuard(vehicle, self.config.dt, n)
        self._s_hint: float | None = None

    def _reset(self) -> None:
        self._s_hint = None
        self._guard.reset()

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        cfg, p = self.config, self.problem
        n = cfg.horizon
        proj = self.reference.project(observation.x, observation.y, self._s_hint)
        self._s_hint = proj.s
        ref = self.reference.horizon(proj.s, n, cfg.dt)
        u_ref = np.empty(2 * n)
        u_ref[0::2] = ref.v[:n]
        u_ref[1::2] = ref.delta[:n]
        guard = self._guard
        if guard.previous is None:
            guard.previous = np.array([observation.speed, u_ref[1]])
        previous = guard.previous
        x0 = kmpc_features(observation)
        if not np.isfinite(x0).all():
            return self._fallback(u_ref, "kmpc needs measured speed, yaw rate and wheel angle")
        z0 = self.model.lift(x0)
        local = reference_in_local_frame(ref, observation).reshape(-1)
        # f = 2 (M' Q (Mz z0 - local) - R u_ref - D' W d0) with d0 = [u_prev, 0, ...].
        np.subtract(self._Mz @ z0, local, out=local)
        f = self._MtQ2 @ local
        f -= self._r2 * u_ref
        f[:2] -= self._w2_first * previous
        lb = p.U_min.copy()
        ub = p.U_max.copy()
        np.minimum(ub[0::2], u_ref[0::2] + cfg.speed_margin, out=ub[0::2])
        np.minimum(lb, ub, out=lb)
        lbA = np.full(n, -p.steer_step_max)
        ubA = np.full(n, p.steer_step_max)
        lbA[0] += previous[1]
        ubA[0] += previous[1]
        if not self._qp.is_setup:
            self._qp.setup(self._H, f, lb, ub, p.A_rate, lbA, ubA)
        else:
            self._qp.update(f=f, lb=lb, ub=ub, lbA=lbA, ubA=ubA)
        result = self._qp.solve()
        if not result.solved or not np.isfinite(result.x).all():
            return self._fallback(u_ref, f"QP failed: {result.status}")
        return self._command(guard.accept(result.x.reshape(n, 2))), "ok", ""

    def _fallback(self, u_ref: np.ndarray, message: str) -> tuple[Command, str, str]:
        return self._command(self._guard.fallback(u_ref[:2])), "fallback", message

    def _command(self, u: np.ndarray) -> Command:
        u = self._guard.apply(u)
        return Command(speed=float(u[0]), steer=float(u[1]))
