"""The settings of every controller of a car, in one typed record: :class:`ControllerSettings`.

A car (:class:`rkmpc.config.car.CarConfig`) holds one of these; every controller is built from
it by :func:`rkmpc.control.registry.make_controller`, each class taking the fields it reads
(:meth:`rkmpc.control.base.Controller.from_settings`). A setting written in a car file
(``[controllers.rkmpc] position_weight``) thus reaches the controller as a typed field, never
through a dictionary of options.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

from rkmpc.control.learned.residual_config import PAPER_RESIDUAL, ResidualMPCConfig, RKMPCConfig
from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.nonlinear.settings import NMPCConfig
from rkmpc.control.pure_pursuit import PurePursuitConfig
from rkmpc.core.errors import ParameterError
from rkmpc.core.jsonutil import to_json_ready

__all__ = ["SECTIONS", "ControllerSettings"]

#: The sections of a car file's ``[controllers]``, their attribute and settings class.
SECTIONS: dict[str, tuple[str, type]] = {
    "lmpc": ("lmpc", LMPCConfig),
    "rkmpc": ("rkmpc", RKMPCConfig),
    "rkmpc-paper": ("rkmpc_paper", ResidualMPCConfig),
    "pp": ("pp", PurePursuitConfig),
    "nmpc": ("nmpc", NMPCConfig),
}


@dataclass(frozen=True, kw_only=True)
class ControllerSettings:
    """The settings of every controller of one car (the controllers' defaults by default).

    Parameters
    ----------
    lmpc : LMPCConfig
        The linear MPC: ``lmpc``, ``lmpc-id``, ``kmpc``, and the baseline of ``rkmpc`` and
        ``rkmpc-paper``.
    rkmpc : RKMPCConfig
        The residual MPC of ``rkmpc``.
    rkmpc_paper : ResidualMPCConfig
        The residual MPC of ``rkmpc-paper`` (not an :class:`RKMPCConfig`: it reads none of
        rkmpc's own settings).
    pp : PurePursuitConfig
        Pure pursuit.
    nmpc : NMPCConfig
        The nonlinear MPCs (``nmpc``, ``nmpc-dynamic`` and their acados variants).
    """

    lmpc: LMPCConfig = field(default_factory=LMPCConfig)
    rkmpc: RKMPCConfig = field(default_factory=RKMPCConfig)
    rkmpc_paper: ResidualMPCConfig = PAPER_RESIDUAL
    pp: PurePursuitConfig = field(default_factory=PurePursuitConfig)
    nmpc: NMPCConfig = field(default_factory=NMPCConfig)

    def __post_init__(self) -> None:
        for section, (attr, kind) in SECTIONS.items():
            value = getattr(self, attr)
            if type(value) is not kind:
                raise ParameterError(
                    f"ControllerSettings.{attr} ([controllers.{section}]) must be a {kind.__name__}, "
                    f"got {type(value).__name__}"
                )

    def with_period(self, dt: float) -> ControllerSettings:
        """The same settings planning with the control period ``dt`` (s): the MPCs' ``dt``."""
        if self.lmpc.dt == dt and self.nmpc.dt == dt:
            return self
        return replace(self, lmpc=replace(self.lmpc, dt=dt), nmpc=replace(self.nmpc, dt=dt))

    def to_json(self) -> dict[str, Any]:
        """Every section's values, by section name."""
        return {
            section: to_json_ready(asdict(getattr(self, attr))) for section, (attr, _) in SECTIONS.items()
        }
