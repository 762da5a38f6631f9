"""The nonlinear MPCs' optimisation problem: settings (:class:`NMPCConfig`) and the CasADi NLP.

Every control period the NMPCs solve the multiple-shooting NLP

.. math::

    \\min_{X, U} \\sum_{k=1}^{N} q_p \\|p_k - p^r_k\\|^2 + q_\\theta (\\theta_k - \\theta^r_k)^2
    + \\sum_{k=0}^{N-1} r_v (v_k - v^r_k)^2 + r_\\delta (\\delta_k - \\delta^r_k)^2
    + w_v (v_k - v_{k-1})^2 + w_\\delta (\\delta_k - \\delta_{k-1})^2

subject to ``X_0 = x(t)``, ``X_{k+1} = F(X_k, U_k)`` and ``|delta_k - delta_{k-1}| <= max_rate * dt``
(the input bounds are set per step). :class:`TrackingNLP` builds it once with CasADi (SX,
``expand=True``); its parameters are the initial state, the reference poses and inputs over the
horizon and the previous input.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from rkmpc.control.nonlinear.settings import HESSIANS, SOLVERS, NMPCConfig

__all__ = ["HESSIANS", "SOLVERS", "NMPCConfig", "TrackingNLP"]


class TrackingNLP:
    """The NLP of the tracking cost on a discrete model ``F(x, u)``, built once.

    Parameters
    ----------
    model_map : casadi.Function
        ``F(x[nx], u[2]) -> x_next`` over one control period.
    config : NMPCConfig
        Horizon, weights and solver settings.
    nx : int
        Model states (the first three are ``x, y, theta``).
    steer_step_max : float
        Largest change of the steering command per step (rad).

    Attributes
    ----------
    n_w, n_g, n_xvars : int
        Decision variables, constraints, and state variables among the decision variables.
    lbg, ubg : numpy.ndarray
        Constraint bounds (the dynamics are equalities, the steering steps bounded).
    """

    def __init__(self, model_map: Any, config: NMPCConfig, nx: int, steer_step_max: float) -> None:
        cfg = config
        self.config = cfg
        n = cfg.horizon
        X = ca.SX.sym("X", nx, n + 1)
        U = ca.SX.sym("U", 2, n)
        x0 = ca.SX.sym("x0", nx)
        pose_r = ca.SX.sym("pose_r", 3, n)
        u_r = ca.SX.sym("u_r", 2, n)
        u_prev = ca.SX.sym("u_prev", 2)
        x_next = model_map.map(n)(X[:, :n], U)
        w_state = ca.DM([cfg.position_weight, cfg.position_weight, cfg.heading_weight])
        terminal = ca.DM.ones(1, n)
        terminal[n - 1] = cfg.terminal_factor
        e_state = X[:3, 1:] - pose_r
        cost = ca.sum2(ca.sum1(w_state * e_state**2) * terminal)
        w_in = ca.DM([cfg.speed_weight, cfg.steer_weight])
        w_rate = ca.DM([cfg.speed_rate_weight, cfg.steer_rate_weight])
        du = ca.horzcat(U[:, 0] - u_prev, U[:, 1:] - U[:, :-1])
        cost += ca.sum2(ca.sum1(w_in * (U - u_r) ** 2)) + ca.sum2(ca.sum1(w_rate * du**2))
        g = ca.vertcat(ca.vec(X[:, 0] - x0), ca.vec(X[:, 1:] - x_next), ca.vec(du[1, :]))
        self.w = ca.vertcat(ca.vec(X), ca.vec(U))
        self.p = ca.vertcat(x0, ca.vec(pose_r), ca.vec(u_r), u_prev)
        self.cost = cost
        self.nlp = {"x": self.w, "p": self.p, "f": cost, "g": g}
        self.n_w = int(self.w.numel())
        self.n_g = int(g.numel())
        self.n_xvars = nx * (n + 1)
        self.lbg = np.zeros(self.n_g)
        self.ubg = np.zeros(self.n_g)
        self.lbg[-n:] = -steer_step_max
        self.ubg[-n:] = steer_step_max

    def solver(self, hessian: str) -> Any:
        """The CasADi ``nlpsol`` of the problem with the given Hessian choice (see :data:`HESSIANS`)."""
        cfg = self.config
        common: dict[str, Any] = {"expand": True, "print_time": False, "error_on_fail": False}
        if hessian == "gauss-newton":
            # The cost is quadratic in w, so its Hessian is constant; the model's curvature is dropped.
            lam_f = ca.SX.sym("lam_f")
            lam_g = ca.SX.sym("lam_g", self.n_g)
            hess = lam_f * ca.hessian(self.cost, self.w)[0]
            # IPOPT takes the upper triangle, the SQP method the full symmetric matrix.
            if cfg.solver == "ipopt":
                hess = ca.triu(hess)
            common["hess_lag"] = ca.Function("hess_lag", [self.w, self.p, lam_f, lam_g], [hess])
        opts = _ipopt_options(cfg, hessian) if cfg.solver == "ipopt" else _sqp_options(cfg, hessian)
        return ca.nlpsol("nmpc", cfg.solver, self.nlp, {**common, **opts})


def _ipopt_options(cfg: NMPCConfig, hessian: str) -> dict[str, Any]:
    ipopt: dict[str, Any] = {
        "print_level": 0,
        "sb": "yes",
        "tol": cfg.tolerance,
        "max_iter": cfg.max_iterations,
        "warm_start_init_point": "yes" if cfg.warm_start else "no",
        "warm_start_bound_push": 1e-6,
        "warm_start_mult_bound_push": 1e-6,
        "mu_init": 1e-3 if cfg.warm_start else 0.1,
    }
    if cfg.max_cpu_time is not None:
        ipopt["max_cpu_time"] = cfg.max_cpu_time
    if hessian == "limited-memory":
        ipopt["hessian_approximation"] = "limited-memory"
    return {"ipopt": ipopt}


def _sqp_options(cfg: NMPCConfig, hessian: str) -> dict[str, Any]:
    opts: dict[str, Any] = {
        "print_header": False,
        "print_iteration": False,
        "print_status": False,
        "max_iter": cfg.max_iterations,
        "tol_pr": cfg.tolerance,
        "tol_du": cfg.tolerance,
        "convexify_strategy": "regularize",
        "qpsol": "qrqp",
        "qpsol_options": {"print_iter": False, "print_header": False, "error_on_fail": False},
    }
    if hessian == "limited-memory":
        opts["hessian_approximation"] = "limited-memory"
    return opts
