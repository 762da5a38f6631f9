"""KMPC: a linear MPC on a Koopman model of the full vehicle dynamics.

The model (trained on random-excitation data, see
:mod:`rkmpc.learning.data.excitation`) lifts the ``kmpc`` recipe's features
(:data:`rkmpc.learning.features.KMPC_STATE`: ``[x, y, theta, speed,
yaw_rate, wheel_angle]`` with the pose in the car's own frame), and takes the
command ``[v, delta]`` as input. Each step the car is at the local origin, so
only the lifted initial state and the reference change: the QP's Hessian and
constraint matrix are fixed at construction and only its gradient and bounds
are updated. The cost and constraints are the LMPC's (same weights and horizon).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rkmpc.control.learned.lifted import (
    LiftedModel,
    lifted_prediction,
    recipe_state,
    reference_in_local_frame,
)
from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.linear.problem import KinematicMPCProblem
from rkmpc.control.qp import make_qp
from rkmpc.control.tracking import Solution, TrackingController
from rkmpc.core.observation import Observation
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference, ReferenceHorizon

__all__ = ["KoopmanMPC"]


class KoopmanMPC(TrackingController):
    """Linear MPC on a lifted (Koopman) model of the whole car (``kmpc``).

    Parameters
    ----------
    reference : Reference
        Path and speed profile.
    vehicle : VehicleParams
        Input limits.
    model : LiftedModel
        Lifted linear model on :data:`~rkmpc.learning.features.KMPC_STATE` with input the
        command; its ``C_`` maps the lifted state back to those features.
    config : LMPCConfig, optional
        Weights, horizon and solver (the LMPC's by default).
    """

    name = "kmpc"
    settings_field = "lmpc"
    takes_model = True
    #: The features the model was trained on (its recipe's), read from the live observation the same way.
    state = recipe_state("kmpc")
    #: The model's state includes them: NaN (not measured) is refused as invalid input.
    measured_fields = ("yaw_rate", "steer_angle")
    config: LMPCConfig

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        model: LiftedModel,
        config: LMPCConfig | None = None,
    ) -> None:
        super().__init__(reference, vehicle, config if config is not None else LMPCConfig())
        self.model = model
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

    def _solve(self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray) -> Solution:
        cfg, p = self.config, self.problem
        n = cfg.horizon
        u_flat = u_ref.reshape(-1)
        previous = self.previous_command
        x0 = self.state.of_observation(observation)
        if not np.isfinite(x0).all():
            return Solution(None, "kmpc needs measured speed, yaw rate and wheel angle", "invalid_input")
        z0 = self.model.lift(x0)
        local = reference_in_local_frame(ref, observation).reshape(-1)
        # f = 2 (M' Q (Mz z0 - local) - R u_ref - D' W d0) with d0 = [u_prev, 0, ...].
        np.subtract(self._Mz @ z0, local, out=local)
        f = self._MtQ2 @ local
        f -= self._r2 * u_flat
        f[:2] -= self._w2_first * previous
        lb = p.U_min.copy()
        ub = p.U_max.copy()
        lb[0::2], ub[0::2] = self._speed_bounds(u_ref)
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
            return Solution(None, f"QP failed: {result.status}", result.reason)
        return Solution(result.x.reshape(n, 2))
