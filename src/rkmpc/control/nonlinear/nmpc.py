"""Nonlinear MPC on the kinematic (the paper's NMPC) and the dynamic single-track model.

Both controllers solve, every control period, the multiple-shooting NLP

.. math::

    \\min_{X, U} \\sum_{k=1}^{N} q_p \\|p_k - p^r_k\\|^2 + q_\\theta (\\theta_k - \\theta^r_k)^2
    + \\sum_{k=0}^{N-1} r_v (v_k - v^r_k)^2 + r_\\delta (\\delta_k - \\delta^r_k)^2
    + w_v (v_k - v_{k-1})^2 + w_\\delta (\\delta_k - \\delta_{k-1})^2

subject to ``X_0 = x(t)``, ``X_{k+1} = F(X_k, U_k)`` (RK4 of the model over one
period), the input bounds of the car, ``v_k <= v^r_k + margin`` and
``|delta_k - delta_{k-1}| <= max_rate * dt``, where ``u_{-1}`` is the input
applied at the previous step. This is the cost and constraint set of
:class:`rkmpc.control.linear.lmpc.LinearMPC`, without the linearisation.

The NLP is built once with CasADi (SX, ``expand=True``); its parameters are
the initial state, the reference poses and inputs over the horizon and the
previous input. Positions are expressed relative to the current reference
point and the observed yaw is unwrapped to the branch of the reference
heading, so the problem is well scaled anywhere on any track. Every step only
sets the parameters and bounds and warm-starts the solver from the previous
solution shifted by one step (primal and dual).

When the solver fails (not converged, iteration or CPU-time budget exceeded,
infeasible, exception) the step falls back to the previous plan shifted by one
step, or to the reference inputs when there is none, and reports
``"fallback"`` with the solver's status.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from rkmpc.control.nonlinear.models import dynamic_ode, kinematic_ode, rk4_map
from rkmpc.control.nonlinear.nlp import SOLVERS, NMPCConfig, TrackingNLP
from rkmpc.control.tracking import Solution, TrackingController
from rkmpc.core.angles import branch_shift, wrap_scalar
from rkmpc.core.errors import ParameterError, raise_if_interrupted
from rkmpc.core.observation import Observation
from rkmpc.estimation.steering import SteeringModel, WheelAnglePropagator
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference, ReferenceHorizon

__all__ = ["NLP_REASONS", "SOLVERS", "DynamicNMPC", "KinematicNMPC", "NMPCConfig"]

#: Controller status of a failed solve by IPOPT's (or the SQP method's) return status; any
#: other failure is ``"numerical"`` (restoration failed, invalid number, step too small, ...).
#: The CPU-time budget is off unless a user opts in; then it is a budget like the iterations.
NLP_REASONS: dict[str, str] = {
    "Infeasible_Problem_Detected": "infeasible",
    "Maximum_Iterations_Exceeded": "iteration_limit",
    "Maximum_CpuTime_Exceeded": "iteration_limit",
    "Maximum_WallTime_Exceeded": "iteration_limit",
}


class KinematicNMPC(TrackingController):
    """The paper's NMPC: the kinematic bicycle model (Eq. 1) in a multiple-shooting NLP.

    States ``[x, y, theta]``, inputs ``[v, delta]``; see the module docstring
    for the NLP.

    Parameters
    ----------
    reference : Reference
        Path and speed profile to track.
    vehicle : VehicleParams
        Wheelbase, input limits and steering-rate limit (and, for
        :class:`DynamicNMPC`, the nominal dynamic parameters).
    config : NMPCConfig, optional
        Weights, horizon and solver.

    Attributes
    ----------
    last_plan : numpy.ndarray or None
        Input sequence ``[v, delta]`` of the last successful solve, shape (N, 2).
    last_states : numpy.ndarray or None
        Predicted states of the last successful solve in track coordinates,
        shape (N+1, nx).
    last_status : str
        Return status of the last solve.
    """

    name = "nmpc"
    settings_field = "nmpc"
    #: Number of model states (the first three are always ``x, y, theta``).
    nx = 3
    #: RK4 steps per period when the config leaves it open.
    default_substeps = 1
    #: Hessian when the config leaves it open.
    default_hessian = "exact"

    config: NMPCConfig

    def __init__(
        self, reference: Reference, vehicle: VehicleParams, config: NMPCConfig | None = None
    ) -> None:
        super().__init__(reference, vehicle, config if config is not None else NMPCConfig())
        cfg = self.config
        self.substeps = cfg.substeps if cfg.substeps is not None else self.default_substeps
        self.hessian = cfg.hessian if cfg.hessian is not None else self.default_hessian
        self.steer_step_max = self._guard.steer_step_max
        self.u_min, self.u_max = self._guard.u_min, self._guard.u_max
        #: Discrete model map ``F(x, u) -> x_next`` (CasADi SX function).
        self.model_map = rk4_map(self._ode(), cfg.dt, self.substeps)
        self._solver = self._build_solver()
        self._reset_solver()

    # ------------------------------------------------------------------ model hooks
    def _ode(self) -> Any:
        """The continuous-time model ``f(x, u)`` (CasADi function)."""
        return kinematic_ode(self.vehicle.wheelbase)

    def _initial_state(self, observation: Observation, yaw: float) -> np.ndarray:
        """Model state at the observation; ``yaw`` is already on the reference branch."""
        return np.array([observation.x, observation.y, yaw])

    def _reference_states(self, ref: ReferenceHorizon) -> np.ndarray:
        """States along the reference for a cold start, shape (N+1, nx)."""
        return np.column_stack([ref.x, ref.y, ref.theta])

    # ------------------------------------------------------------------ NLP
    def _build_solver(self) -> Any:
        problem = TrackingNLP(self.model_map, self.config, self.nx, self.steer_step_max)
        self._n_w, self._n_g, self._n_xvars = problem.n_w, problem.n_g, problem.n_xvars
        self._lbg, self._ubg = problem.lbg, problem.ubg
        return problem.solver(self.hessian)

    # ------------------------------------------------------------------ controller
    def _reset_solver(self) -> None:
        # Warm start in track coordinates: states (N+1, nx), inputs (N, 2), duals.
        self._ws_states: np.ndarray | None = None
        self._ws_inputs: np.ndarray | None = None
        self._ws_lam_x: np.ndarray | None = None
        self._ws_lam_g: np.ndarray | None = None
        self.last_plan: np.ndarray | None = None
        self.last_states: np.ndarray | None = None
        self.last_status = ""

    def _solve(self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray) -> Solution:
        cfg = self.config
        n, nx = cfg.horizon, self.nx
        yaw = ref.theta[0] + wrap_scalar(observation.yaw - ref.theta[0])
        x0 = self._initial_state(observation, yaw)
        origin = np.array([ref.x[0], ref.y[0]])
        x0_rel = x0.copy()
        x0_rel[:2] -= origin
        pose_r = np.column_stack([ref.x[1:] - origin[0], ref.y[1:] - origin[1], ref.theta[1:]])
        p = np.concatenate([x0_rel, pose_r.ravel(), u_ref.ravel(), self._guard.previous])

        lbx = np.full(self._n_w, -np.inf)
        ubx = np.full(self._n_w, np.inf)
        u_lb = np.tile(self.u_min, (n, 1))
        u_ub = np.tile(self.u_max, (n, 1))
        u_lb[:, 0], u_ub[:, 0] = self._speed_bounds(u_ref)
        lbx[self._n_xvars :] = u_lb.ravel()
        ubx[self._n_xvars :] = u_ub.ravel()

        states0, inputs0, lam_x0, lam_g0 = self._initial_guess(x0, ref, u_ref)
        states0 = states0.copy()
        states0[:, :2] -= origin
        w0 = np.concatenate([states0.ravel(), np.clip(inputs0, u_lb, u_ub).ravel()])
        args: dict[str, Any] = {"x0": w0, "p": p, "lbx": lbx, "ubx": ubx, "lbg": self._lbg, "ubg": self._ubg}
        if cfg.warm_start:
            args["lam_x0"] = lam_x0
            args["lam_g0"] = lam_g0
        try:
            sol = self._solver(**args)
            stats = self._solver.stats()
            status = str(stats.get("return_status", "unknown"))
            w_opt = np.asarray(sol["x"], dtype=float).ravel()
            finite = bool(np.all(np.isfinite(w_opt)))
            solved = finite and self._accept(stats, status)
        except Exception as exc:  # the loop must never crash on a solver error
            raise_if_interrupted(exc)  # but Ctrl-C during IPOPT (a SystemError from CasADi) ends it
            status = f"exception: {exc}"
            solved, finite, w_opt, sol = False, False, w0, {}
        if status == "User_Requested_Stop":  # IPOPT's own word for a Ctrl-C during the solve
            raise KeyboardInterrupt
        self.last_status = status
        if finite and (solved or status in ("Maximum_Iterations_Exceeded", "Maximum_CpuTime_Exceeded")):
            states = w_opt[: self._n_xvars].reshape(n + 1, nx).copy()
            states[:, :2] += origin
            inputs = w_opt[self._n_xvars :].reshape(n, 2)
            self._ws_states, self._ws_inputs = states, inputs
            self._ws_lam_x = np.asarray(sol["lam_x"], dtype=float).ravel()
            self._ws_lam_g = np.asarray(sol["lam_g"], dtype=float).ravel()
        if solved and self._ws_inputs is not None:
            self.last_plan = self._ws_inputs.copy()
            self.last_states = self._ws_states
            return Solution(self.last_plan)
        self.last_plan = None
        self.last_states = None
        reason = "exception" if status.startswith("exception") else NLP_REASONS.get(status, "numerical")
        return Solution(None, f"NLP failed: {status}", reason)

    def _accept(self, stats: dict[str, Any], status: str) -> bool:
        """Whether a solve counts as successful."""
        if bool(stats.get("success", False)):
            return True
        # SQP with a fixed iteration budget (RTI-like): the iterate is used once its QPs were solved.
        return self.config.solver == "sqpmethod" and status == "Maximum_Iterations_Exceeded"

    def _initial_guess(
        self, x0: np.ndarray, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Primal guess (states in track coordinates, inputs) and dual guesses."""
        n = self.config.horizon
        if not self.config.warm_start or self._ws_states is None or self._ws_inputs is None:
            states = self._reference_states(ref)
            states[0] = x0
            return states, u_ref.copy(), np.zeros(self._n_w), np.zeros(self._n_g)
        states = _shift(self._ws_states)
        inputs = _shift(self._ws_inputs)
        # Keep the previous prediction's heading on the branch of the new reference.
        states[:, 2] -= branch_shift(states[0, 2] - x0[2])
        states[0] = x0
        lam_x = np.zeros(self._n_w)
        lam_g = np.zeros(self._n_g)
        if self._ws_lam_x is not None and self._ws_lam_g is not None:
            nx, nxv = self.nx, self._n_xvars
            lam_x[nxv:] = _shift(self._ws_lam_x[nxv:].reshape(n, 2)).ravel()
            lam_g[nx:nxv] = _shift(self._ws_lam_g[nx:nxv].reshape(n, nx)).ravel()
            lam_g[nxv:] = _shift(self._ws_lam_g[nxv:])
        return states, inputs, lam_x, lam_g

    def predict(self, x0: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """Roll the discrete model out from ``x0`` under ``inputs`` (N, 2); returns (N+1, nx)."""
        states = [np.asarray(x0, dtype=float)]
        for u in np.asarray(inputs, dtype=float):
            states.append(np.asarray(self.model_map(states[-1], u), dtype=float).ravel())
        return np.vstack(states)


class DynamicNMPC(KinematicNMPC):
    """NMPC on the nominal dynamic single-track model with Pacejka tyres and actuator lags.

    States ``[x, y, theta, v, beta, r, delta_w]`` (speed magnitude, side-slip
    angle, yaw rate, actual wheel angle), inputs ``[v_cmd, delta_cmd]``; see
    :func:`rkmpc.control.nonlinear.models.dynamic_ode`. The cost and constraints are
    those of :class:`KinematicNMPC` (on ``x, y, theta`` and the inputs).

    Unmeasured parts of the state are estimated: the side slip and yaw rate
    from the kinematic relations, the wheel angle from the servo lag driven by
    the previous commands. Unless the config says otherwise the model is
    integrated with two RK4 steps per period and the NLP uses the Gauss-Newton
    Hessian (the exact one costs about twice the solve time for the same
    closed loop).

    Parameters
    ----------
    reference : Reference
        Path and speed profile to track.
    vehicle : VehicleParams
        Nominal car parameters.
    config : NMPCConfig, optional
        Weights, horizon and solver.
    min_speed : float, optional
        Speed floor (m/s) of the model's slip denominators; the car's
        ``blend_speed_high`` when None.
    """

    name = "nmpc-dynamic"
    nx = 7
    default_substeps = 2
    default_hessian = "gauss-newton"

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        config: NMPCConfig | None = None,
        min_speed: float | None = None,
    ) -> None:
        self.min_speed = float(vehicle.blend_speed_high if min_speed is None else min_speed)
        if not (math.isfinite(self.min_speed) and self.min_speed > 0):
            raise ParameterError(f"DynamicNMPC.min_speed must be > 0, got {self.min_speed}")
        self._wheel = WheelAnglePropagator(self._steering(vehicle), (config or NMPCConfig()).dt)
        super().__init__(reference, vehicle, config)

    def _steering(self, vehicle: VehicleParams) -> SteeringModel:
        """The servo that runs the wheel angle from the commands sent (the car's nominal one)."""
        return SteeringModel.nominal(vehicle)

    def _wheel_measurement(self, observation: Observation) -> float:
        """The measured wheel angle the state starts from (NaN: run it from the commands)."""
        return observation.steer_angle

    def _ode(self) -> Any:
        return dynamic_ode(self.vehicle, self.min_speed)

    def _reset_solver(self) -> None:
        super()._reset_solver()
        self._wheel.reset()

    def _first_previous_input(self, observation: Observation, u_ref: np.ndarray) -> np.ndarray:
        steer = observation.steer_angle if math.isfinite(observation.steer_angle) else u_ref[0, 1]
        return np.array([observation.speed, steer])

    def _initial_state(self, observation: Observation, yaw: float) -> np.ndarray:
        length = self.vehicle.wheelbase
        previous = self._guard.previous
        delta = self._wheel.step(
            None if previous is None else float(previous[1]), self._wheel_measurement(observation)
        )
        if math.isfinite(observation.slip_angle):
            beta = observation.slip_angle
        else:
            beta = math.atan(self.vehicle.lr / length * math.tan(delta))
        # The observed speed is the velocity along the heading, v cos(beta).
        v = max(observation.speed, 0.0) / max(math.cos(beta), 0.1)
        if math.isfinite(observation.yaw_rate):
            r = observation.yaw_rate
        else:
            r = v * math.cos(beta) * math.tan(delta) / length
        return np.array([observation.x, observation.y, yaw, v, beta, r, delta])

    def _reference_states(self, ref: ReferenceHorizon) -> np.ndarray:
        length = self.vehicle.wheelbase
        beta = np.arctan(self.vehicle.lr / length * np.tan(ref.delta))
        r = ref.v * np.cos(beta) * np.tan(ref.delta) / length
        return np.column_stack([ref.x, ref.y, ref.theta, ref.v, beta, r, ref.delta])


def _shift(a: np.ndarray) -> np.ndarray:
    """Drop the first row (entry) and repeat the last one."""
    return np.concatenate([a[1:], a[-1:]])
