"""Building an acados solver once and loading it: the generated C code, its bulk Cython interface, the cache.

The generated C code and the Cython module (:data:`BULK_PYX`) are built once per
problem into ``~/.cache/rkmpc/acados/<name>`` (or ``$RKMPC_CACHE_DIR/acados``),
never into the working directory; concurrent builds of the same problem wait on
a file lock (:func:`locked`).
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib.util
import os
import subprocess
import sys
import sysconfig
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = [
    "BULK_PYX",
    "INSTALL_HINT",
    "acados_cache_dir",
    "build_bulk_module",
    "import_acados",
    "load_module",
    "locked",
]

INSTALL_HINT = (
    "the acados NMPCs need acados and cython; install them with `pip install rkmpc[acados]` "
    "(comma-deps-acados==0.2.2.post92, cython==3.3.1)"
)
#: The Cython module built beside each generated solver: bulk copies in and out of acados.
BULK_PYX = '''\
# cython: language_level=3, boundscheck=False, wraparound=False, initializedcheck=False
"""Bulk access to one generated acados OCP solver (written by rkmpc.control.nonlinear.acados)."""

cimport acados_solver_common as common
cimport acados_solver as generated


cdef class BulkSolver:
    """Create the generated solver; set and get the data of all stages in one call each."""

    cdef generated.nlp_solver_capsule *capsule
    cdef common.ocp_nlp_config *config
    cdef common.ocp_nlp_dims *dims
    cdef common.ocp_nlp_in *nlp_in
    cdef common.ocp_nlp_out *nlp_out
    cdef common.ocp_nlp_solver *solver
    cdef bint created
    cdef readonly int N, nx, nu, ny, ny_e

    def __cinit__(self, int N, int nx, int nu, int ny, int ny_e):
        self.created = False
        self.capsule = generated.acados_create_capsule()
        if self.capsule == NULL:
            raise MemoryError("acados: could not allocate the solver capsule")
        if generated.acados_create(self.capsule) != 0:
            raise RuntimeError("acados: could not create the solver")
        self.created = True
        self.config = generated.acados_get_nlp_config(self.capsule)
        self.dims = generated.acados_get_nlp_dims(self.capsule)
        self.nlp_in = generated.acados_get_nlp_in(self.capsule)
        self.nlp_out = generated.acados_get_nlp_out(self.capsule)
        self.solver = generated.acados_get_nlp_solver(self.capsule)
        self.N, self.nx, self.nu, self.ny, self.ny_e = N, nx, nu, ny, ny_e
        if (common.ocp_nlp_dims_get_from_attr(self.config, self.dims, self.nlp_out, 0, b"x") != nx
                or common.ocp_nlp_dims_get_from_attr(self.config, self.dims, self.nlp_out, 0, b"u") != nu):
            raise ValueError("acados: the generated solver has other dimensions")

    def __dealloc__(self):
        if self.capsule != NULL:
            if self.created:
                generated.acados_free(self.capsule)
            generated.acados_free_capsule(self.capsule)

    cdef void _check(self, const double[:, ::1] a, int rows, int cols, str name) except *:
        if a.shape[0] != rows or a.shape[1] != cols:
            raise ValueError(f"{name}: expected shape ({rows}, {cols}), got ({a.shape[0]}, {a.shape[1]})")

    def prepare(self, const double[::1] x0, const double[:, ::1] yref, const double[::1] yref_e,
                const double[:, ::1] lbu, const double[:, ::1] ubu,
                const double[:, ::1] x_guess, const double[:, ::1] u_guess):
        """Initial state, references, input bounds and initial guess of all stages."""
        cdef int k
        cdef common.ocp_nlp_config *cfg = self.config
        cdef common.ocp_nlp_dims *dims = self.dims
        cdef common.ocp_nlp_in *nlp_in = self.nlp_in
        cdef common.ocp_nlp_out *out = self.nlp_out
        if x0.shape[0] != self.nx or yref_e.shape[0] != self.ny_e:
            raise ValueError("x0 or yref_e: wrong length")
        self._check(yref, self.N, self.ny, "yref")
        self._check(lbu, self.N, self.nu, "lbu")
        self._check(ubu, self.N, self.nu, "ubu")
        self._check(x_guess, self.N + 1, self.nx, "x_guess")
        self._check(u_guess, self.N, self.nu, "u_guess")
        common.ocp_nlp_constraints_model_set(cfg, dims, nlp_in, 0, b"lbx", <void *> &x0[0])
        common.ocp_nlp_constraints_model_set(cfg, dims, nlp_in, 0, b"ubx", <void *> &x0[0])
        for k in range(self.N):
            common.ocp_nlp_cost_model_set(cfg, dims, nlp_in, k, b"yref", <void *> &yref[k, 0])
            common.ocp_nlp_constraints_model_set(cfg, dims, nlp_in, k, b"lbu", <void *> &lbu[k, 0])
            common.ocp_nlp_constraints_model_set(cfg, dims, nlp_in, k, b"ubu", <void *> &ubu[k, 0])
            common.ocp_nlp_out_set(cfg, dims, out, k, b"x", <void *> &x_guess[k, 0])
            common.ocp_nlp_out_set(cfg, dims, out, k, b"u", <void *> &u_guess[k, 0])
        common.ocp_nlp_cost_model_set(cfg, dims, nlp_in, self.N, b"yref", <void *> &yref_e[0])
        common.ocp_nlp_out_set(cfg, dims, out, self.N, b"x", <void *> &x_guess[self.N, 0])

    def solve(self):
        """One call of the acados solver; returns its status (0: success)."""
        return generated.acados_solve(self.capsule)

    def solution(self, double[:, ::1] x_out, double[:, ::1] u_out):
        """Copy the current iterate into ``x_out`` (N+1, nx) and ``u_out`` (N, nu)."""
        cdef int k
        self._check(x_out, self.N + 1, self.nx, "x_out")
        self._check(u_out, self.N, self.nu, "u_out")
        for k in range(self.N):
            common.ocp_nlp_out_get(self.config, self.dims, self.nlp_out, k, b"x", <void *> &x_out[k, 0])
            common.ocp_nlp_out_get(self.config, self.dims, self.nlp_out, k, b"u", <void *> &u_out[k, 0])
        common.ocp_nlp_out_get(self.config, self.dims, self.nlp_out, self.N, b"x", <void *> &x_out[self.N, 0])

    def solve_time(self):
        """acados' own time of the last solve (s)."""
        cdef double t = 0.0
        common.ocp_nlp_get(self.config, self.solver, b"time_tot", <void *> &t)
        return t

    def reset(self):
        """Zero the iterate and the QP solver's memory (after a failure)."""
        generated.acados_reset(self.capsule, 1)
'''


def acados_cache_dir() -> Path:
    """Root folder of the generated solvers: ``$RKMPC_CACHE_DIR/acados`` or ``~/.cache/rkmpc/acados``."""
    root = os.environ.get("RKMPC_CACHE_DIR")
    base = Path(root) if root else Path.home() / ".cache" / "rkmpc"
    return base / "acados"


def import_acados() -> tuple[Any, Any]:
    """Import acados, set its environment and preload its libraries.

    Returns the ``acados`` package (paths) and ``acados_template``.

    Raises
    ------
    ImportError
        When acados or cython is not installed.
    """
    try:
        import acados  # comma-deps-acados: the C library and the template live under this package
        from acados import acados_template
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(INSTALL_HINT) from exc
    if importlib.util.find_spec("Cython") is None:  # pragma: no cover - depends on the environment
        raise ImportError(INSTALL_HINT)
    os.environ.setdefault("ACADOS_SOURCE_DIR", acados.DIR)
    os.environ.setdefault("TERA_PATH", acados.TERA_PATH)
    os.environ.setdefault("ACADOS_PYTHON_INTERFACE_PATH", acados.TEMPLATE_DIR)
    # libacados.so has no RPATH: load it and its dependencies before the generated solver, which
    # then finds them by name. Locally, not globally: qpOASES_e (a dependency of libacados) brings
    # its own reduced dgemm_ and dpotrf_, which, in the global scope, would stand in for the BLAS of
    # every library loaded after it (torch's float64 solve crashed on them).
    for lib in ("libblasfeo.so", "libhpipm.so", "libqpOASES_e.so.3.1", "libacados.so"):
        path = os.path.join(acados.LIB_DIR, lib)
        if os.path.exists(path):
            ctypes.CDLL(path, mode=ctypes.RTLD_LOCAL)
    return acados, acados_template


@contextlib.contextmanager
def locked(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``path`` (a no-op where ``fcntl`` is missing)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _run(cmd: list[str], cwd: Path) -> None:
    """Run a build command; raise RuntimeError with its output when it fails."""
    done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"acados build step failed: {' '.join(cmd)}\n{done.stdout}\n{done.stderr}")


def build_bulk_module(acados: Any, code_dir: Path, model_name: str) -> Path:
    """Compile :data:`BULK_PYX` against the generated solver in ``code_dir``; returns the module file."""
    module = f"{model_name}_bulk"
    (code_dir / f"{module}.pyx").write_text(BULK_PYX)
    cython = [sys.executable, "-m", "cython", "-3", "-I", acados.TEMPLATE_DIR, "-I", str(code_dir)]
    _run([*cython, "-o", f"{module}.c", f"{module}.pyx"], code_dir)
    include = Path(acados.INCLUDE_DIR)
    includes = [code_dir, include, include / "acados", include / "blasfeo" / "include"]
    includes += [include / "hpipm" / "include", include / "qpOASES_e", Path(sysconfig.get_paths()["include"])]
    libs = [f"acados_ocp_solver_{model_name}", "acados", "hpipm", "blasfeo", "m"]
    target = code_dir / f"{module}{sysconfig.get_config_var('EXT_SUFFIX') or '.so'}"
    cc = os.environ.get("CC", "cc").split()
    _run(
        [*cc, "-O2", "-fPIC", "-shared", "-o", str(target), f"{module}.c"]
        + [f"-I{path}" for path in includes]
        + [f"-L{code_dir}", f"-L{acados.LIB_DIR}"]
        + [f"-l{lib}" for lib in libs]
        + [f"-Wl,-rpath,{code_dir}", f"-Wl,-rpath,{acados.LIB_DIR}"],
        code_dir,
    )
    return target


def load_module(name: str, path: Path) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:  # pragma: no cover - defensive
        raise ImportError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
