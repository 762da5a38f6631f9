"""Residual Koopman MPC: a linear MPC plus a residual MPC on a lifted model.

Both controllers keep the paper's structure: the LMPC of :mod:`rkmpc.control.linear.lmpc`
computes the baseline ``U_lmpc`` on the kinematic model; a residual MPC on a learned lifted linear
(Koopman) model computes the correction ``dU``; the car receives ``U_lmpc + dU`` clipped to its
limits and to the LMPC's speed floor (:class:`rkmpc.control.guard.SpeedFloor`), which bounds the
residual QP too. They differ in what the learned model describes (``docs/method.md``).

``rkmpc`` (default): the residual sits in the kinematic model's input channel. The lifted model,
on features of the speed, wheel angle and yaw rate, predicts the input ``U_p`` the kinematic model
needs to reproduce the car's motion when ``U`` is applied; the residual MPC chooses ``dU`` so that
the kinematic model driven by the predicted ``U_p`` follows the reference, around the LMPC's own
linearisation. Its Hessian changes every step and is factorised with LAPACK
(:class:`rkmpc.control.qp.DaqpQP`); its lateral guard bounds the corrected plan's lateral
deviations (:mod:`rkmpc.control.learned.lateral_guard`).

``rkmpc-paper``: the literal reading. The lifted state is the pose in the car's local frame,
driven by the control residual ``dU``; the residual MPC tracks the reference in the local frame
with ``mu dv^2 + eps ddelta^2`` on the correction (paper Eq. MPC2). Its Hessian is fixed.
"""

from __future__ import annotations

import math

import numpy as np

from rkmpc.control.learned.adaptation import OutputRLS
from rkmpc.control.learned.lateral_guard import LateralGuardConfig
from rkmpc.control.learned.lifted import lifted_prediction, reference_in_local_frame
from rkmpc.control.learned.oscillation import OscillationConfig
from rkmpc.control.learned.progress import ProgressSplit, linearisation
from rkmpc.control.learned.residual_base import ResidualMPCBase, all_finite
from rkmpc.control.learned.residual_config import PAPER_RESIDUAL, RKMPCConfig
from rkmpc.control.learned.trust import CorrectionTrust
from rkmpc.control.linear.lmpc import Prediction
from rkmpc.core.observation import Observation
from rkmpc.learning.data.residuals import kinematic_inverse

__all__ = ["PaperResidualKoopmanMPC", "ResidualKoopmanMPC"]


class ResidualKoopmanMPC(ResidualMPCBase):
    """RKMPC with the residual in the kinematic model's input channel (the default ``rkmpc``).

    Parameters
    ----------
    reference : Reference
        Path and speed profile.
    vehicle : VehicleParams
        The car.
    model : LiftedModel
        Lifted linear model on the ``rkmpc`` recipe's features
        (:data:`rkmpc.learning.features.RESIDUAL_STATE`) with input the applied
        command and output the nominal input ``U_p`` (``y = C z + D u``).
    config : ResidualMPCConfig, optional
        Residual MPC weights and bounds.
    lmpc_config : LMPCConfig, optional
        The baseline LMPC's settings (its defaults otherwise).
    baseline : LinearMPC, optional
        Another baseline whose plan the residual corrects, on the same reference (e.g. ``lmpc-id``'s
        :class:`~rkmpc.control.linear.lmpc_id.IdentifiedLMPC`); the nominal LMPC when None.
        ``benchmarks/residual_baseline.py`` measures it: no better than the nominal one (docs/method.md).
    """

    name = "rkmpc"
    settings_field = "rkmpc"
    default_config: RKMPCConfig = RKMPCConfig()
    config: RKMPCConfig

    def _lateral_config(self) -> LateralGuardConfig:
        return self.config.lateral_guard

    def _oscillation_config(self) -> OscillationConfig:
        return self.config.oscillation

    def _precompute(self) -> None:
        # Time invariant: U_p over the horizon = Mz z0 + Mu U, computed once.
        m = self.model
        self._Mz, self._Mu = lifted_prediction(m.A_, m.B_, m.C_, m.D_, self.horizon, first=0)
        self._z0: np.ndarray | None = None
        # A model that knows its training range and feature map (a KoopmanModel) gets a trust guard.
        x_min, x_max, cx = (getattr(m, name, None) for name in ("x_min_", "x_max_", "Cx_"))
        if x_min is not None and x_max is not None and cx is not None:
            self.trust = CorrectionTrust(m.A_, m.B_, cx, x_min, x_max, self.config.trust)
        self._rls = OutputRLS(m.C_, m.D_, self.config.adaptation) if self.config.adaptation.enabled else None
        self._split = ProgressSplit(self.reference, self.lmpc.problem) if self.config.retimed else None
        # The last step's lifted state, command and pose (for adaptation).
        self._last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._pose = np.zeros(3)
        # Diagonal entries of the residual Hessian that weigh the steering corrections.
        steer = 2 * np.arange(self.horizon) + 1
        self._steer_diag = (steer, steer)
        #: Steps whose slip angle was not measured, so their prediction went without its drift.
        self.slip_unmeasured = 0
        #: Steps that slid sideways faster than half of ``slip_velocity_limit``: drift faded.
        self.slip_drift_faded = 0

    def _reset(self) -> None:
        super()._reset()
        self._last = None
        self.slip_unmeasured = 0
        self.slip_drift_faded = 0
        if self._rls is not None:
            self._rls.reset()
            self._refresh_prediction()

    def diagnostics(self) -> dict[str, float]:
        out = super().diagnostics()
        if self._rls is not None:
            out.update(rls_updates=float(self._rls.updates), rls_skipped=float(self._rls.skipped))
        if self.config.slip_drift:
            out["slip_unmeasured"] = float(self.slip_unmeasured)
            out["slip_drift_faded"] = float(self.slip_drift_faded)
        return out

    def _add_slip_drift(self, e0: np.ndarray, observation: Observation, Phi: np.ndarray) -> None:
        """Add to the predicted deviations ``e0`` (3N,) how a slip angle held over the horizon moves them
        (weighted by :meth:`RKMPCConfig.slip_drift_weight`). The heading column of ``Phi`` holds, in
        its position rows, the sums of ``v_r T (-sin, cos)(theta_r)``: the displacement of a heading
        offset that never turns the car, which is what a car sliding at a fixed angle adds."""
        beta = observation.slip_angle
        if not math.isfinite(beta):
            self.slip_unmeasured += 1
            return
        weight = self.config.slip_drift_weight(beta, observation.speed)
        if weight < 1.0:
            self.slip_drift_faded += 1
        beta *= weight
        for row in (0, 1):  # x and y of every step; the heading rows are not moved
            e0[row::3] += beta * Phi[row::3, 2]

    def _refresh_prediction(self) -> None:
        if self._rls is None:
            return
        m = self.model
        self._Mz, self._Mu = lifted_prediction(m.A_, m.B_, self._rls.C, self._rls.D, self.horizon, first=0)

    def _adapt(self, pose: np.ndarray) -> None:
        """Learn the output map from the step just driven: its ``U_p`` from the two poses."""
        if self._rls is None or self._last is None:
            return
        z, u, last_pose = self._last
        dt = self.lmpc.config.dt
        y = kinematic_inverse(last_pose[None, :], pose[None, :], self.vehicle.wheelbase, dt)[0]
        if self._rls.update(z, u, y):
            self._refresh_prediction()

    def _applied(self, u: np.ndarray) -> None:
        if self.trust is not None and self._z0 is not None:
            self.trust.expect(self._z0, u)
        if self._rls is not None:  # only adaptation looks back at the last step
            self._last = None if self._z0 is None else (self._z0, np.array(u, dtype=float), self._pose)
        self._z0 = None

    def _residual_qp(
        self, observation: Observation, pred: Prediction, plan: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        previous = self._guard.previous
        if previous is None:  # first step: as if the car had been held at what it does now
            previous = np.array([observation.speed, observation.steer_angle])
        x = self.state.of_observation(observation, previous)
        if not all_finite(x):
            raise FloatingPointError("rkmpc needs measured speed, yaw rate and wheel angle")
        z0 = self.model.lift(x)
        if self._rls is not None:
            self._pose = np.array([observation.x, observation.y, observation.yaw])
            self._adapt(self._pose)
        if self.trust is not None:
            self.trust.judge(x)
        self._z0 = np.asarray(z0, dtype=float)
        # Kinematic deviations when the car's effective input is U_p(U_lmpc + dU).
        effective = self._Mz @ z0 + self._Mu @ plan
        Phi, Gamma, theta, u_ref = linearisation(pred, effective, self._split)
        e0 = Phi @ pred.xi0 + Gamma @ (effective - u_ref)
        if self.config.slip_drift:
            self._add_slip_drift(e0, observation, Phi)
        GM = Gamma @ self._Mu
        self.lateral.pose(theta, e0, GM)
        if self._split is not None:
            e0, GM = self._split.rows(pred, effective, self._Mu, e0, GM, theta)
        GtQ = (self._q[:, None] * GM).T
        H = GtQ @ GM
        H += self._R
        if self.config.lateral_accel_weight > 0.0:
            gain = pred.plan[:, 0] ** 2 / self.vehicle.wheelbase  # (m/s^2)/rad at each planned speed
            H[self._steer_diag] += self.config.lateral_accel_weight * gain**2
        H *= 2.0
        f = GtQ @ e0
        f *= 2.0
        return H, f


class PaperResidualKoopmanMPC(ResidualMPCBase):
    """The literal reading of the paper's RKMPC (``rkmpc-paper``).

    Parameters
    ----------
    reference, vehicle, config, lmpc_config, baseline
        As :class:`ResidualKoopmanMPC`.
    model : LiftedModel
        Lifted linear model with state ``[x, y, theta]`` (m, m, rad) in the local frame and
        input the control residual ``dU`` (m/s, rad); ``C`` maps back to the pose.
    """

    name = "rkmpc-paper"
    settings_field = "rkmpc_paper"
    default_config = PAPER_RESIDUAL
    varying_hessian = False

    def _precompute(self) -> None:
        m = self.model
        self._Mz, self._Mu = lifted_prediction(m.A_, m.B_, m.C_[:3], None, self.horizon, first=1)
        # The car sits at the origin of its own frame: the features of any observation are the pose 0.
        origin = self.state.of_observation(Observation(0.0, 0.0, 0.0, 0.0))
        self._free = self._Mz @ np.asarray(m.lift(origin), dtype=float)
        # Fixed Hessian: the model is time invariant and starts at the local origin.
        self._MtQ = self._Mu.T * self._q
        self._H = 2.0 * (self._MtQ @ self._Mu + self._R)

    def _residual_qp(
        self, observation: Observation, pred: Prediction, plan: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        local = reference_in_local_frame(pred.reference, observation).reshape(-1)
        np.subtract(self._free, local, out=local)
        f = self._MtQ @ local
        f *= 2.0
        return self._H, f
