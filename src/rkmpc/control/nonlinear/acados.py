"""The nonlinear MPCs as acados real-time iterations (optional fast path).

:class:`AcadosKinematicNMPC` (``nmpc-acados``) and
:class:`rkmpc.control.nonlinear.acados_dynamic.AcadosDynamicNMPC`
(``nmpc-acados-dynamic``) pose the NLP of
:class:`rkmpc.control.nonlinear.nmpc.KinematicNMPC` and
:class:`rkmpc.control.nonlinear.nmpc.DynamicNMPC` (same model, cost, horizon, bounds
and state estimate) and solve it with acados: one SQP real-time iteration
(``SQP_RTI``) per control period and a dense QP solver.

To express the steering-rate limit and the input-rate cost, the input applied
one step earlier is carried as two extra states, so that the OCP is

* states ``[model states, v_prev, delta_prev]``, controls ``u = [v_cmd, delta_cmd]``;
* discrete dynamics ``x_{k+1} = [F(x_k, u_k), u_k]``, with ``F`` the RK4 map of
  one period (:func:`rkmpc.control.nonlinear.models.rk4_map`), inputs held over the period;
* linear least squares on ``y_k = [x_k, y_k, theta_k, u_k, u_k - u_prev_k]``
  against ``[pose^r_k, u^r_k, 0]`` (the pose term is constant at stage 0), and
  ``terminal_factor`` times the pose weights at stage N;
* bounds ``u_min <= u_k <= u_max``, ``v_k <= v^r_k + margin``, and the linear
  constraint ``|delta_k - delta_prev_k| <= max_rate * dt``;
* ``x_0`` fixed to the estimated state and the previous command.

Positions are relative to the current reference point (as in the CasADi
version); the previous solution is shifted by one step, moved into the new
frame and given to acados as the initial guess, every step.

The per-step exchange with acados goes through a small Cython module built
next to the generated solver: it copies the references, bounds and initial
guess of all stages in one call and reads the solution back in one call, so
the Python overhead of a step does not grow with the horizon.

The generated C code and the Cython module are built once per problem into
``~/.cache/rkmpc/acados/<name>`` (or ``$RKMPC_CACHE_DIR/acados``), never into
the working directory; ``<name>`` is a hash of everything that enters the
generated code (model expressions, weights, bounds, solver options, versions),
so a second construction of the same problem, in any process, reuses the
build. Concurrent builds of the same problem wait on a file lock.

acados is optional: ``pip install rkmpc[acados]`` (``comma-deps-acados`` and
``cython``; a C compiler is needed on first use).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import logging
import math
import os
import shutil
import sys
import sysconfig
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rkmpc.control.nonlinear.acados_build import (
    BULK_PYX,
    acados_cache_dir,
    build_bulk_module,
    import_acados,
    load_module,
    locked,
)
from rkmpc.control.nonlinear.nmpc import KinematicNMPC, NMPCConfig
from rkmpc.control.tracking import Solution
from rkmpc.core.angles import branch_shift, wrap_scalar
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation
from rkmpc.core.versions import package_version
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference, ReferenceHorizon

__all__ = ["QP_SOLVERS", "AcadosKinematicNMPC", "acados_cache_dir"]

_LOG = logging.getLogger(__name__)

#: Controller status of a failed RTI by acados' status code (2: ACADOS_MAXITER, 7: ACADOS_TIMEOUT);
#: NaN detected (1), minimal step (3), QP failure (4) and any other code are ``"numerical"``.
ACADOS_REASONS: dict[int, str] = {2: "iteration_limit", 7: "iteration_limit"}

#: Bumped when the generated problem changes in a way the hash would not see.
_CODE_VERSION = 2
#: QP solvers the acados NMPCs accept.
QP_SOLVERS = ("FULL_CONDENSING_QPOASES", "PARTIAL_CONDENSING_HPIPM")
_HESSIANS = {"exact": "EXACT", "gauss-newton": "GAUSS_NEWTON"}
_NU = 2


class AcadosKinematicNMPC(KinematicNMPC):
    """Kinematic bicycle NMPC solved by one acados real-time iteration per period.

    The NLP, state estimate and fall-backs are those of
    :class:`rkmpc.control.nonlinear.nmpc.KinematicNMPC`; see the module docstring for
    how the NLP is posed to acados.

    Parameters
    ----------
    reference : Reference
        Path and speed profile to track.
    vehicle : VehicleParams
        Wheelbase, input limits and steering-rate limit (and, for the dynamic
        variant, the nominal dynamic parameters).
    config : NMPCConfig, optional
        Weights, horizon, period, RK4 sub-steps and Hessian (``"exact"``, with
        the Hessian mirrored to be positive definite, or ``"gauss-newton"``;
        None for the class default) and ``warm_start``; ``solver``,
        ``max_iterations``, ``max_cpu_time`` and ``tolerance`` are not used (one
        real-time iteration per step).
    qp_solver : str
        One of :data:`QP_SOLVERS`; dense qpOASES by default.
    cache_dir : path, optional
        Root of the generated solvers; :func:`acados_cache_dir` by default.

    Raises
    ------
    ImportError
        When acados (``comma-deps-acados``) or cython is not installed.
    ParameterError
        For an unknown QP solver or an unsupported Hessian.
    RuntimeError
        When generating or compiling the solver fails.

    Attributes
    ----------
    build_dir : pathlib.Path
        Folder of the generated solver.
    built : bool
        Whether this construction generated and compiled the solver (False
        when it was found in the cache).
    last_solve_time : float
        acados' own time of the last solve (s), without the Python around it.
    """

    name = "nmpc-acados"
    default_hessian = "gauss-newton"
    #: Tag of the generated model's name.
    model_tag = "kin"

    def __init__(
        self,
        reference: Reference,
        vehicle: VehicleParams,
        config: NMPCConfig | None = None,
        qp_solver: str = "FULL_CONDENSING_QPOASES",
        cache_dir: str | os.PathLike[str] | None = None,
    ) -> None:
        self._acados, self._template = import_acados()
        if qp_solver not in QP_SOLVERS:
            raise ParameterError(f"qp_solver must be one of {QP_SOLVERS}, got {qp_solver!r}")
        self.qp_solver = qp_solver
        self._cache_root = Path(cache_dir) if cache_dir is not None else acados_cache_dir()
        self.built = False
        self.last_solve_time = math.nan
        super().__init__(reference, vehicle, config)

    # ------------------------------------------------------------------ build
    def _build_solver(self) -> Any:
        if self.hessian not in _HESSIANS:
            raise ParameterError(
                f"{type(self).__name__} supports the Hessians {tuple(_HESSIANS)}, got {self.hessian!r}"
            )
        ocp, description = self._ocp()
        digest = hashlib.sha256(json.dumps(description, sort_keys=True).encode()).hexdigest()[:16]
        model_name = f"rkmpc_{self.model_tag}_{digest}"
        ocp.model.name = model_name
        self._cache_root.mkdir(parents=True, exist_ok=True)
        self.build_dir = self._cache_root / model_name
        code_dir = self.build_dir / "c_generated_code"
        ext = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
        module_file = code_dir / f"{model_name}_bulk{ext}"
        stamp = self.build_dir / "built.json"
        with locked(self._cache_root / f"{model_name}.lock"):
            if not (stamp.exists() and module_file.exists()):
                self._generate(ocp, code_dir)
                build_bulk_module(self._acados, code_dir, model_name)
                stamp.write_text(json.dumps(description, sort_keys=True, indent=1))
                self.built = True
        module = load_module(f"{model_name}_bulk", module_file)
        n = self.config.horizon
        nxa = self.nx + _NU
        self._ny = 3 + 2 * _NU
        return module.BulkSolver(n, nxa, _NU, self._ny, 3)

    def _generate(self, ocp: Any, code_dir: Path) -> None:
        """Generate the C code of ``ocp`` into ``code_dir`` and build its shared library."""
        at = self._template
        shutil.rmtree(self.build_dir, ignore_errors=True)
        self.build_dir.mkdir(parents=True)
        ocp.code_export_directory = str(code_dir)
        cwd = os.getcwd()
        try:
            # acados_template writes some files relative to the working directory, and prints.
            os.chdir(self.build_dir)
            with contextlib.redirect_stdout(io.StringIO()):
                at.AcadosOcpSolver.generate(ocp, json_file=str(self.build_dir / "acados_ocp.json"))
                at.AcadosOcpSolver.build(str(code_dir), with_cython=False, verbose=False)
        finally:
            os.chdir(cwd)
        if not (code_dir / f"libacados_ocp_solver_{ocp.model.name}.so").exists():
            raise RuntimeError(f"acados: building the solver in {code_dir} failed")

    def _ocp(self) -> tuple[Any, dict[str, Any]]:
        """The acados OCP and a description of everything that enters its generated code."""
        import casadi as ca

        at = self._template
        cfg = self.config
        nxa = self.nx + _NU
        model = at.AcadosModel()
        x = ca.SX.sym("x", nxa)
        u = ca.SX.sym("u", _NU)
        model.x = x
        model.u = u
        model.disc_dyn_expr = ca.vertcat(self.model_map(x[: self.nx], u), u)
        ocp = at.AcadosOcp()
        ocp.model = model
        ocp.dims.N = cfg.horizon
        ocp.solver_options.tf = cfg.horizon * cfg.dt
        self._set_cost(ocp.cost)
        self._set_constraints(ocp.constraints)
        self._set_options(ocp.solver_options)
        description = {
            "code_version": _CODE_VERSION,
            "pyx": hashlib.sha256(BULK_PYX.encode()).hexdigest(),
            "dynamics": str(model.disc_dyn_expr),
            "horizon": cfg.horizon,
            "dt": cfg.dt,
            "W": ocp.cost.W.tolist(),
            "W_e": ocp.cost.W_e.tolist(),
            "u_min": self.u_min.tolist(),
            "u_max": self.u_max.tolist(),
            "steer_step_max": self.steer_step_max,
            "hessian": self.hessian,
            "qp_solver": self.qp_solver,
            "acados": [
                getattr(self._acados, "__file__", ""),
                package_version("comma-deps-acados", "unknown"),
            ],
            "cython": package_version("cython", "unknown"),
            "python": [sys.version, sysconfig.get_config_var("EXT_SUFFIX")],
        }
        return ocp, description

    def _set_cost(self, cost: Any) -> None:
        """Linear least squares on ``y = [pose, u, u - u_prev]`` (and the pose at the end)."""
        cfg = self.config
        nx, nxa = self.nx, self.nx + _NU
        # acados scales the stage cost by the step dt (not the terminal one), so the stage
        # weights are divided by dt to keep the NMPC's cost.
        w_pose = [cfg.position_weight, cfg.position_weight, cfg.heading_weight]
        w_stage = [*w_pose, cfg.speed_weight, cfg.steer_weight, cfg.speed_rate_weight, cfg.steer_rate_weight]
        vx = np.zeros((3 + 2 * _NU, nxa))
        vx[:3, :3] = np.eye(3)
        vx[3 + _NU :, nx:] = -np.eye(_NU)
        vu = np.zeros((3 + 2 * _NU, _NU))
        vu[3 : 3 + _NU] = np.eye(_NU)
        vu[3 + _NU :] = np.eye(_NU)
        vx_e = np.zeros((3, nxa))
        vx_e[:, :3] = np.eye(3)
        cost.cost_type = "LINEAR_LS"
        cost.cost_type_e = "LINEAR_LS"
        cost.W = np.diag(w_stage) / cfg.dt
        cost.W_e = np.diag([cfg.terminal_factor * w for w in w_pose])
        cost.Vx, cost.Vu, cost.Vx_e = vx, vu, vx_e
        cost.yref = np.zeros(3 + 2 * _NU)
        cost.yref_e = np.zeros(3)

    def _set_constraints(self, con: Any) -> None:
        """Input bounds (the speed bound is set per stage), and ``|delta - delta_prev| <= max_rate dt``."""
        nx, nxa = self.nx, self.nx + _NU
        con.x0 = np.zeros(nxa)
        con.idxbu = np.arange(_NU)
        con.lbu = self.u_min.copy()
        con.ubu = self.u_max.copy()
        c_mat = np.zeros((1, nxa))
        c_mat[0, nx + 1] = -1.0
        d_mat = np.zeros((1, _NU))
        d_mat[0, 1] = 1.0
        con.C, con.D = c_mat, d_mat
        con.lg = np.array([-self.steer_step_max])
        con.ug = np.array([self.steer_step_max])

    def _set_options(self, opts: Any) -> None:
        """One SQP real-time iteration per step with the chosen Hessian and dense QP solver."""
        opts.integrator_type = "DISCRETE"
        opts.nlp_solver_type = "SQP_RTI"
        opts.hessian_approx = _HESSIANS[self.hessian]
        if self.hessian == "exact":
            opts.regularize_method = "MIRROR"
        opts.qp_solver = self.qp_solver
        if self.qp_solver == "PARTIAL_CONDENSING_HPIPM":
            opts.qp_solver_cond_N = self.config.horizon
        opts.qp_solver_warm_start = 1
        opts.qp_solver_iter_max = 50
        opts.print_level = 0

    # ------------------------------------------------------------------ controller
    def _reset_solver(self) -> None:
        super()._reset_solver()
        n, nxa = self.config.horizon, self.nx + _NU
        # Warm start in track coordinates: augmented states (N+1, nx+2), inputs (N, 2).
        self._ws_x: np.ndarray | None = None
        self._ws_u: np.ndarray | None = None
        self._yref = np.zeros((n, self._ny))
        self._yref_e = np.zeros(3)
        self._lbu = np.tile(self.u_min, (n, 1))
        self._ubu = np.tile(self.u_max, (n, 1))
        self._x_out = np.zeros((n + 1, nxa))
        self._u_out = np.zeros((n, _NU))

    def _solve(self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray) -> Solution:
        cfg = self.config
        n, nx = cfg.horizon, self.nx
        yaw = ref.theta[0] + wrap_scalar(observation.yaw - ref.theta[0])
        origin = np.array([ref.x[0], ref.y[0]])
        x0 = np.concatenate([self._initial_state(observation, yaw), self._guard.previous])
        x0[:2] -= origin

        yref = self._yref
        yref[:, 0] = ref.x[:n] - origin[0]
        yref[:, 1] = ref.y[:n] - origin[1]
        yref[:, 2] = ref.theta[:n]
        yref[:, 3:5] = u_ref
        self._yref_e[:] = (ref.x[n] - origin[0], ref.y[n] - origin[1], ref.theta[n])
        self._lbu[:, 0], self._ubu[:, 0] = self._speed_bounds(u_ref)
        x_guess, u_guess = self._initial_guess_rti(x0, origin, ref, u_ref)

        solver = self._solver
        try:
            solver.prepare(x0, yref, self._yref_e, self._lbu, self._ubu, x_guess, u_guess)
            status_code = int(solver.solve())
            solver.solution(self._x_out, self._u_out)
            self.last_solve_time = float(solver.solve_time())
            finite = bool(np.isfinite(self._x_out).all() and np.isfinite(self._u_out).all())
            self.last_status = str(status_code)
        except Exception as exc:  # the loop must never crash on a solver error
            status_code, finite = -1, False
            self.last_status = f"exception: {exc}"
        if status_code == 0 and finite:
            states = self._x_out.copy()
            states[:, :2] += origin
            plan = self._u_out.copy()
            self._ws_x, self._ws_u = states, plan
            self.last_plan = plan
            self.last_states = states[:, :nx]
            return Solution(plan)
        # Keep the guess (one step older) as the next warm start; clear acados' memory.
        self._ws_x, self._ws_u = None, None
        if np.isfinite(x_guess[1:]).all() and np.isfinite(u_guess).all():
            self._ws_x = x_guess + np.r_[origin, np.zeros(x_guess.shape[1] - 2)]
            self._ws_u = u_guess
        with contextlib.suppress(Exception):
            solver.reset()
        self.last_plan = None
        self.last_states = None
        message = f"acados RTI failed: status {self.last_status}"
        _LOG.debug("%s step %d: %s", self.name, self.step_count, message)
        reason = "exception" if status_code == -1 else ACADOS_REASONS.get(status_code, "numerical")
        return Solution(None, message, reason)

    def _initial_guess_rti(
        self, x0: np.ndarray, origin: np.ndarray, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Augmented states (relative to ``origin``) and inputs to start the iteration from."""
        if self.config.warm_start and self._ws_x is not None and self._ws_u is not None:
            states = np.concatenate([self._ws_x[1:], self._ws_x[-1:]])
            inputs = np.concatenate([self._ws_u[1:], self._ws_u[-1:]])
            states[:, :2] -= origin
            states[:, 2] -= branch_shift(states[0, 2] - x0[2])
        else:
            model_states = self._reference_states(ref)
            model_states[:, :2] -= origin
            inputs = u_ref.copy()
            states = np.column_stack([model_states, np.concatenate([x0[None, -_NU:], inputs])])
        states[0] = x0
        return np.ascontiguousarray(states), np.ascontiguousarray(inputs)
