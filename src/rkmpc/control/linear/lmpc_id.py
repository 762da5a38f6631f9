"""``lmpc-id``: the linear MPC with a physically identified model.

The baseline a skeptical expert asks for before any neural network: the same
LMPC (weights, horizon, QP) whose kinematic model is extended with what two
laps of data identify physically (see :mod:`rkmpc.learning.identification`):

* the steering servo as a first-order lag state ``delta_w`` driven by the
  commanded angle, ``delta_w(k+1) = a delta_w(k) + (1 - a) delta_cmd(k)``,
  ``a = exp(-T / tau)``;
* the understeer gradient ``K``: the path curvature the wheel angle produces is
  ``tan(delta_w) / (L + K v^2)``, so steady cornering needs the feed-forward
  ``delta_r = atan((L + K v_r^2) kappa_r)``; both come from
  :mod:`rkmpc.learning.identification`, the model the fit identifies ``K`` in.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rkmpc.control.guard import WheelAngleEstimate
from rkmpc.control.linear.lmpc import LinearMPC, LMPCConfig
from rkmpc.control.linear.problem import condense
from rkmpc.core.angles import wrap_scalar
from rkmpc.core.observation import Observation
from rkmpc.learning.identification import IdentifiedModel, effective_wheelbase, steady_state_steer
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference, ReferenceHorizon


class IdentifiedLMPC(LinearMPC):
    """LMPC on the kinematic model plus an identified servo lag and understeer gradient.

    Parameters
    ----------
    reference : Reference
        Path and speed profile.
    vehicle : VehicleParams
        Wheelbase and limits.
    model : IdentifiedModel
        Identified servo time constant and understeer gradient.
    config : LMPCConfig, optional
        The LMPC's weights (the same as the plain LMPC by default).
    """

    name = "lmpc-id"
    extra_states = 1

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        model: IdentifiedModel,
        config: LMPCConfig | None = None,
    ) -> None:
        super().__init__(reference, vehicle, config)
        self.model = model
        self._wheel = WheelAngleEstimate(model.servo_time_constant, self.config.dt)
        self._a = self._wheel.a

    def _reset_solver(self) -> None:
        super()._reset_solver()
        self._wheel.reset()

    def _reference_inputs(self, ref: ReferenceHorizon) -> np.ndarray:
        n = self.config.horizon
        L, K = self.vehicle.wheelbase, self.model.understeer_gradient
        v = ref.v[:n]
        kappa = np.tan(ref.delta[:n]) / L
        return np.column_stack([v, steady_state_steer(kappa, v, L, K)])

    def _prediction(
        self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n, T = self.config.horizon, self.config.dt
        L, K = self.vehicle.wheelbase, self.model.understeer_gradient
        v, delta = u_ref[:, 0], u_ref[:, 1]
        theta = ref.theta[:n]
        xi0 = np.array(
            [
                observation.x - ref.x[0],
                observation.y - ref.y[0],
                wrap_scalar(observation.yaw - ref.theta[0]),
                self._wheel(observation.steer_angle, self._guard.previous) - delta[0],
            ]
        )
        l_eff = effective_wheelbase(L, K, v)
        A = np.zeros((n, 4, 4))
        A[:, 0, 0] = A[:, 1, 1] = A[:, 2, 2] = 1.0
        A[:, 0, 2] = -v * np.sin(theta) * T
        A[:, 1, 2] = v * np.cos(theta) * T
        A[:, 2, 3] = v * T / (l_eff * np.cos(delta) ** 2)
        A[:, 3, 3] = self._a
        B = np.zeros((n, 4, 2))
        B[:, 0, 0] = np.cos(theta) * T
        B[:, 1, 0] = np.sin(theta) * T
        B[:, 2, 0] = np.tan(delta) * T * (L - K * v * v) / (l_eff * l_eff)
        B[:, 3, 1] = 1.0 - self._a
        Phi, Gamma = condense(A, B)
        return xi0, Phi, Gamma
