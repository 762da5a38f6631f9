"""Controllers behind one interface: observation in, command out."""

from rkmpc.control.base import Command, Controller, Observation, StepInfo
from rkmpc.control.factory import CONTROLLERS, make_controller, register_controller
from rkmpc.control.lmpc import LinearMPC, LMPCConfig
from rkmpc.control.pure_pursuit import PurePursuit, PurePursuitConfig

__all__ = [
    "CONTROLLERS",
    "Command",
    "Controller",
    "LMPCConfig",
    "LinearMPC",
    "Observation",
    "PurePursuit",
    "PurePursuitConfig",
    "StepInfo",
    "make_controller",
    "register_controller",
]
