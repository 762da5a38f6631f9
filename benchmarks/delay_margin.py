"""How much actuation delay a controller tolerates, through each sensor profile: the real-time margin.

``rkmpc car-loop --clock realtime`` adds delay the lock-step loop does not have: the node plans
from an odometry up to one odometry period old (on its 20 Hz timer, about 12 ms on average with
50 Hz odometry) and the car applies the command at its next 10 ms physics step (5 ms). This
script measures, without ROS and in lock-step (so the figures do not depend on the machine's
load), how each controller's two laps of a track degrade as a command acts ``d`` seconds after it
is given: the car of ``rkmpc sim-node`` (:class:`~rkmpc.ros.sim_plant.PhysicsPlant`, 100 Hz
physics, a timed actuation delay), the controller built for the car's sensor profile as every
command builds it (behind the state estimator where the profile is not ideal).

Prints, per profile, controller and delay, the outcome and the mean / largest lateral error (m)
over the run (both laps: a swing that grows shows on the second). Controllers that learn are
trained as ``compare`` trains them (two LMPC laps through the same sensors; the model cache).

Run: ``python benchmarks/delay_margin.py [--track builtin] [--controllers lmpc]
[--sensors ideal,no-steer,f1tenth-real] [--delays 0,0.01,0.02,0.03,0.05] [--laps 2]``.
"""

from __future__ import annotations

import argparse

import numpy as np

from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.ros.sim_config import SimNodeConfig
from rkmpc.ros.sim_plant import PhysicsPlant
from rkmpc.sim.build import build_controller
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.scenario import Scenario, load_scenario

#: The physics step of ``rkmpc sim-node`` (s): its default rate's.
PHYSICS_DT = 1.0 / SimNodeConfig.physics_rate_hz


def drive_delayed(
    scenario: Scenario, controller: str, model: object, delay: float, laps: int
) -> tuple[str, float, float]:
    """Outcome, mean and largest |lateral error| (m) of ``laps`` laps with a ``delay`` (s) actuation delay."""
    ctrl = build_controller(controller, scenario, model)
    plant = PhysicsPlant(scenario.make_plant(0), physics_dt=PHYSICS_DT, actuation_delay=delay)
    result = simulate(plant, ctrl, scenario.track, scenario.reference, SimConfig(dt=scenario.dt, laps=laps))
    lateral = np.abs(result.log["lateral_error"])
    return result.outcome, float(lateral.mean()), float(lateral.max())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--track", default="builtin")
    parser.add_argument("--controllers", default="lmpc")
    parser.add_argument("--sensors", default="ideal,no-steer,f1tenth-real")
    parser.add_argument("--delays", default="0,0.01,0.02,0.03,0.05")
    parser.add_argument("--laps", type=int, default=2)
    args = parser.parse_args(argv)
    delays = [float(d) for d in args.delays.split(",")]
    print("| sensors | controller | " + " | ".join(f"{d * 1000:g} ms" for d in delays) + " |")
    print("|---|---|" + "---|" * len(delays))
    for sensors in args.sensors.split(","):
        car = load_scenario("builtin").car.with_sensors(sensors)
        scenario = Scenario.from_car(car, args.track)
        controllers = args.controllers.split(",")
        models, _ = learn_models(scenario, ModelPlan(controllers=controllers))
        for controller in controllers:
            cells = []
            for delay in delays:
                outcome, mean, largest = drive_delayed(
                    scenario, controller, models.get(controller), delay, args.laps
                )
                mark = "" if outcome == "completed" else f" ({outcome})"
                cells.append(f"{mean:.4f} / {largest:.3f}{mark}")
            print(f"| {sensors} | {controller} | " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
