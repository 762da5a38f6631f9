"""Plants by name: :func:`make_plant`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rkmpc.core.registry import Registry
from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.plants.fullsize import FullSizePlant

__all__ = ["PLANTS", "make_plant"]


def _make_f1tenth(**options: Any) -> Plant:
    params = options.pop("params", None) or f1tenth()
    return DynamicPlant(params, **options)


def _make_fullsize(**options: Any) -> Plant:
    return FullSizePlant(**options)


#: Plant factories by name; each accepts the plant's keyword options.
PLANTS: Registry[Callable[..., Plant]] = Registry(
    "plant", {"f1tenth": _make_f1tenth, "fullsize": _make_fullsize}
)


def make_plant(name: str, **options: Any) -> Plant:
    """Build a registered plant.

    Parameters
    ----------
    name : str
        A key of :data:`PLANTS` (``"f1tenth"``, ``"fullsize"``).
    **options
        Keyword options of the plant's constructor (``internal_dt``,
        ``input_delay``, ``friction``; ``params`` for ``"f1tenth"``).

    Returns
    -------
    Plant
        The plant, reset to the origin at standstill.

    Raises
    ------
    UnknownNameError
        If ``name`` is not registered.
    """
    return PLANTS[name](**options)
