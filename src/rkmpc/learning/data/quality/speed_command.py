"""Whether a log's speed command set the car's speed, and the repair when it did not.

A remote-controlled car's log may record an Ackermann command whose speed is not what drove the
car: the throttle came from the radio, the VESC ran on duty cycle, or the command was a constant
cap. One of the shared real runs records a commanded 5 m/s while the car drove at 1.3 m/s. A model
that learns from such a command learns a speed map that holds in no other log. :func:`speed_command_check`
compares the speed reached at the end of each period with the speed commanded for it;
:func:`with_measured_speed_commands` replaces the recorded speed command by the command the car's
speed loop (a first-order lag of the car's time constant, the plant's model of it) needed to go from
each measured speed to the next: the speed the driver asked for, as far as the car shows it, in
the units and with the lag of a command that did set the speed. The import applies it when the
spec asks (``speed_command``), and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.learning.data.dataset import TransitionDataset

__all__ = [
    "SPEED_COMMAND_RULES",
    "TRACKING_RANGE",
    "SpeedCommandCheck",
    "speed_command_check",
    "with_measured_speed_commands",
]

#: How an import treats the recorded speed command: as recorded, replaced by the measured speed, or
#: replaced only when it did not set the speed (:data:`TRACKING_RANGE`).
SPEED_COMMAND_RULES = ("recorded", "measured", "auto")
#: Median ratio of the speed reached to the speed commanded that counts as tracking the command.
TRACKING_RANGE = (0.67, 1.5)
_SPEED = OBSERVATION_FIELDS.index("speed")


@dataclass(frozen=True, kw_only=True)
class SpeedCommandCheck:
    """The speed reached at the end of each period against the speed commanded for it.

    Parameters
    ----------
    ratio : float
        Median of reached / commanded over the transitions commanded and driven at least 0.5 and
        0.3 m/s (NaN without any).
    samples : int
        Those transitions.
    tracks : bool
        Whether ``ratio`` lies in :data:`TRACKING_RANGE` (True when there are no samples).
    replaced : bool
        Whether the import replaced the recorded speed command by the measured speed.
    """

    ratio: float
    samples: int
    tracks: bool
    replaced: bool = False

    def message(self) -> str | None:
        """A warning when the command did not set the speed, else None."""
        if self.tracks:
            return None
        then = (
            "replaced by the measured speed for learning and evaluation"
            if self.replaced
            else 'kept as recorded (speed_command = "recorded"): a model learns a speed map of this log only'
        )
        return (
            f"the speed command did not set the speed: the car reached {self.ratio:.2f} times the "
            f"speed commanded (median of {self.samples} transitions); {then}"
        )


def speed_command_check(data: TransitionDataset) -> SpeedCommandCheck:
    """How the speed reached at the end of each period compares with the speed commanded for it."""
    commanded = data.command[:, 0]
    reached = data.next_obs[:, _SPEED]
    used = np.isfinite(commanded) & np.isfinite(reached) & (commanded >= 0.5) & (reached >= 0.3)
    if not used.any():
        return SpeedCommandCheck(ratio=float("nan"), samples=0, tracks=True)
    ratio = float(np.median(reached[used] / commanded[used]))
    low, high = TRACKING_RANGE
    return SpeedCommandCheck(ratio=ratio, samples=int(used.sum()), tracks=low <= ratio <= high)


def with_measured_speed_commands(data: TransitionDataset, time_constant: float) -> TransitionDataset:
    """``data`` with each speed command replaced by what a first-order speed loop needed.

    With the command held over a period ``dt`` a lag of ``time_constant`` (s) goes from ``v_k`` to
    ``v_{k+1} = u + (v_k - u) a``, ``a = exp(-dt / time_constant)``; so ``u = (v_{k+1} - a v_k) / (1 - a)``,
    held at or above 0.
    """
    a = math.exp(-data.dt / time_constant)
    command = data.command.copy()
    speed, reached = data.obs[:, _SPEED], data.next_obs[:, _SPEED]
    command[:, 0] = np.maximum((reached - a * speed) / (1.0 - a), 0.0)
    return replace(data, command=command)
