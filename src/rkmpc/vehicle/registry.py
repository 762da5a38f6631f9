"""Plants by name: :func:`make_plant`."""

from __future__ import annotations

from collections.abc import Callable

from rkmpc.core.registry import Registry
from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.plants.fullsize import FullSizePlant

__all__ = ["PLANTS", "make_plant"]


def _make_f1tenth() -> Plant:
    return DynamicPlant(f1tenth())


#: Plant factories by name, each making the preset's plant with its default settings (a plant with
#: other settings is built from its class: ``DynamicPlant(params, internal_dt=...)``).
PLANTS: Registry[Callable[[], Plant]] = Registry(
    "plant", {"f1tenth": _make_f1tenth, "fullsize": FullSizePlant}
)


def make_plant(name: str) -> Plant:
    """Build a registered plant.

    Parameters
    ----------
    name : str
        A key of :data:`PLANTS` (``"f1tenth"``, ``"fullsize"``).

    Returns
    -------
    Plant
        The plant, reset to the origin at standstill.

    Raises
    ------
    UnknownNameError
        If ``name`` is not registered.
    """
    return PLANTS[name]()
