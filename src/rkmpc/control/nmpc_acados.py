"""Kinematic NMPC as an acados real-time iteration (optional fast path).

:class:`AcadosKinematicNMPC` tracks the same time-indexed reference as
:class:`rkmpc.control.nmpc.KinematicNMPC` with the same weights, but solves the
OCP with acados: one SQP real-time iteration (``SQP_RTI``) per control period,
an explicit RK4 integrator and a structure-exploiting QP solver.

To express the steering-rate limit as a simple bound, the applied inputs are
states of the OCP and their rates are its controls:

* states ``[x, y, theta, v, delta]`` (``v, delta``: the command in force),
* controls ``[a, omega] = [dv/dt, ddelta/dt]``, ``|omega| <= max_rate``.

The command of a period is ``[v, delta]`` of the first predicted state
``x_1``, so ``|delta_1 - delta_0| <= max_rate * dt`` as in the CasADi NMPC;
the difference is that, inside a period, the model's speed and wheel angle
ramp linearly from the old command to the new one instead of jumping.

Cost (``LINEAR_LS``), stage ``k = 1..N``: ``q_p |p_k - p^r_k|^2 +
q_theta (theta_k - theta^r_k)^2 + r_v (v_k - v^r_{k-1})^2 + r_delta (delta_k -
delta^r_{k-1})^2``, plus at every stage ``k = 0..N-1`` the rate terms
``w_v (a_k dt)^2 + w_delta (omega_k dt)^2`` (= the squared step-to-step input
changes). Per-stage bounds ``v_k <= v^r_{k-1} + margin`` and the car's input
limits act on the states ``v_k, delta_k``.

Positions are relative to the current reference point (as in the CasADi
version); the previous solution is shifted by one step, moved into the new
frame and given to acados as the initial guess.

The generated C code is built once per problem (horizon, period, weights,
car limits) into ``~/.cache/rkmpc/acados/<hash>`` (or ``$RKMPC_CACHE_DIR``),
never into the working directory. acados is optional: install it with
``pip install comma-deps-acados==0.2.2.post92``.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rkmpc.control.base import Command, Controller, Observation
from rkmpc.control.guard import CommandGuard
from rkmpc.control.lmpc import wrap_angle
from rkmpc.control.nmpc import NMPCConfig
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference

__all__ = ["AcadosKinematicNMPC", "acados_cache_dir"]

_INSTALL_HINT = (
    "AcadosKinematicNMPC needs acados; install it with `pip install comma-deps-acados==0.2.2.post92`"
)
#: Bumped when the generated problem changes in a way the hash would not see.
_CODE_VERSION = 1
_QP_SOLVERS = ("PARTIAL_CONDENSING_HPIPM", "FULL_CONDENSING_QPOASES")
_TWO_PI = 2.0 * math.pi


def acados_cache_dir() -> Path:
    """Root folder of the generated solvers."""
    root = os.environ.get("RKMPC_CACHE_DIR")
    base = Path(root) if root else Path.home() / ".cache" / "rkmpc"
    return base / "acados"


def _import_acados() -> tuple[Any, Any]:
    """Import acados, set its environment and preload its libraries.

    Returns the ``acados`` package (paths) and ``acados_template``.
    """
    try:
        import acados  # comma-deps-acados: the C library and the template live under this package
        from acados import acados_template
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(_INSTALL_HINT) from exc
    os.environ.setdefault("ACADOS_SOURCE_DIR", acados.DIR)
    os.environ.setdefault("TERA_PATH", acados.TERA_PATH)
    os.environ.setdefault("ACADOS_PYTHON_INTERFACE_PATH", acados.TEMPLATE_DIR)
    # libacados.so has no RPATH: load its dependencies globally before the generated solver.
    for lib in ("libblasfeo.so", "libhpipm.so", "libqpOASES_e.so.3.1", "libacados.so"):
        path = os.path.join(acados.LIB_DIR, lib)
        if os.path.exists(path):
            ctypes.CDLL(path, mode=ctypes.RTLD_GLOBAL)
    return acados, acados_template


class AcadosKinematicNMPC(Controller):
    """Kinematic bicycle NMPC solved by one acados real-time iteration per period.

    Parameters
    ----------
    reference : Reference
        Path and speed profile to track.
    vehicle : VehicleParams
        Wheelbase, input limits and steering-rate limit.
    config : NMPCConfig, optional
        Weights, horizon and period (the solver fields are ignored).
    qp_solver : str
        ``"PARTIAL_CONDENSING_HPIPM"`` (default) or ``"FULL_CONDENSING_QPOASES"``.
    cache_dir : path, optional
        Where to build the solver; :func:`acados_cache_dir` by default.

    Raises
    ------
    ImportError
        When acados (``comma-deps-acados``) is not installed.
    """

    name = "nmpc-acados"
    nx = 5

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        config: NMPCConfig | None = None,
        qp_solver: str = "PARTIAL_CONDENSING_HPIPM",
        cache_dir: str | os.PathLike[str] | None = None,
    ) -> None:
        self._acados, self._template = _import_acados()
        super().__init__()
        if qp_solver not in _QP_SOLVERS:
            raise ValueError(f"qp_solver must be one of {_QP_SOLVERS}, got {qp_solver!r}")
        self.reference = reference
        self.vehicle = vehicle
        self.config = config if config is not None else NMPCConfig()
        self.qp_solver = qp_solver
        self._guard = CommandGuard(vehicle, self.config.dt, self.config.horizon)
        self.steer_step_max = self._guard.steer_step_max
        self.u_min, self.u_max = self._guard.u_min, self._guard.u_max
        root = Path(cache_dir) if cache_dir is not None else acados_cache_dir()
        self.build_dir = root / self._problem_hash()
        self._solver = self._build_solver()
        self._reset()

    # ------------------------------------------------------------------ build
    def _problem(self) -> dict[str, Any]:
        cfg = self.config
        return {
            "code_version": _CODE_VERSION,
            "horizon": cfg.horizon,
            "dt": cfg.dt,
            "weights": [
                cfg.position_weight,
                cfg.heading_weight,
                cfg.speed_weight,
                cfg.steer_weight,
                cfg.speed_rate_weight,
                cfg.steer_rate_weight,
                cfg.terminal_factor,
            ],
            "wheelbase": self.vehicle.wheelbase,
            "u_min": self.u_min.tolist(),
            "u_max": self.u_max.tolist(),
            "max_rate": self.vehicle.steering.max_rate,
            "qp_solver": self.qp_solver,
            "acados": getattr(self._acados, "__file__", ""),
        }

    def _problem_hash(self) -> str:
        text = json.dumps(self._problem(), sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def _build_solver(self) -> Any:
        import casadi as ca

        at = self._template
        cfg = self.config
        n, dt = cfg.horizon, cfg.dt
        big = 1e3

        model = at.AcadosModel()
        model.name = "rkmpc_kin"
        x = ca.SX.sym("x", self.nx)
        u = ca.SX.sym("u", 2)
        th, v, delta = x[2], x[3], x[4]
        model.x = x
        model.u = u
        model.xdot = ca.SX.sym("xdot", self.nx)
        model.f_expl_expr = ca.vertcat(
            v * ca.cos(th), v * ca.sin(th), v * ca.tan(delta) / self.vehicle.wheelbase, u[0], u[1]
        )

        ocp = at.AcadosOcp()
        ocp.model = model
        ocp.dims.N = n
        ocp.solver_options.tf = n * dt

        # Linear least squares on y = [x, u]: poses and commands against the reference, rates.
        ny = self.nx + 2
        w_state = [cfg.position_weight, cfg.position_weight, cfg.heading_weight]
        w_state += [cfg.speed_weight, cfg.steer_weight]
        w_rate = [cfg.speed_rate_weight * dt**2, cfg.steer_rate_weight * dt**2]
        ocp.cost.cost_type = "LINEAR_LS"
        ocp.cost.cost_type_e = "LINEAR_LS"
        ocp.cost.W = np.diag(w_state + w_rate)
        ocp.cost.W_e = np.diag([cfg.terminal_factor * w for w in w_state[:3]] + w_state[3:])
        vx = np.zeros((ny, self.nx))
        vx[: self.nx, : self.nx] = np.eye(self.nx)
        vu = np.zeros((ny, 2))
        vu[self.nx :, :] = np.eye(2)
        ocp.cost.Vx = vx
        ocp.cost.Vu = vu
        ocp.cost.Vx_e = np.eye(self.nx)
        ocp.cost.yref = np.zeros(ny)
        ocp.cost.yref_e = np.zeros(self.nx)

        # Rate bounds on the controls; command bounds on the states v, delta (stages 1..N).
        ocp.constraints.idxbu = np.array([0, 1])
        ocp.constraints.lbu = np.array([-big, -self.vehicle.steering.max_rate])
        ocp.constraints.ubu = np.array([big, self.vehicle.steering.max_rate])
        ocp.constraints.idxbx = np.array([3, 4])
        ocp.constraints.lbx = self.u_min.copy()
        ocp.constraints.ubx = self.u_max.copy()
        ocp.constraints.idxbx_e = np.array([3, 4])
        ocp.constraints.lbx_e = self.u_min.copy()
        ocp.constraints.ubx_e = self.u_max.copy()
        ocp.constraints.x0 = np.zeros(self.nx)

        opts = ocp.solver_options
        opts.qp_solver = self.qp_solver
        opts.hessian_approx = "GAUSS_NEWTON"
        opts.integrator_type = "ERK"
        opts.sim_method_num_stages = 4
        opts.sim_method_num_steps = 1
        opts.nlp_solver_type = "SQP_RTI"
        opts.print_level = 0
        if self.qp_solver == "PARTIAL_CONDENSING_HPIPM":
            opts.qp_solver_cond_N = n
            opts.qp_solver_warm_start = 1
        opts.qp_solver_iter_max = 50

        self.build_dir.mkdir(parents=True, exist_ok=True)
        ocp.code_export_directory = str(self.build_dir / "c_generated_code")
        json_file = str(self.build_dir / "acados_ocp.json")
        lib = Path(ocp.code_export_directory) / f"libacados_ocp_solver_{model.name}.so"
        built = lib.exists() and Path(json_file).exists()
        cwd = os.getcwd()
        try:
            # acados_template writes some files relative to the working directory.
            os.chdir(self.build_dir)
            return at.AcadosOcpSolver(
                ocp, json_file=json_file, build=not built, generate=not built, verbose=False
            )
        finally:
            os.chdir(cwd)

    # ------------------------------------------------------------------ controller
    def _reset(self) -> None:
        self._s_hint: float | None = None
        self._guard.reset()
        # Previous solution in track coordinates: states (N+1, 5), controls (N, 2).
        self._ws_states: np.ndarray | None = None
        self._ws_controls: np.ndarray | None = None
        self.last_plan: np.ndarray | None = None
        self.last_states: np.ndarray | None = None
        self.last_status = ""

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        cfg = self.config
        n = cfg.horizon
        solver = self._solver
        proj = self.reference.project(observation.x, observation.y, self._s_hint)
        self._s_hint = proj.s
        ref = self.reference.horizon(proj.s, n, cfg.dt)
        u_ref = np.column_stack([ref.v[:n], ref.delta[:n]])
        if self._guard.previous is None:
            self._guard.previous = np.array([observation.speed, u_ref[0, 1]])
        yaw = ref.theta[0] + wrap_angle(observation.yaw - ref.theta[0])
        origin = np.array([ref.x[0], ref.y[0]])
        x0 = np.array([observation.x - origin[0], observation.y - origin[1], yaw, *self._guard.previous])

        # Initial guess: the shifted previous solution in the new frame, or the reference.
        if self._ws_states is not None and self._ws_controls is not None:
            states = np.concatenate([self._ws_states[1:], self._ws_states[-1:]])
            controls = np.concatenate([self._ws_controls[1:], np.zeros((1, 2))])
            states[:, 2] -= _TWO_PI * round((states[0, 2] - yaw) / _TWO_PI)
            states[:, :2] -= origin
        else:
            states = np.column_stack(
                [ref.x - origin[0], ref.y - origin[1], ref.theta, np.r_[u_ref[:1], u_ref]]
            )
            controls = np.zeros((n, 2))
        states[0] = x0

        solver.set(0, "lbx", x0)
        solver.set(0, "ubx", x0)
        u_ub = np.minimum(self.u_max[0], u_ref[:, 0] + cfg.speed_margin)
        u_lb = np.minimum(self.u_min[0], u_ub)
        zeros2 = np.zeros(2)
        for k in range(n + 1):
            solver.set(k, "x", states[k])
            pose = [ref.x[k] - origin[0], ref.y[k] - origin[1], ref.theta[k]]
            if k == 0:
                solver.set(0, "yref", np.concatenate([x0, zeros2]))
            else:
                cmd = u_ref[k - 1]
                bounds_lo = np.array([u_lb[k - 1], self.u_min[1]])
                bounds_hi = np.array([u_ub[k - 1], self.u_max[1]])
                solver.constraints_set(k, "lbx", bounds_lo)
                solver.constraints_set(k, "ubx", bounds_hi)
                if k < n:
                    solver.set(k, "yref", np.concatenate([pose, cmd, zeros2]))
                else:
                    solver.set(k, "yref", np.concatenate([pose, cmd]))
            if k < n:
                solver.set(k, "u", controls[k])
        try:
            status_code = int(solver.solve())
            sol_x = np.array([solver.get(k, "x") for k in range(n + 1)])
            sol_u = np.array([solver.get(k, "u") for k in range(n)])
            finite = bool(np.all(np.isfinite(sol_x)) and np.all(np.isfinite(sol_u)))
        except Exception as exc:  # the loop must never crash on a solver error
            status_code, finite = -1, False
            sol_x, sol_u = states, controls
            self.last_status = f"exception: {exc}"
        else:
            self.last_status = str(status_code)
        if status_code == 0 and finite:
            sol_x = sol_x.copy()
            sol_x[:, :2] += origin
            self._ws_states, self._ws_controls = sol_x, sol_u
            plan = sol_x[1:, 3:5].copy()
            u = self._guard.accept(plan)
            self.last_plan = plan
            self.last_states = sol_x
            flag, message = "ok", ""
        else:
            u = self._guard.fallback(u_ref[0])
            self.last_plan = None
            self.last_states = None
            flag, message = "fallback", f"acados RTI failed: status {self.last_status}"
        u = self._guard.apply(u)
        return Command(speed=float(u[0]), steer=float(u[1])), flag, message
