"""The LMPC linearised about its own previous plan instead of the reference: an experiment.

The LMPC (:class:`rkmpc.control.linear.lmpc.LinearMPC`) linearises the kinematic bicycle along
the reference: heading, speed and wheel angle of the path. Where the car is off the path, or the
path asks for more than the car can do, that is not where the car will be. The usual remedy of
linear time-varying MPC (the real-time iteration of nonlinear MPC) linearises instead about the
previous step's plan, shifted by one step and rolled out from the measured pose with the same
forward-Euler model. The condensed prediction then has an affine part, ``X = Phi xi0 + Gamma dU +
c``, carried here as one more column of ``Phi`` (and a 1 appended to ``xi0``), so the LMPC's QP is
otherwise unchanged: same weights, bounds, solver and deviation variables. With no previous plan
(the first step, or after a failed solve) it linearises along the reference as the LMPC does.

Only the LMPC is changed: ``lmpc-id``, ``kmpc`` and the residual MPCs on top keep the reference
linearisation (their prediction has no affine part). Ideal sensors, the ``f1tenth`` preset's
car and settings, seed 0, one lap.

Run: ``python benchmarks/plan_linearisation.py builtin ../shared/tracks/centerlines/*.csv``.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from steering_limit import FRACTION, WINDOW, near, places_near_limit

from rkmpc.control.linear.lmpc import LinearMPC
from rkmpc.core.observation import Observation
from rkmpc.sim.build import build_controller
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.run import RunSpec, build_plant
from rkmpc.sim.scenario import Scenario, load_scenario
from rkmpc.track.reference import ReferenceHorizon
from rkmpc.vehicle.kinematic import kinematic_rhs, linearize_discrete


class PlanLinearisedLMPC(LinearMPC):
    """The LMPC, linearised about its previous plan (shifted one step) with the affine term."""

    name = "lmpc-plan"

    def _prediction(
        self, observation: Observation, ref: ReferenceHorizon, u_ref: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        xi0, Phi, Gamma = super()._prediction(observation, ref, u_ref)
        if self.last_plan is None:
            return xi0, Phi, Gamma
        n, T, L = self.config.horizon, self.config.dt, self.vehicle.wheelbase
        u_bar = np.vstack([self.last_plan[1:], self.last_plan[-1:]])
        # The plan rolled out from the measured pose, in the reference's continuous heading.
        x_bar = np.empty((n + 1, 3))
        x_bar[0] = [observation.x, observation.y, ref.theta[0] + xi0[2]]
        for k in range(n):
            x_bar[k + 1] = x_bar[k] + T * kinematic_rhs(x_bar[k], u_bar[k], L)
        A, B = linearize_discrete(x_bar[:n, 2], u_bar[:, 0], u_bar[:, 1], L, T)
        Phi, Gamma = self.problem.prediction_matrices(x_bar[:n, 2], u_bar[:, 0], u_bar[:, 1])
        x_ref = np.column_stack([ref.x[: n + 1], ref.y[: n + 1], ref.theta[: n + 1]])
        # xi(k+1) = A_k xi(k) + B_k dU_k + c_k, with c_k the linearisation's offset from the reference.
        offset = np.zeros(3)
        affine = np.empty((n, 3))
        for k in range(n):
            c = (x_bar[k + 1] - x_ref[k + 1]) - A[k] @ (x_bar[k] - x_ref[k]) - B[k] @ (u_bar[k] - u_ref[k])
            offset = A[k] @ offset + c
            affine[k] = offset
        return np.append(xi0, 1.0), np.column_stack([Phi, affine.reshape(-1)]), Gamma


def lap(scenario: Scenario, controller: LinearMPC) -> tuple[str, np.ndarray, np.ndarray, float]:
    """Outcome, arc length (m) and |lateral error| (m) of every step, and the mean |heading error| (rad)."""
    plant = build_plant(scenario, RunSpec(controller="lmpc"))
    result = simulate(
        plant, controller, scenario.track, scenario.reference, SimConfig(dt=scenario.dt, laps=1)
    )
    log = result.log
    return (
        result.outcome,
        log["s"],
        np.abs(log["lateral_error"]),
        float(np.mean(np.abs(log["heading_error"]))),
    )


def row(track: str) -> str:
    """One Markdown row: the LMPC and the plan-linearised LMPC on ``track``."""
    scenario = load_scenario(track)
    lmpc = build_controller("lmpc", scenario)
    if not isinstance(lmpc, LinearMPC):
        raise TypeError(f"{track}: the f1tenth preset's lmpc is not a LinearMPC")
    plan = PlanLinearisedLMPC(scenario.reference, scenario.vehicle, lmpc.config)
    hot = places_near_limit(scenario)
    cells = []
    for controller in (lmpc, plan):
        outcome, along, error, heading = lap(scenario, controller)
        close = near(along, hot, scenario.reference.path.length)
        near_mean = f"{error[close].mean():.4f}" if close.any() else "-"
        cells.append((outcome, error.mean(), error.max(), heading, near_mean, error[~close].mean()))
    (o1, m1, x1, h1, n1, a1), (o2, m2, x2, h2, n2, a2) = cells
    return (
        f"| {scenario.track.name} | {o1} / {o2} | {m1:.4f} / {m2:.4f} ({m2 / m1 - 1:+.0%}) "
        f"| {x1:.3f} / {x2:.3f} ({x2 / x1 - 1:+.0%}) | {h1:.4f} / {h2:.4f} ({h2 / h1 - 1:+.0%}) "
        f"| {n1} / {n2} | {a1:.4f} / {a2:.4f} |"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("tracks", nargs="+", help="built-in track names or centre-line CSV files")
    args = parser.parse_args(argv)
    sys.stdout.write(
        "LMPC / plan-linearised LMPC, ideal sensors, one lap; near: within "
        f"{WINDOW:g} m of path beyond {FRACTION:g} of the steering limit\n\n"
        "| track | outcome | lateral mean (m) | lateral max (m) | heading mean (rad) | near (m) "
        "| away (m) |\n"
        "|---|---|---|---|---|---|---|\n"
    )
    for track in args.tracks:
        sys.stdout.write(row(track) + "\n")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
