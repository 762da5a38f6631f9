"""Controllers by name: :func:`make_controller` and the registry it reads.

Built-in controllers are registered by the import path of their class and
imported on first use, so that building a pure pursuit does not load CasADi and
the optional acados extra is needed only by the acados controllers. Every
controller is built from a car's :class:`~rkmpc.control.settings.ControllerSettings`
(each class takes its own fields: :meth:`rkmpc.control.base.Controller.from_settings`).
Which controllers need a learned model, and of which kind, comes from their recipes
(:mod:`rkmpc.learning.recipes`).

:func:`make_controller` does not check a model against the car: a scenario's
:func:`rkmpc.sim.build.build_controller` does (car, period, wheelbase, track scale), once.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from rkmpc.control.base import Controller
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import ParameterError
from rkmpc.core.registry import Registry
from rkmpc.learning.recipes import RECIPES
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference

__all__ = ["CONTROLLERS", "MODEL_KIND", "make_controller", "register_controller"]


class _Lazy:
    """A controller class named by ``"module:Class"``, imported when first asked for."""

    def __init__(self, target: str) -> None:
        self.target = target

    def load(self) -> type[Controller]:
        module, _, cls = self.target.partition(":")
        loaded: type[Controller] = getattr(importlib.import_module(module), cls)
        return loaded

    def __repr__(self) -> str:
        return f"<controller {self.target}>"


#: Controller classes by registry name (imported on first use).
CONTROLLERS: Registry[_Lazy] = Registry(
    "controller",
    {
        "pp": _Lazy("rkmpc.control.pure_pursuit:PurePursuit"),
        "lmpc": _Lazy("rkmpc.control.linear.lmpc:LinearMPC"),
        "lmpc-id": _Lazy("rkmpc.control.linear.lmpc_id:IdentifiedLMPC"),
        "nmpc": _Lazy("rkmpc.control.nonlinear.nmpc:KinematicNMPC"),
        "nmpc-dynamic": _Lazy("rkmpc.control.nonlinear.nmpc:DynamicNMPC"),
        "nmpc-id": _Lazy("rkmpc.control.nonlinear.nmpc_id:IdentifiedDynamicNMPC"),
        "nmpc-acados": _Lazy("rkmpc.control.nonlinear.acados:AcadosKinematicNMPC"),
        "nmpc-acados-dynamic": _Lazy("rkmpc.control.nonlinear.acados_dynamic:AcadosDynamicNMPC"),
        "kmpc": _Lazy("rkmpc.control.learned.kmpc:KoopmanMPC"),
        "rkmpc": _Lazy("rkmpc.control.learned.rkmpc:ResidualKoopmanMPC"),
        "rkmpc-paper": _Lazy("rkmpc.control.learned.rkmpc:PaperResidualKoopmanMPC"),
    },
)

#: Controllers that need a learned or identified ``model``, and its kind (from the recipes).
MODEL_KIND: dict[str, str] = {recipe.controller: recipe.kind for recipe in RECIPES}


def register_controller(name: str, target: str) -> None:
    """Add a controller class, ``"module:Class"`` (importable), to the registry under ``name``."""
    CONTROLLERS.register(name, _Lazy(target))


def make_controller(
    name: str,
    reference: Reference,
    vehicle: VehicleParams,
    *,
    settings: ControllerSettings | None = None,
    model: object = None,
) -> Controller:
    """Build a controller by name from a car's settings.

    Parameters
    ----------
    name : str
        Registry name: ``"pp"`` (pure pursuit), ``"lmpc"`` (linear MPC),
        ``"lmpc-id"`` (LMPC with identified servo lag and understeer), ``"nmpc"`` and
        ``"nmpc-dynamic"`` (nonlinear MPC, CasADi), ``"nmpc-id"`` (the dynamic one on identified
        tyres and servo, one SQP iteration per period), ``"nmpc-acados"`` and
        ``"nmpc-acados-dynamic"`` (the same as acados real-time iterations; needs
        the optional extra ``rkmpc[acados]``), ``"kmpc"``
        (Koopman MPC), ``"rkmpc"`` (residual Koopman MPC) or ``"rkmpc-paper"``
        (its literal reading). ``lmpc-id``, ``nmpc-id`` and the last three need ``model``.
    reference : Reference
        Path and speed profile to track.
    vehicle : VehicleParams
        The car's parameters.
    settings : ControllerSettings, optional
        The car's controller settings (each controller reads its own); the defaults when None.
    model : optional
        The model of a learned controller (a ``KoopmanModel`` or an ``IdentifiedModel``).

    Raises
    ------
    UnknownNameError
        For an unknown name.
    ParameterError
        When a learned controller is built without its model, or another with one.
    """
    cls = CONTROLLERS[name].load()
    if name in MODEL_KIND and model is None:
        raise ParameterError(f"controller {name!r} needs model= (a {MODEL_KIND[name]!r} model)")
    return cls.from_settings(
        reference, vehicle, settings if settings is not None else ControllerSettings(), model
    )
