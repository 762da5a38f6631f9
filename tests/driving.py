"""A controller driven the first steps of the built-in track on the nominal plant (tests of its step)."""

from __future__ import annotations

from rkmpc.control.base import Controller
from rkmpc.core.observation import Observation
from rkmpc.sim.scenario import Scenario
from rkmpc.vehicle.registry import make_plant


def drive_then_step(sc: Scenario, controller: Controller, steps: int) -> Observation:
    """Drive ``steps`` steps from the reference's start, then step once more; that step's observation."""
    plant = make_plant("f1tenth")
    start = sc.reference.horizon(0.0, 1, sc.dt)
    plant.reset(start.x[0], start.y[0], start.theta[0], start.v[0], start.delta[0])
    for _ in range(steps):
        plant.step(controller.step(plant.observe()), sc.dt)
    observation = plant.observe()
    controller.step(observation)
    return observation
