"""The settings of ``rkmpc sim-node``, the project's simulated car as a ROS 2 node."""

from __future__ import annotations

from dataclasses import dataclass, field

from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_integer, require_choice, require_nonnegative, require_positive_or_none

__all__ = ["CLOCKS", "SimNodeConfig"]

#: ``"realtime"``: physics paced by the wall clock, commands applied as they come (what a user
#: watches). ``"lockstep"``: publish the odometry, wait for the command that answers it (stamped
#: with the odometry's stamp), then advance one control period; a run's result then does not depend
#: on how busy the machine is.
CLOCKS = ("realtime", "lockstep")


@dataclass(frozen=True, kw_only=True)
class SimNodeConfig:
    """What the simulated car drives and how it talks (SI units).

    Parameters
    ----------
    car : CarConfig
        The car (its plant, or the zoo car it drives: ``car.plant``), as every command reads it.
    track, raceline, scale : as :meth:`rkmpc.sim.scenario.Scenario.from_car`
        The track (built-in name or TUM CSV), an optional race line, the file scale.
    clock : str
        One of :data:`CLOCKS`.
    laps : int
        Laps to drive; the node reports and exits when they are done or the car leaves the track.
    period : float
        Control period (s): in lock-step, the time the car advances per command.
    physics_rate_hz : float
        Physics steps per second (100, as the F1TENTH simulator).
    odometry_rate_hz : float
        Odometry messages per second in real time (at most the physics rate).
    actuation_delay : float
        Time from a command's arrival to the car acting on it (s), >= 0, on top of the car's own.
    standstill : bool
        Start at rest with straight wheels instead of at the reference speed.
    seed : int
        Seed of the car's randomness (a zoo car's odometry noise).
    odometry_topic, drive_topic, steering_topic, status_topic : str
        Topics; ``steering_topic`` carries the true front wheel angle (``std_msgs/msg/Float64``,
        rad), empty for none. The status topic carries JSON (``std_msgs/msg/String``).
    frame, child_frame : str
        Frame ids of the odometry (the F1TENTH bridge's ``map`` and ``ego_racecar/base_link``).
    answer_timeout : float
        Lock-step: how long (wall-clock s) to wait for an answer before ending the run as
        ``"no_controller"``: a bound against a hang, not a measure.
    startup_timeout : float or None
        How long (s) to wait for the first command; None waits until interrupted.
    """

    car: CarConfig = field(default_factory=lambda: load_preset("f1tenth"))
    track: str = "builtin"
    raceline: str | None = None
    scale: float | None = None
    clock: str = "realtime"
    laps: int = 1
    period: float = 0.05
    physics_rate_hz: float = 100.0
    odometry_rate_hz: float = 50.0
    actuation_delay: float = 0.0
    standstill: bool = False
    seed: int = 0
    odometry_topic: str = "/ego_racecar/odom"
    drive_topic: str = "/drive"
    steering_topic: str = ""
    status_topic: str = "/rkmpc/sim/status"
    frame: str = "map"
    child_frame: str = "ego_racecar/base_link"
    answer_timeout: float = 30.0
    startup_timeout: float | None = None

    def __post_init__(self) -> None:
        require_choice(self, "clock", CLOCKS)
        if not is_integer(self.laps, 1):
            raise ParameterError(f"laps must be an integer >= 1, got {self.laps!r}")
        require_positive_or_none(
            self, "period", "physics_rate_hz", "odometry_rate_hz", "answer_timeout", "startup_timeout"
        )
        require_nonnegative(self, "actuation_delay")
        steps = self.period * self.physics_rate_hz
        if abs(steps - round(steps)) > 1e-6:
            raise ParameterError(
                f"period ({self.period} s) must be whole physics steps (1/{self.physics_rate_hz} s)"
            )
        if self.odometry_rate_hz > self.physics_rate_hz:
            raise ParameterError("odometry_rate_hz must not exceed physics_rate_hz")

    @property
    def physics_dt(self) -> float:
        """The physics step (s)."""
        return 1.0 / self.physics_rate_hz

    @property
    def odometry_every(self) -> int:
        """Physics steps between odometry messages in real time."""
        return max(1, round(self.physics_rate_hz / self.odometry_rate_hz))
