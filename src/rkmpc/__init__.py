"""rkmpc: Residual Koopman model predictive control for vehicle trajectory tracking.

The names below are the stable public API. They are imported on first use, so
that ``import rkmpc.track`` (or any lower floor of the package) does not load
the solvers, CasADi or PyTorch.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from rkmpc.core.versions import RKMPC_VERSION as __version__

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from rkmpc.analysis.metrics import lap_metrics
    from rkmpc.control.registry import make_controller
    from rkmpc.learning.data.dataset import TransitionDataset
    from rkmpc.learning.identification import identify
    from rkmpc.learning.io import load_model
    from rkmpc.learning.koopman.model import KoopmanModel
    from rkmpc.learning.pipeline import train_model
    from rkmpc.sim.closed_loop import simulate
    from rkmpc.sim.scenario import load_scenario

#: Public name -> module that defines it.
_API = {
    "make_controller": "rkmpc.control.registry",
    "load_scenario": "rkmpc.sim.scenario",
    "simulate": "rkmpc.sim.closed_loop",
    "lap_metrics": "rkmpc.analysis.metrics",
    "TransitionDataset": "rkmpc.learning.data.dataset",
    "train_model": "rkmpc.learning.pipeline",
    "identify": "rkmpc.learning.identification",
    "KoopmanModel": "rkmpc.learning.koopman.model",
    "load_model": "rkmpc.learning.io",
}

__all__ = [
    "KoopmanModel",
    "TransitionDataset",
    "__version__",
    "identify",
    "lap_metrics",
    "load_model",
    "load_scenario",
    "make_controller",
    "simulate",
    "train_model",
]


def __getattr__(name: str) -> Any:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'rkmpc' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])
