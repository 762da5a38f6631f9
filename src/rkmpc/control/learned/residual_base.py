"""The residual MPCs' common part: the LMPC's baseline, a residual QP on top, the guarded sum.

:class:`ResidualMPCBase` runs the LMPC of :mod:`rkmpc.control.linear.lmpc` for the baseline
``U_lmpc`` (or another :class:`~rkmpc.control.linear.lmpc.LinearMPC` given as ``baseline``, whose
plan it corrects through the kinematic prediction the baseline hands it,
:meth:`~rkmpc.control.linear.lmpc.LinearMPC.kinematic_prediction`), asks its subclass for the
residual QP of the correction ``dU``
(:mod:`rkmpc.control.learned.rkmpc`), solves it with the given backend, and sends
``U_lmpc + dU`` clipped to the car's limits and the LMPC's speed floor. A residual QP that fails,
or features that are not finite, send the LMPC's command alone, with the reason as the step's
status.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rkmpc.control.base import Controller
from rkmpc.control.guard import CommandGuard
from rkmpc.control.learned.lateral_guard import LateralGuard, LateralGuardConfig
from rkmpc.control.learned.lifted import LiftedModel, recipe_state
from rkmpc.control.learned.oscillation import OscillationConfig, OscillationDamper
from rkmpc.control.learned.residual_config import ResidualMPCConfig
from rkmpc.control.learned.trust import CorrectionTrust
from rkmpc.control.linear.lmpc import LinearMPC, LMPCConfig, Prediction
from rkmpc.control.qp import make_qp
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.learning.features import FeatureMap
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.control.settings import ControllerSettings
    from rkmpc.track.reference import Reference

__all__ = ["ResidualMPCBase", "all_finite"]


def all_finite(values: np.ndarray) -> bool:
    """Whether every entry of a small float array is finite."""
    return bool(np.isfinite(values).all())


class ResidualMPCBase(Controller):
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
        baseline: LinearMPC | None = None,
    ) -> None:
        super().__init__(reference, vehicle.wheelbase)
        self.reference = reference
        self.vehicle = vehicle
        self.model = model
        self.config = config if config is not None else self.default_config
        self._check_config(self.config)
        self.state: FeatureMap = recipe_state(self.name)
        if baseline is not None and (lmpc_config is not None or baseline.reference is not reference):
            raise ParameterError(
                f"{self.name}: a baseline brings its own settings and must track the same reference; "
                "give either baseline or lmpc_config"
            )
        #: The baseline MPC whose plan the residual QP corrects (the nominal LMPC unless given).
        self.lmpc = baseline if baseline is not None else LinearMPC(reference, vehicle, lmpc_config)
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
        self._rate_gram = difference.T @ difference
        self._R = np.diag(self._r) + self.config.steer_rate_weight * self._rate_gram
        #: Trust (0-1) given to the last correction (:mod:`rkmpc.control.learned.trust`).
        self.trust: CorrectionTrust | None = None
        #: Last correction applied (first step), shape (2,).
        self.last_correction = np.zeros(2)
        #: The lateral-deviation constraint of the residual QP (``rkmpc`` only; off for the paper's).
        self.lateral = LateralGuard(n, vehicle.wheelbase, self._lateral_config())
        #: The damper of the correction's limit cycle (``rkmpc`` only; off for the paper's).
        self.oscillation = OscillationDamper(self._oscillation_config(), vehicle.steering.max_rate, self.dt)
        # What the damping adds to the residual QP's Hessian (``2 w D'D``), once.
        self._damping_hessian = (2.0 * self.oscillation.config.damping_weight) * self._rate_gram
        # The Hessian the residual QP holds (a fixed one need not be passed again).
        self._qp_hessian: np.ndarray | None = None
        self._precompute()

    def _lateral_config(self) -> LateralGuardConfig:
        """The lateral guard's settings (subclasses with one): off here."""
        return LateralGuardConfig()

    def _oscillation_config(self) -> OscillationConfig:
        """The oscillation damper's settings (subclasses with one): off here."""
        return OscillationConfig()

    def _check_config(self, config: ResidualMPCConfig) -> None:
        """Refuse settings of another class than this controller's (subclasses)."""
        if type(config) is not type(self.default_config):
            raise ParameterError(
                f"{self.name} takes a {type(self.default_config).__name__}, got {type(config).__name__}"
            )

    @classmethod
    def from_settings(
        cls, reference: Reference, vehicle: VehicleParams, settings: ControllerSettings, model: object = None
    ) -> ResidualMPCBase:
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
        self.oscillation.reset()
        if self.trust is not None:
            self.trust.reset()

    def diagnostics(self) -> dict[str, float]:
        """Steps on which the correction was faded, by cause, and the mean trust (for the run's record)."""
        guarded = {"lateral_guard_steps": float(self.lateral.steps)} if self.lateral.config.enabled else {}
        if self.oscillation.config.enabled:
            guarded["oscillation_damped_steps"] = float(self.oscillation.steps)
            guarded["oscillation_onsets"] = float(self.oscillation.onsets)
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
        pred = self.lmpc.kinematic_prediction()
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
        damping = self.oscillation.weight
        if damping > 0.0:  # the correction oscillates: its changes weigh more
            H = H + self._damping_hessian
        rate_weight = self.config.steer_rate_weight + damping
        if rate_weight > 0.0:
            # The first correction's change from the one applied last: w (d_0 - d_last)^2 adds
            # -2 w d_last to its linear term (before the QP is given it).
            f = f.copy()
            f[1] -= 2.0 * rate_weight * self.last_correction[1]
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
        if not result.solved or not all_finite(result.x):
            return self._apply(plan[:2], np.zeros(2)), result.reason, f"residual QP failed: {result.status}"
        lateral.judge(result.x)
        weight = 1.0 if self.trust is None else self.trust.trust
        return self._apply(plan[:2], weight * result.x[:2]), "ok", ""

    def _apply(self, base: np.ndarray, correction: np.ndarray) -> Command:
        """Guard ``base + correction`` at the LMPC's reference speed of this step (its floor)."""
        u = self._guard.apply(base + correction, self.lmpc.reference_speed)
        self.last_correction = u - base
        self.oscillation.observe(float(base[1]), float(self.last_correction[1]))
        self.lmpc.residual_applied(u)
        self._applied(u)
        return Command(speed=float(u[0]), steer=float(u[1]))

    def _applied(self, u: np.ndarray) -> None:
        """Hook: the command ``u`` (shape (2,)) was sent."""

    def _residual_qp(
        self, observation: Observation, pred: Prediction, plan: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError
