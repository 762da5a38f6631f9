"""Where the jobs of :func:`rkmpc.experiments.parallel.run_jobs` run: the backends' set-up.

* :func:`check_backend`: the packages a backend needs are installed, said in one line before any
  work (a study trains its shared models first; it must not find out after them).
* :func:`backend_config`: joblib's ``parallel_config`` for the backend (a Ray session started
  when none runs).
* :func:`watch_parent`: a local worker ends when the process that started it is gone. A loky
  worker in the middle of a job otherwise runs it to its end after its parent was killed
  (``kill -9``, out of memory), and a long study's job runs for minutes.
"""

from __future__ import annotations

import importlib.util
import os
import threading
import time
from typing import Any

from rkmpc.core.errors import MissingPackageError, ParameterError

__all__ = ["BACKENDS", "PARENT_POLL_S", "backend_config", "check_backend", "watch_parent"]

#: Backends :func:`rkmpc.experiments.parallel.run_jobs` accepts.
BACKENDS = ("loky", "dask", "ray")

#: The packages each backend needs beyond joblib, and how to install them.
_NEEDS: dict[str, tuple[str, ...]] = {"loky": (), "dask": ("dask", "distributed"), "ray": ("ray",)}
_INSTALL = "pip install 'rkmpc[cluster]'"

#: How often a worker looks for its parent (s): how long it may outlive it.
PARENT_POLL_S = 0.5


def check_backend(backend: str) -> None:
    """Raise :class:`MissingPackageError` (one line) when a package ``backend`` needs is missing."""
    if backend not in BACKENDS:
        raise ParameterError(f"backend must be one of {list(BACKENDS)}, got {backend!r}")
    missing = [name for name in _NEEDS[backend] if importlib.util.find_spec(name) is None]
    if missing:
        raise MissingPackageError(
            f"backend {backend!r} needs {' and '.join(missing)}, not installed: {_INSTALL}"
        )


def backend_config(backend: str, n_jobs: int, address: str | None) -> tuple[dict[str, Any], bool]:
    """joblib's ``parallel_config`` for the backend, and whether Ray was started here."""
    check_backend(backend)
    config: dict[str, Any] = {"backend": backend, "n_jobs": n_jobs}
    if backend == "loky":
        config["inner_max_num_threads"] = 1
        return config, False
    if backend == "dask":
        import distributed

        if address is not None:
            config["scheduler_host"] = address
            return config, False
        try:
            distributed.get_client()
        except ValueError:
            raise ParameterError(
                "backend 'dask' without an address needs a dask.distributed.Client started in "
                "this process (Client(...) or Client(LocalCluster(...))), or address='tcp://...'"
            ) from None
        return config, False
    import ray
    from ray.util.joblib import register_ray

    register_ray()
    if ray.is_initialized():
        return config, False
    ray.init(address=address)
    return config, True


_WATCHING: list[int] = []


def watch_parent(parent: int) -> None:
    """End this process (a local worker) soon after ``parent``, the process that started it, ends.

    Does nothing in ``parent`` itself (jobs run in the calling process) or when this process
    already watches. A daemon thread compares :func:`os.getppid` with ``parent`` every
    :data:`PARENT_POLL_S` seconds: a worker whose parent died has been handed to another process
    (init), and leaves at once with :func:`os._exit` (the job it was running has no one to
    report to).
    """
    if os.getpid() == parent or _WATCHING:
        return
    _WATCHING.append(parent)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="rkmpc-parent-watch", daemon=True).start()
