"""Controllers by name: :func:`make_controller` and the registry it reads.

Built-in controllers are registered by the import path of their class and
imported on first use, so that building a pure pursuit does not load CasADi and
the optional acados extra is needed only by the acados controllers. Which
controllers need a learned model, and of which kind, comes from their recipes
(:mod:`rkmpc.learning.recipes`).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from rkmpc.control.base import Controller
from rkmpc.core.errors import ParameterError
from rkmpc.learning.contract import Provenance, contract_of
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.recipes import RECIPES
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference

__all__ = ["CONTROLLERS", "MODEL_KIND", "make_controller", "register_controller"]

ControllerFactory = Callable[..., Controller]


class _Lazy:
    """A controller class named by ``"module:Class"``, imported when first called."""

    def __init__(self, target: str) -> None:
        self.target = target

    def __call__(self, reference: Reference, vehicle: VehicleParams, **options: Any) -> Controller:
        module, _, cls = self.target.partition(":")
        factory: ControllerFactory = getattr(importlib.import_module(module), cls)
        return factory(reference, vehicle, **options)

    def __repr__(self) -> str:
        return f"<controller {self.target}>"


#: Controller builders by registry name; each takes ``(reference, vehicle, **options)``.
CONTROLLERS: dict[str, ControllerFactory] = {
    "pp": _Lazy("rkmpc.control.pure_pursuit:PurePursuit"),
    "lmpc": _Lazy("rkmpc.control.linear.lmpc:LinearMPC"),
    "lmpc-id": _Lazy("rkmpc.control.linear.lmpc_id:IdentifiedLMPC"),
    "nmpc": _Lazy("rkmpc.control.nonlinear.nmpc:KinematicNMPC"),
    "nmpc-dynamic": _Lazy("rkmpc.control.nonlinear.nmpc:DynamicNMPC"),
    "nmpc-acados": _Lazy("rkmpc.control.nonlinear.acados:AcadosKinematicNMPC"),
    "nmpc-acados-dynamic": _Lazy("rkmpc.control.nonlinear.acados_dynamic:AcadosDynamicNMPC"),
    "kmpc": _Lazy("rkmpc.control.learned.kmpc:KoopmanMPC"),
    "rkmpc": _Lazy("rkmpc.control.learned.rkmpc:ResidualKoopmanMPC"),
    "rkmpc-paper": _Lazy("rkmpc.control.learned.rkmpc:PaperResidualKoopmanMPC"),
}

#: Controllers that need a learned or identified ``model=`` option, and its kind (from the recipes).
MODEL_KIND: dict[str, str] = {recipe.controller: recipe.kind for recipe in RECIPES}


def register_controller(name: str, factory: ControllerFactory) -> None:
    """Add a controller builder to the registry under ``name``."""
    if name in CONTROLLERS:
        raise ValueError(f"a controller named {name!r} is already registered")
    CONTROLLERS[name] = factory


def make_controller(
    name: str, reference: Reference, vehicle: VehicleParams, *, allow_mismatch: bool = False, **options: Any
) -> Controller:
    """Build a controller by name.

    A learned model that records what it was trained with (its contract,
    :mod:`rkmpc.learning.contract`) is checked against the car (name, wheelbase) and the
    controller's period: a model of another car or period is refused.

    Parameters
    ----------
    name : str
        Registry name: ``"pp"`` (pure pursuit), ``"lmpc"`` (linear MPC),
        ``"lmpc-id"`` (LMPC with identified servo lag and understeer), ``"nmpc"`` and
        ``"nmpc-dynamic"`` (nonlinear MPC, CasADi), ``"nmpc-acados"`` and
        ``"nmpc-acados-dynamic"`` (the same as acados real-time iterations; needs
        the optional extra ``rkmpc[acados]``), ``"kmpc"``
        (Koopman MPC), ``"rkmpc"`` (residual Koopman MPC) or ``"rkmpc-paper"``
        (its literal reading). The last four need ``model=``.
    reference : Reference
        Path and speed profile to track.
    vehicle : VehicleParams
        The car's parameters.
    allow_mismatch : bool
        Use a model of another car or period anyway, with a
        :class:`~rkmpc.core.errors.ContractWarning`.
    **options
        Passed to the controller, for example ``config=LMPCConfig(...)``.

    Returns
    -------
    Controller

    Raises
    ------
    ValueError
        For an unknown name.
    ParameterError
        When a learned controller is built without its ``model``.
    ContractError
        When its model was trained with another car, wheelbase or period, unless ``allow_mismatch``.
    """
    try:
        factory = CONTROLLERS[name]
    except KeyError:
        raise ValueError(f"unknown controller {name!r}; known: {sorted(CONTROLLERS)}") from None
    if name in MODEL_KIND and ("model" not in options or options["model"] is None):
        raise ParameterError(f"controller {name!r} needs model= (a {MODEL_KIND[name]!r} model)")
    controller = factory(reference, vehicle, **options)
    model = options["model"] if "model" in options else None
    if isinstance(model, KoopmanModel):
        runs_with = Provenance(vehicle=vehicle.name, dt=controller.dt, wheelbase=vehicle.wheelbase)
        contract_of(model.metadata_).check(
            runs_with, source=f"the {name} model", made="trained", allow_mismatch=allow_mismatch
        )
    return controller
