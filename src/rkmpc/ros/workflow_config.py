"""What ``rkmpc car-loop`` runs: :class:`WorkflowConfig`."""

from __future__ import annotations

from dataclasses import dataclass

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import require_choice
from rkmpc.ros.sim_config import CLOCKS
from rkmpc.vehicle.sensors import get_sensor_profile

__all__ = ["WorkflowConfig"]


@dataclass(frozen=True)
class WorkflowConfig:
    """What ``rkmpc car-loop`` runs (SI units).

    Parameters
    ----------
    out : str
        The output folder (must not exist or be empty, unless ``force``).
    clock : str
        ``"lockstep"`` (default) or ``"realtime"`` (:data:`rkmpc.ros.sim_config.CLOCKS`).
    track : str
        Built-in track name or TUM centre-line CSV.
    record_laps : int
        LMPC laps recorded for training (the paper's two).
    controllers : tuple of str
        Controllers of Table II, driven a lap each.
    delay : float
        Added actuation delay (s) of the latency-compensation runs; 0 skips them.
    delay_controllers : tuple of str
        Controllers driven with the added delay, with and without compensation.
    seed : int
        Seed of the simulated car and of the training.
    domain_id : int or None
        ``ROS_DOMAIN_ID`` of the run (0-101); None picks one from the process id.
    force : bool
        Replace an earlier ``car-loop`` output folder.
    timeout : float
        Wall-clock bound (s) of each process: a guard against a hang, never a measure.
    sensors : str
        The simulated car's sensors (:mod:`rkmpc.vehicle.sensors`), which the node's car file
        declares too: ``"f1tenth-real"`` (default: a real car's, no wheel angle, so no steering
        topic, and the node drives through the state estimator) or ``"ideal"`` (the wheel angle
        published on a steering topic, as before).
    """

    out: str
    clock: str = "lockstep"
    track: str = "builtin"
    record_laps: int = 2
    controllers: tuple[str, ...] = ("lmpc", "lmpc-id", "rkmpc")
    delay: float = 0.05
    delay_controllers: tuple[str, ...] = ("lmpc", "rkmpc")
    seed: int = 0
    domain_id: int | None = None
    force: bool = False
    timeout: float = 3600.0
    sensors: str = "f1tenth-real"

    def __post_init__(self) -> None:
        from rkmpc.learning.recipes import recipe_for

        require_choice(self, "clock", CLOCKS)
        if self.record_laps < 1:
            raise ParameterError(f"record_laps must be >= 1, got {self.record_laps}")
        if not (self.delay >= 0.0 and self.timeout > 0.0):
            raise ParameterError("delay must be >= 0 and timeout > 0")
        get_sensor_profile(self.sensors)
        if self.domain_id is not None and not 0 <= self.domain_id <= 101:
            raise ParameterError(f"domain_id must be in 0-101, got {self.domain_id}")
        learned = {r.controller: r.kind for name in self.controllers if (r := recipe_for(name)) is not None}
        learned.update(
            {r.controller: r.kind for name in self.delay_controllers if (r := recipe_for(name)) is not None}
        )
        unsupported = sorted(name for name, kind in learned.items() if kind not in ("residual", "identified"))
        if unsupported:
            raise ParameterError(
                f"the workflow trains residual and identified models only, not for {unsupported}"
            )
