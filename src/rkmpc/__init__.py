"""rkmpc: Residual Koopman model predictive control for vehicle trajectory tracking."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("rkmpc")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

from rkmpc.control.factory import make_controller

__all__ = ["__version__", "make_controller"]
