"""Versions of Python and the packages that shape a result, recorded beside every result."""

from __future__ import annotations

import platform
from collections.abc import Iterable
from importlib.metadata import PackageNotFoundError, version

__all__ = ["RESULT_PACKAGES", "RKMPC_VERSION", "package_version", "versions"]

#: Packages whose versions every result records.
RESULT_PACKAGES = ("rkmpc", "numpy", "scipy", "daqp", "osqp", "commonroad-vehicle-models")


def package_version(name: str, missing: str = "not installed") -> str:
    """The installed version of distribution ``name``, or ``missing``."""
    try:
        return version(name)
    except PackageNotFoundError:
        return missing


def versions(extra: Iterable[str] = ()) -> dict[str, str]:
    """``{"python": ..., package: version}`` for :data:`RESULT_PACKAGES` and ``extra``."""
    out = {"python": platform.python_version()}
    for name in (*RESULT_PACKAGES, *extra):
        out[name] = package_version(name)
    return out


#: The installed version of rkmpc (``0.0.0`` when run from a source tree without metadata).
RKMPC_VERSION = package_version("rkmpc", "0.0.0")
