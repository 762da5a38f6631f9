"""Issue 27's probe: silently wrong results (a pace beyond the car, environment settings taken as
something else, a model driving another car, a spin called a timeout, training on laps that fell short)."""

from __future__ import annotations

import json
from pathlib import Path

from probe_cases import (
    CLEAR_ERROR,
    CORRECT,
    GRACEFUL,
    Evidence,
    Probe,
    case,
    caught_warnings,
    cli_error,
    identified_model,
    raises,
    warned,
)

GROUP = "silent (issue 27)"
CONFIGS = Path(__file__).resolve().parents[2] / "configs"
README = Path(__file__).resolve().parents[2] / "README.md"


@case(
    "silent.max_speed_beyond_drive",
    GROUP,
    "--max-speed 20 on a car whose drive tops out at 8 m/s: refused naming both",
    CLEAR_ERROR,
    problem="silent",
)
def max_speed_beyond_drive(probe: Probe) -> Evidence:
    args = ["run", "--controller", "lmpc", "--max-speed", "20", "--out", str(probe.path("o"))]
    return cli_error(probe, args, "--max-speed: 20 m/s", "[vehicle.drive] max_speed: 8 m/s")


@case(
    "silent.drive_slower_than_pace",
    GROUP,
    "[vehicle.drive] max_speed = 0.5 below the speed limits (off track at 25 %): refused naming both",
    CLEAR_ERROR,
    problem="silent",
)
def drive_slower_than_pace(probe: Probe) -> Evidence:
    car = probe.path("slow.toml")
    car.write_text('[vehicle]\npreset = "f1tenth"\n\n[vehicle.drive]\nmax_speed = 0.5\n')
    args = ["run", "--controller", "lmpc", "--config", str(car), "--out", str(probe.path("o"))]
    return cli_error(probe, args, "slow.toml", "3.5 m/s", "[vehicle.drive] max_speed: 0.5 m/s")


@case(
    "silent.lateral_beyond_grip",
    GROUP,
    "--lateral-accel 30 beyond the tyres' grip: warned, naming the grip (the study ladder may go there)",
    GRACEFUL,
    problem="silent",
)
def lateral_beyond_grip(probe: Probe) -> Evidence:
    from rkmpc.cli.common import PaceWarning

    args = [
        "run",
        "--controller",
        "pp",
        "--track",
        "oval",
        "--lateral-accel",
        "30",
        "--out",
        str(probe.path("o")),
    ]
    with caught_warnings() as seen:
        run = probe.cli(*args)
    assert run.code == 0, run.err[-500:]
    return Evidence(GRACEFUL, warned(seen, PaceWarning, "30 m/s^2", "grip, about 11.2 m/s^2"))


@case(
    "silent.env_random_start_string",
    GROUP,
    'F1TenthEnvConfig(random_start="no") (taken as true): refused, a bool is needed',
    CLEAR_ERROR,
    problem="silent",
)
def env_random_start_string(_: Probe) -> Evidence:
    from rkmpc.envs.f1tenth import F1TenthEnvConfig

    return raises(lambda: F1TenthEnvConfig(random_start="no"), "random_start")  # type: ignore[arg-type]


@case(
    "silent.policy_period",
    GROUP,
    "a ControllerPolicy built for 0.01 s steps driving an environment of 0.05 s steps: refused",
    CLEAR_ERROR,
    problem="silent",
)
def policy_period(_: Probe) -> Evidence:
    from probe_cases import controller, scenario

    from rkmpc.envs.adapter import ControllerPolicy, run_episode
    from rkmpc.envs.f1tenth import F1TenthEnvConfig, F1TenthTrackEnv

    env = F1TenthTrackEnv(scenario(), F1TenthEnvConfig(timestep=0.05))
    policy = ControllerPolicy(controller("lmpc"), 0.01)  # each command held 5 steps of 0.05 s
    return raises(lambda: run_episode(env, policy, seed=0, max_steps=20), "0.01", "0.05")


@case(
    "silent.model_of_another_zoo_car",
    GROUP,
    "a model learned on the f1tenth plant driving the zoo's gym car: refused, naming the plant",
    CLEAR_ERROR,
    problem="silent",
)
def model_of_another_zoo_car(probe: Probe) -> Evidence:
    from rkmpc.config.loader import load_preset
    from rkmpc.sim.build import check_model
    from rkmpc.sim.scenario import Scenario

    gym = Scenario.from_car(load_preset("f1tenth").with_zoo_car("gym"), "builtin")
    model = identified_model(probe)  # identified from laps of the f1tenth plant, as `rkmpc train` makes it
    return raises(
        lambda: check_model(model, gym, source="lmpc-id.json"), "plant = 'f1tenth'", "plant = 'gym'"
    )


@case(
    "silent.spin_then_stop",
    GROUP,
    "the README's race file with the LMPC: the car spins and stops; said 'stopped' with why, not 'timeout'",
    GRACEFUL,
    problem="silent",
)
def spin_then_stop(probe: Probe) -> Evidence:
    out = probe.path("race")
    run = probe.cli(
        "run", "--controller", "lmpc", "--config", str(CONFIGS / "f1tenth-race.toml"), "--out", str(out)
    )
    assert run.code == 0, run.err[-500:]
    text = " ".join(run.err.split())
    assert "lmpc: stopped" in text and "timeout" not in text, text[:500]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["outcome"] == "stopped" and "inadmissible" in metrics["failure"]
    line = next(line for line in run.err.splitlines() if "lmpc: stopped" in line)
    return Evidence(GRACEFUL, f"{line.strip()} {metrics['failure']}")


@case(
    "silent.readme_race_example",
    GROUP,
    "the README's race example runs as the README says (a completed lap at race pace)",
    CORRECT,
    slow=True,
    problem="silent",
    see_also=("tests/sim/test_stopped.py::test_the_readmes_race_example_runs_as_the_readme_says",),
)
def readme_race_example(probe: Probe) -> Evidence:
    import shlex

    lines = README.read_text().splitlines()
    (line,) = [x for x in lines if x.startswith("rkmpc run") and "f1tenth-race" in x]
    argv = shlex.split(line.split("#")[0])[1:]
    argv[argv.index("--config") + 1] = str(README.parent / argv[argv.index("--config") + 1])
    argv[argv.index("--out") + 1] = str(probe.path("race"))
    run = probe.cli(*argv)
    assert run.code == 0, run.err[-500:]
    metrics = json.loads((probe.path("race") / "metrics.json").read_text())
    assert metrics["completed"], metrics["outcome"]
    return Evidence(CORRECT, f"{line.split('#')[0].strip()}: completed, lap {metrics['lap_time_s']:.2f} s")


@case(
    "silent.short_lmpc_data",
    GROUP,
    "a learned controller trained on LMPC laps that left the track: said on the terminal",
    GRACEFUL,
    problem="silent",
)
def short_lmpc_data(probe: Probe) -> Evidence:
    from rkmpc.config.loader import load_car_config
    from rkmpc.experiments.models import ModelPlan, learn_models
    from rkmpc.sim.scenario import Scenario

    race = Scenario.from_car(load_car_config(CONFIGS / "f1tenth-race.toml"), "builtin")
    said: list[str] = []
    _, record = learn_models(race, ModelPlan(controllers=("lmpc-id",), use_cache=False), say=said.append)
    warnings = [
        line for line in said if line.startswith("warning: the lmpc laps of the data did not complete")
    ]
    assert record.data is not None and record.data.outcome != "completed" and len(warnings) == 1, said
    # rkmpc train on such data says it too
    from rkmpc.sim.collect import collect

    short = collect(race, laps=2)
    short.save(probe.path("short.npz"))
    run = probe.cli(
        "train",
        "--data",
        str(probe.path("short.npz")),
        "--kind",
        "identified",
        "--out",
        str(probe.path("id.json")),
    )
    assert run.code == 0 and "warning: the lmpc laps of the data did not complete" in run.out, run.out
    return Evidence(GRACEFUL, warnings[0])
