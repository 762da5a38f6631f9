"""The acados NMPCs (optional extra ``rkmpc[acados]``): laps, the build cache, fall-backs.

`make test` installs the extra, so these run in CI (the laps in the slow tier); without it they
skip. The generated solvers are kept between runs in pytest's cache folder
(``.pytest_cache/d/rkmpc/acados``): a cold build compiles for 4 to 15 s per problem, a cached one
loads in about 20 ms.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from rkmpc.analysis.metrics import lap_metrics
from rkmpc.control import make_controller
from rkmpc.control.nonlinear.acados import AcadosKinematicNMPC, acados_cache_dir
from rkmpc.control.nonlinear.nmpc import NMPCConfig
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation
from rkmpc.sim.closed_loop import simulate
from rkmpc.vehicle.registry import make_plant

pytest.importorskip("acados", reason="acados is the optional extra rkmpc[acados] (`make test` installs it)")
pytest.importorskip("Cython", reason="the acados NMPCs build a Cython module (the extra rkmpc[acados])")

ACADOS = ("nmpc-acados", "nmpc-acados-dynamic")
#: The CasADi NMPC that solves the same NLP.
CASADI = {"nmpc-acados": "nmpc", "nmpc-acados-dynamic": "nmpc-dynamic"}
#: The CasADi NMPC's real-time path: one SQP iteration per step, like the RTI.
ONE_SQP = NMPCConfig(solver="sqpmethod", max_iterations=1)


@pytest.fixture(scope="session")
def solver_cache(pytestconfig, tmp_path_factory):
    """A cache root kept between test runs (pytest's cache), a temporary one without it."""
    cache = getattr(pytestconfig, "cache", None)
    return cache.mkdir("rkmpc") if cache is not None else tmp_path_factory.mktemp("rkmpc")


@pytest.fixture(autouse=True)
def _kept_solvers(solver_cache, monkeypatch):
    """The acados solvers of these tests come from (and go to) :func:`solver_cache`."""
    monkeypatch.setenv("RKMPC_CACHE_DIR", str(solver_cache))


def _make(name, scenario, config=None):
    """The controller through the registry, from a car's settings (as every command builds it)."""
    settings = ControllerSettings(nmpc=config if config is not None else NMPCConfig())
    return make_controller(name, scenario.reference, scenario.vehicle, settings=settings)


def _on_path_observation(scenario, s=5.0, offset=0.0):
    path = scenario.reference.path
    p = path.position(s)
    yaw = float(path.heading(s))
    return Observation(
        x=float(p[0]) + offset * math.sin(yaw),
        y=float(p[1]) - offset * math.cos(yaw),
        yaw=yaw,
        speed=float(scenario.reference.profile.speed(s)),
    )


@pytest.mark.slow
@pytest.mark.parametrize("name", ACADOS)
def test_acados_nmpc_laps_builtin_like_casadi(builtin_scenario, name):
    sc = builtin_scenario
    reference = lap_metrics(
        simulate(make_plant("f1tenth"), _make(CASADI[name], sc, ONE_SQP), sc.track, sc.reference)
    )
    ctrl = _make(name, sc)
    assert ctrl.build_dir.parent == acados_cache_dir()
    result = simulate(make_plant("f1tenth"), ctrl, sc.track, sc.reference)
    metrics = lap_metrics(result)
    assert result.outcome == "completed", metrics
    assert ctrl.fallback_count == 0
    # Same NLP as the CasADi NMPC, one RTI per step: the closed loops agree closely.
    assert metrics["lateral_error_mean_m"] <= 1.05 * reference["lateral_error_mean_m"]
    assert metrics["lateral_error_max_m"] <= 1.1 * reference["lateral_error_max_m"]
    steer = result.log["cmd_steer"][:-1]
    assert np.all(np.abs(steer) <= sc.vehicle.steering.max_angle + 1e-9)
    step_max = sc.vehicle.steering.max_rate * ctrl.config.dt
    assert np.all(np.abs(np.diff(steer)) <= step_max + 1e-9)


@pytest.mark.slow  # several seconds: the slow tier (make test-slow, run by CI)
@pytest.mark.parametrize("name", ACADOS)
def test_acados_build_is_cached_outside_the_working_directory(builtin_scenario, name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    sc = builtin_scenario
    first = _make(name, sc)
    second = _make(name, sc)
    assert not second.built
    assert second.build_dir == first.build_dir
    assert (second.build_dir / "built.json").exists()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_acados_another_problem_is_another_build(builtin_scenario):
    sc = builtin_scenario
    first = _make("nmpc-acados", sc)
    other = _make("nmpc-acados", sc, replace(NMPCConfig(), horizon=12))
    assert other.config.horizon == 12
    assert other.build_dir != first.build_dir
    assert other.last_plan is None
    other.reset()
    other.step(_on_path_observation(sc))
    assert other.info.status == "ok"
    assert other.last_plan is not None and other.last_plan.shape == (12, 2)


def test_acados_nmpc_plan_matches_reference_on_path(builtin_scenario):
    sc = builtin_scenario
    ctrl = _make("nmpc-acados", sc)
    ctrl.reset()
    obs = _on_path_observation(sc)
    for _ in range(3):
        ctrl.step(obs)
    assert ctrl.info.status == "ok"
    assert ctrl.last_plan is not None and ctrl.last_plan.shape == (ctrl.config.horizon, 2)
    assert ctrl.last_states is not None and ctrl.last_states.shape == (ctrl.config.horizon + 1, 3)
    # Predicted path starts at the car and stays near the reference.
    assert np.allclose(ctrl.last_states[0, :2], [obs.x, obs.y])
    ref = sc.reference.horizon(sc.reference.project(obs.x, obs.y).s, ctrl.config.horizon, ctrl.config.dt)
    assert np.max(np.hypot(ctrl.last_states[:, 0] - ref.x, ctrl.last_states[:, 1] - ref.y)) < 0.2


class _FailingSolver:
    """Wraps a solver and makes some of its solves fail."""

    def __init__(self, solver, mode):
        self._solver = solver
        self.mode = mode
        self.resets = 0

    def __getattr__(self, name):
        return getattr(self._solver, name)

    def solve(self):
        if self.mode == "raise":
            raise RuntimeError("injected")
        if self.mode == "status":
            self._solver.solve()
            return 4  # the QP solver failed
        return self._solver.solve()

    def reset(self):
        self.resets += 1
        self._solver.reset()


@pytest.mark.parametrize("name", ACADOS)
@pytest.mark.parametrize("mode", ["status", "raise"])
def test_acados_forced_failure_falls_back_and_recovers(builtin_scenario, name, mode):
    sc = builtin_scenario
    ctrl = _make(name, sc)
    ctrl.reset()
    obs = _on_path_observation(sc)
    first = ctrl.step(obs)
    assert ctrl.info.status == "ok"
    plan = ctrl.last_plan.copy()
    failing = _FailingSolver(ctrl._solver, mode)
    ctrl._solver = failing
    commands = []
    for i in range(3):
        commands.append(ctrl.step(obs))
        assert ctrl.info.status in ("numerical", "exception", "iteration_limit")
        assert "acados RTI failed" in ctrl.info.message
        assert ctrl.fallback_count == i + 1
        assert ctrl.last_plan is None
    assert failing.resets == 3
    # The fall-back is the last plan, shifted, within the steering-rate limit.
    assert commands[0].speed == pytest.approx(plan[1, 0])
    step_max = sc.vehicle.steering.max_rate * ctrl.config.dt
    steers = [first.steer] + [c.steer for c in commands]
    assert np.all(np.abs(np.diff(steers)) <= step_max + 1e-9)
    failing.mode = "ok"
    ctrl.step(obs)
    assert ctrl.info.status == "ok"
    assert ctrl.step_count == 5 and ctrl.fallback_count == 3


@pytest.mark.parametrize("name", ACADOS)
def test_acados_infeasible_problem_falls_back(builtin_scenario, name):
    sc = builtin_scenario
    ctrl = _make(name, sc)
    ctrl.reset()
    obs = _on_path_observation(sc)
    ctrl.step(obs)
    # A previous wheel angle far outside the limits: the rate constraint cannot be met.
    ctrl._guard.previous = np.array([1.0, sc.vehicle.steering.max_angle + 1.0])
    cmd = ctrl.step(obs)
    assert ctrl.info.status == "numerical"  # acados reports a QP failure, not infeasibility
    assert np.isfinite(cmd.speed) and np.isfinite(cmd.steer)
    assert ctrl.fallback_count == 1
    ctrl.step(obs)
    assert ctrl.info.status == "ok"


def test_acados_rejects_bad_options(builtin_scenario):
    sc = builtin_scenario
    with pytest.raises(ParameterError, match="qp_solver"):
        AcadosKinematicNMPC(sc.reference, sc.vehicle, qp_solver="OSQP")
    with pytest.raises(ParameterError, match="limited-memory"):
        _make("nmpc-acados", sc, replace(NMPCConfig(), hessian="limited-memory"))


def test_loading_acados_leaves_the_blas_of_later_libraries_alone():
    # qpOASES_e, which libacados needs, defines its own reduced dgemm_ and dpotrf_. Loaded into the
    # global scope, they stood in for the BLAS of libraries loaded after it: torch, imported after an
    # acados NMPC was built, crashed (SIGSEGV) in its first float64 solve. A fresh process, so that
    # torch loads after acados whatever this process has loaded.
    import subprocess
    import sys

    code = (
        "from rkmpc.control.nonlinear.acados_build import import_acados\n"
        "import_acados()\n"
        "import torch\n"
        "a = torch.rand(8, 8, dtype=torch.float64) + 8 * torch.eye(8, dtype=torch.float64)\n"
        "b = torch.rand(8, 3, dtype=torch.float64)\n"
        "x = torch.linalg.solve(a, b)\n"
        "assert torch.allclose(a @ x, b)\n"
        "print('ok')\n"
    )
    command = [sys.executable, "-c", code]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0 and done.stdout.strip() == "ok", (done.returncode, done.stderr[-2000:])
