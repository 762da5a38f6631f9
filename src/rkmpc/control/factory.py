"""Build controllers by name."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from rkmpc.control.base import Controller
from rkmpc.control.koopman_mpc import KoopmanMPC
from rkmpc.control.lmpc import LinearMPC
from rkmpc.control.lmpc_id import IdentifiedLMPC
from rkmpc.control.nmpc import DynamicNMPC, KinematicNMPC
from rkmpc.control.pure_pursuit import PurePursuit
from rkmpc.control.rkmpc import PaperResidualKoopmanMPC, ResidualKoopmanMPC
from rkmpc.vehicle.params import VehicleParams

if TYPE_CHECKING:
    from rkmpc.track.reference import Reference

ControllerFactory = Callable[..., Controller]


def _acados_nmpc(reference: Reference, vehicle: VehicleParams, **options: Any) -> Controller:
    """``nmpc-acados``: imported on use, as acados is an optional extra."""
    from rkmpc.control.nmpc_acados import AcadosKinematicNMPC

    return AcadosKinematicNMPC(reference, vehicle, **options)


def _acados_nmpc_dynamic(reference: Reference, vehicle: VehicleParams, **options: Any) -> Controller:
    """``nmpc-acados-dynamic``: imported on use, as acados is an optional extra."""
    from rkmpc.control.nmpc_acados_dynamic import AcadosDynamicNMPC

    return AcadosDynamicNMPC(reference, vehicle, **options)


#: Controller builders by registry name; each takes ``(reference, vehicle, **options)``.
CONTROLLERS: dict[str, ControllerFactory] = {
    "pp": PurePursuit,
    "lmpc": LinearMPC,
    "lmpc-id": IdentifiedLMPC,
    "nmpc": KinematicNMPC,
    "nmpc-dynamic": DynamicNMPC,
    "nmpc-acados": _acados_nmpc,
    "nmpc-acados-dynamic": _acados_nmpc_dynamic,
    "kmpc": KoopmanMPC,
    "rkmpc": ResidualKoopmanMPC,
    "rkmpc-paper": PaperResidualKoopmanMPC,
}

#: Controllers that need a learned or identified ``model=`` option, and its kind.
MODEL_KIND: dict[str, str] = {
    "lmpc-id": "identified",
    "kmpc": "koopman",
    "rkmpc": "residual",
    "rkmpc-paper": "paper",
}


def register_controller(name: str, factory: ControllerFactory) -> None:
    """Add a controller builder to the registry under ``name``."""
    if name in CONTROLLERS:
        raise ValueError(f"a controller named {name!r} is already registered")
    CONTROLLERS[name] = factory


def make_controller(name: str, reference: Reference, vehicle: VehicleParams, **options: Any) -> Controller:
    """Build a controller by name.

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
    **options
        Passed to the controller, for example ``config=LMPCConfig(...)``.

    Returns
    -------
    Controller
    """
    try:
        factory = CONTROLLERS[name]
    except KeyError:
        raise ValueError(f"unknown controller {name!r}; known: {sorted(CONTROLLERS)}") from None
    return factory(reference, vehicle, **options)
