"""A scripted controller for the tests of what wraps or drives a controller (no solver behind it).

Imported by ``tests/control/test_estimated_controller.py`` and ``tests/ros/test_driver.py``.
"""

from __future__ import annotations

from rkmpc.control.base import Controller
from rkmpc.core.observation import Command, Observation

#: The command a :class:`Scripted` controller answers unless told otherwise: 2 m/s, 0.1 rad.
DRIVE = Command(2.0, 0.1)


class Scripted(Controller):
    """Answers ``command`` (NaN in it too), or raises when ``fail`` is set; keeps what it was shown.

    Both attributes may be changed between steps.
    """

    name = "scripted"
    dt = 0.05

    def __init__(self, command: Command = DRIVE, fail: bool = False) -> None:
        super().__init__()
        self.command, self.fail = command, fail
        self.seen: list[Observation] = []

    def _reset(self) -> None:
        self.seen = []

    def _step(self, observation: Observation) -> tuple[Command, str, str]:
        self.seen.append(observation)
        if self.fail:
            raise RuntimeError("solver exploded")
        return self.command, "ok", ""
