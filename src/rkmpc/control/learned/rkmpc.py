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
from typing import TYPE_CHECKING

import numpy as np

from rkmpc.control.base import Controller
from rkmpc.control.guard import CommandGuard
from rkmpc.control.learned.adaptation import OutputRLS
from rkmpc.control.learned.lateral_guard import LateralGuard, LateralGuardConfig
from rkmpc.control.learned.lifted import (
    LiftedModel,
    lifted_prediction,
    recipe_state,
    reference_in_local_frame,
)
from rkmpc.control.learned.progress import ProgressSplit, linearisation
from rkmpc.control.learned.residual_config import PAPER_RESIDUAL, ResidualMPCConfig, RKMPCConfig
from rkmpc.control.learned.trust import CorrectionTrust
from rkmpc.control.linear.lmpc import LinearMPC, LMPCConfig, Prediction
from rkmpc.control.qp import make_qp
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.learning.data.residuals import kinematic_inverse
from rkmpc.learning.features import FeatureMap
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.control.settings import ControllerSettings
    from rkmpc.track.reference import Reference


def _all_finite(values: np.ndarray) -> bool:
    """Whether every entry of a small float array is finite."""
    return bool(np.isfinite(values).all())


class _ResidualBase(Controller):
    """LMPC baseline plus a residual QP; subclasses supply the residual problem."""

    #: Residual MPC settings used when none are given.
    default_config: ResidualMPCConfig = ResidualMPCConfig()
    #: Whether the residual QP's Hessian changes every step (then it is factorised with LAPACK).
    varying_hessian = True

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        model: LiftedModel,
        config: ResidualMPCConfig | None = None,
        lmpc_config: LMPCConfig | None = None,
    ) -> None:
        super().__init__(reference, vehicle.wheelbase)
        self.reference = reference
        self.vehicle = vehicle
        self.model = model
        self.config = config if config is not None else self.default_config
        self._check_config(self.config)
        self.state: FeatureMap = recipe_state(self.name)
        self.lmpc = LinearMPC(reference, vehicle, lmpc_config)
        self.dt = self.lmpc.config.dt
        n = self.lmpc.config.horizon
        self.horizon = n
        self._qp = make_qp(
            self.config.solver, max_iterations=self.config.max_iterations, factorize=self.varying_hessian
        )
        self._d_max = np.tile([self.config.max_speed_correction, self.config.max_steer_correction], n)
        self._neg_d_max = -self._d_max
        # The LMPC's speed floor bounds the corrected command too (its settings are the baseline's).
        self._guard = CommandGuard(vehicle, self.lmpc.config.dt, n, self.lmpc.config.speed_floor)
        self._u_min = np.tile(self._guard.u_min, n)
        self._u_max = np.tile(self._guard.u_max, n)
        w = [self.config.position_weight, self.config.position_weight, self.config.heading_weight]
        self._q = np.tile(w, n)
        self._r = np.tile([self.config.speed_weight, self.config.steer_weight], n)
        # Correction weights, plus the steering correction's step-to-step changes.
        difference = np.zeros((n, 2 * n))
        difference[np.arange(n), 2 * np.arange(n) + 1] = 1.0
        difference[np.arange(1, n), 2 * np.arange(n - 1) + 1] = -1.0
        self._R = np.diag(self._r) + self.config.steer_rate_weight * difference.T @ difference
        #: Trust (0-1) given to the last correction (:mod:`rkmpc.control.learned.trust`).
        self.trust: CorrectionTrust | None = None
        #: Last correction applied (first step), shape (2,).
        self.last_correction = np.zeros(2)
        #: The lateral-deviation constraint of the residual QP (``rkmpc`` only; off for the paper's).
        self.lateral = LateralGuard(n, vehicle.wheelbase, self._lateral_config())
        # The Hessian the residual QP holds (a fixed one need not be passed again).
        self._qp_hessian: np.ndarray | None = None
        self._precompute()

    def _lateral_config(self) -> LateralGuardConfig:
        """The lateral guard's settings (subclasses with one): off here."""
        return LateralGuardConfig()

    def _check_config(self, config: ResidualMPCConfig) -> None:
        """Refuse settings of another class than this controller's (subclasses)."""
        if type(config) is not type(self.default_config):
            raise ParameterError(
                f"{self.name} takes a {type(self.default_config).__name__}, got {type(config).__name__}"
            )

    @classmethod
    def from_settings(
        cls, reference: Reference, vehicle: VehicleParams, settings: ControllerSettings, model: object = None
    ) -> _ResidualBase:
        config = getattr(settings, cls.settings_field or "")
        model = cls.require_model(model)
        return cls(reference, vehicle, model, config=config, lmpc_config=settings.lmpc)  # type: ignore[arg-type]

    def _precompute(self) -> None:
        """Compute what does not change between steps (subclasses)."""

    def _reset(self) -> None:
        self.lmpc.reset()
        self._guard.reset()
        self.last_correction = np.zeros(2)
        self.lateral.reset()
        if self.trust is not None:
            self.trust.reset()

    def diagnostics(self) -> dict[str, float]:
        """Steps on which the correction was faded, by cause, and the mean trust (for the run's record)."""
        guarded = {"lateral_guard_steps": float(self.lateral.steps)} if self.lateral.config.enabled else {}
        if self.trust is None:
            return guarded
        return {
            **guarded,
            "trust_steps": float(self.trust.steps),
            "trust_faded_range": float(self.trust.faded["range"]),
            "trust_faded_error": float(self.trust.faded["error"]),
            "trust_mean": self.trust.mean,
        }

    def assume_previous(self, command: np.ndarray) -> None:
        """Start as if ``command`` (``[speed, steer]``) had been sent at the step before the next one.

        After :meth:`reset` the controller knows no previous command and assumes the car holds
        what it measures; a car that starts while holding a known command can say so here.
        """
        self._guard.previous = np.array(command, dtype=float).reshape(2)

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        base = self.lmpc.step(observation)
        pred = self.lmpc.last_prediction
        if self.lmpc.info.status != "ok" or pred is None:
            return (
                self._apply(np.array([base.speed, base.steer]), np.zeros(2)),
                self.lmpc.info.status,
                self.lmpc.info.message,
            )
        plan = pred.plan.reshape(-1)
        try:
            H, f = self._residual_qp(observation, pred, plan)
        except FloatingPointError as exc:  # non-finite features: keep the baseline
            return self._apply(np.array([base.speed, base.steer]), np.zeros(2)), "guard", str(exc)
        lb = self._u_min - plan
        # The corrected speeds stay at or above the floor: the QP plans with it.
        np.subtract(self._guard.speed_floor(pred.u_ref[:, 0]), pred.plan[:, 0], out=lb[0::2])
        np.maximum(lb, self._neg_d_max, out=lb)
        ub = self._u_max - plan
        np.minimum(ub, self._d_max, out=ub)
        # As the LMPC: never faster than the reference speed profile.
        np.minimum(ub[0::2], pred.u_ref[:, 0] - pred.plan[:, 0], out=ub[0::2])
        np.minimum(lb, ub, out=lb)
        if self.config.steer_rate_weight > 0.0:
            # The first correction's change from the one applied last: w (d_0 - d_last)^2 adds
            # -2 w d_last to its linear term (before the QP is given it).
            f = f.copy()
            f[1] -= 2.0 * self.config.steer_rate_weight * self.last_correction[1]
        lateral = self.lateral
        if not self._qp.is_setup:
            self._qp.setup(H, f, lb, ub, lateral.rows, lateral.lower, lateral.upper)
        else:
            hessian = None if H is self._qp_hessian else H
            if lateral.config.enabled:  # its rows change every step; without it there are none
                self._qp.update(
                    H=hessian, f=f, lb=lb, ub=ub, A=lateral.rows, lbA=lateral.lower, ubA=lateral.upper
                )
            else:
                self._qp.update(H=hessian, f=f, lb=lb, ub=ub)
        self._qp_hessian = H
        result = self._qp.solve()
        if not result.solved or not _all_finite(result.x):
            return self._apply(plan[:2], np.zeros(2)), result.reason, f"residual QP failed: {result.status}"
        lateral.judge(result.x)
        weight = 1.0 if self.trust is None else self.trust.trust
        return self._apply(plan[:2], weight * result.x[:2]), "ok", ""

    def _apply(self, base: np.ndarray, correction: np.ndarray) -> Command:
        """Guard ``base + correction`` at the LMPC's reference speed of this step (its floor)."""
        u = self._guard.apply(base + correction, self.lmpc.reference_speed)
        self.last_correction = u - base
        self._applied(u)
        return Command(speed=float(u[0]), steer=float(u[1]))

    def _applied(self, u: np.ndarray) -> None:
        """Hook: the command ``u`` (shape (2,)) was sent."""

    def _residual_qp(
        self, observation: Observation, pred: Prediction, plan: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError


class ResidualKoopmanMPC(_ResidualBase):
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
    """

    name = "rkmpc"
    settings_field = "rkmpc"
    default_config: RKMPCConfig = RKMPCConfig()
    config: RKMPCConfig

    def _lateral_config(self) -> LateralGuardConfig:
        return self.config.lateral_guard

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
        if not _all_finite(x):
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


class PaperResidualKoopmanMPC(_ResidualBase):
    """The literal reading of the paper's RKMPC (``rkmpc-paper``).

    Parameters
    ----------
    reference, vehicle, config, lmpc_config
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
