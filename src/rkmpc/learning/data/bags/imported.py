"""What the importers of recordings share (bags, CSV logs): the data set of the transitions found."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from rkmpc.core.versions import versions
from rkmpc.learning.contract import Provenance
from rkmpc.learning.data.bags.resample import Transitions
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.vehicle.params import VehicleParams

__all__ = ["imported_dataset"]


def imported_dataset(
    found: Transitions,
    source: Mapping[str, Any],
    *,
    dt: float,
    vehicle: VehicleParams,
    scale: float | None,
    packages: Iterable[str] = (),
) -> TransitionDataset:
    """The transitions an import found as a data set, with its metadata and its contract.

    Parameters
    ----------
    found : Transitions
        The transitions on the control period.
    source : Mapping
        What the importer records of the recording and the import (JSON-ready); the metadata
        starts with it and goes on with the car (``vehicle``, ``wheelbase`` in m, ``scale``) and
        the versions of the software.
    dt : float
        Control period (s) of the transitions.
    vehicle : VehicleParams
        The car that was recorded.
    scale : float or None
        Scale of the track the car drove (for the contract); None when not known.
    packages : iterable of str
        Packages whose versions the metadata records beside the usual ones
        (:func:`rkmpc.core.versions.versions`).
    """
    all_versions = versions(packages)
    metadata = {
        **source,
        "vehicle": vehicle.name,
        "wheelbase": vehicle.wheelbase,
        "scale": scale,
        "rkmpc_version": all_versions["rkmpc"],
        "versions": all_versions,
    }
    data = TransitionDataset(
        obs=found.obs,
        command=found.command,
        next_obs=found.next_obs,
        dt=dt,
        episode=found.episode,
        metadata=metadata,
    )
    made_with = Provenance(vehicle=vehicle.name, dt=dt, wheelbase=vehicle.wheelbase, scale=scale)
    return data.with_contract(made_with)
