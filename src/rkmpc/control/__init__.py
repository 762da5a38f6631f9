"""Controllers behind one interface: observation in, command out."""

from rkmpc.control.base import Controller, StepInfo
from rkmpc.control.linear.lmpc import LinearMPC, LMPCConfig
from rkmpc.control.pure_pursuit import PurePursuit, PurePursuitConfig
from rkmpc.control.registry import CONTROLLERS, make_controller, register_controller
from rkmpc.core.observation import Command, Observation

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
