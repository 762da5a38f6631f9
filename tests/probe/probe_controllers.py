"""Probe cases: controllers on a car (bad observations, a car far away, why a solver failed)."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from probe_cases import CORRECT, GRACEFUL, Evidence, Probe, case, controller, observations, scenario

GROUP = "controllers on a car"
#: Every controller the CLI drives without acados.
ALL = ("pp", "lmpc", "lmpc-id", "kmpc", "rkmpc", "rkmpc-paper", "nmpc", "nmpc-dynamic")
#: Observations answered before the bad one.
K = 3
GUARD_TEST = "tests/control/test_step_guard.py"


@functools.cache
def _clean(name: str) -> tuple[Any, ...]:
    """The commands of ``name`` on the observations, with nothing refused."""
    ctrl = controller(name)
    return tuple(ctrl.step(o) for o in observations())


def _refused(names: tuple[str, ...], make_bad: Callable[[Any], Any], status: str) -> Evidence:
    """Each controller stops (wheel held) on the bad observation, counts it, and recovers."""
    from rkmpc.control import Command

    obs = observations()
    messages = []
    for name in names:
        ctrl = controller(name)
        got = [ctrl.step(o) for o in obs[:K]]
        stop = ctrl.step(make_bad(obs[K]))
        assert ctrl.info.status == status, (name, ctrl.info.status, ctrl.info.message)
        assert stop == Command(0.0, got[-1].steer), (name, stop)
        messages.append(ctrl.info.message)
        got += [ctrl.step(o) for o in obs[K:]]
        assert tuple(got) == _clean(name), f"{name} did not recover after the refused step"
        assert ctrl.status_counts[status] == 1, (name, dict(ctrl.status_counts))
    assert all(messages), messages
    return Evidence(GRACEFUL, f"{len(names)} controllers: stop, '{status}' counted, recovered; {messages[0]}")


@case(
    "ctrl.nan_position",
    GROUP,
    "an observation with a NaN position, on every controller",
    GRACEFUL,
    see_also=(GUARD_TEST,),
)
def nan_position(_: Probe) -> Evidence:
    return _refused(ALL, lambda o: replace(o, x=math.nan), "invalid_input")


@case("ctrl.nan_yaw", GROUP, "an observation with a NaN yaw, on every controller", GRACEFUL)
def nan_yaw(_: Probe) -> Evidence:
    return _refused(ALL, lambda o: replace(o, yaw=math.nan), "invalid_input")


@case(
    "ctrl.pp_nonfinite",
    GROUP,
    "pure pursuit given a NaN yaw, a NaN speed, an infinite x: no NaN steer with status ok",
    GRACEFUL,
)
def pp_nonfinite(_: Probe) -> Evidence:
    bad = {
        "yaw": lambda o: replace(o, yaw=math.nan),
        "speed": lambda o: replace(o, speed=math.nan),
        "x": lambda o: replace(o, x=math.inf),
    }
    seen = [_refused(("pp",), make, "invalid_input").message.split("; ", 1)[1] for make in bad.values()]
    return Evidence(GRACEFUL, f"stop, 'invalid_input' each time: {' / '.join(seen)}")


@case(
    "ctrl.far_from_track",
    GROUP,
    "a car 1.4e6 m from the track, on every controller: a stop, not 'ok'",
    GRACEFUL,
)
def far_from_track(_: Probe) -> Evidence:
    return _refused(ALL, lambda o: replace(o, x=o.x + 1.4e6), "inadmissible")


@case(
    "ctrl.solver_reasons",
    GROUP,
    "a solver's failure says why (iteration limit, infeasible, numerical), counted per reason",
    CORRECT,
)
def solver_reasons(_: Probe) -> Evidence:
    import numpy as np

    from rkmpc.analysis.metrics import lap_metrics
    from rkmpc.control.base import STATUSES
    from rkmpc.control.nonlinear.nmpc import NMPCConfig
    from rkmpc.control.qp import QPResult
    from rkmpc.control.settings import ControllerSettings
    from rkmpc.sim.closed_loop import SimConfig, simulate
    from rkmpc.vehicle.registry import make_plant

    for reason in ("infeasible", "iteration_limit", "numerical", "invalid_input", "inadmissible", "guard"):
        assert reason in STATUSES, reason
    x = np.zeros(2)
    assert QPResult(x, False, "primal infeasible", 3).reason == "infeasible"
    assert QPResult(x, False, "maximum iterations reached", 3).reason == "iteration_limit"
    assert QPResult(np.full(2, np.nan), True, "optimal", 3).reason == "numerical"
    ctrl = controller("nmpc", settings=ControllerSettings(nmpc=NMPCConfig(max_iterations=1)))
    obs = observations()[0]
    ctrl.step(replace(obs, yaw=obs.yaw + 0.5))
    assert ctrl.info.status == "iteration_limit", ctrl.info.status
    assert ctrl.status_counts == {"iteration_limit": 1}
    message = ctrl.info.message
    sc = scenario()
    pp = controller("pp")
    metrics = lap_metrics(
        simulate(make_plant("f1tenth"), pp, sc.track, sc.reference, SimConfig(max_time=0.2))
    )
    assert metrics.status_counts == {"ok": metrics.steps}  # the counts reach the metrics
    return Evidence(CORRECT, f"nmpc: iteration_limit ({message}); QP reasons mapped; counts in metrics")
