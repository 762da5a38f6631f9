"""A car its controller stopped, standing still: the run ends as ``stopped`` and says why (issue 27:
the README's race example spun at 8.5 s and was reported as a ``timeout`` after 1,337 stops)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rkmpc.config.loader import load_car_config
from rkmpc.sim.closed_loop import OUTCOMES, STOPPED_S
from rkmpc.sim.run import RunSpec, drive
from rkmpc.sim.scenario import Scenario

RACE = Path(__file__).resolve().parents[2] / "configs" / "f1tenth-race.toml"


def test_a_car_that_spins_and_stops_is_stopped_not_timed_out():
    scenario = Scenario.from_car(load_car_config(RACE), "builtin")  # beyond the LMPC's pace (docs/pace.md)
    result = drive(scenario, RunSpec("lmpc"))
    assert "stopped" in OUTCOMES and result.outcome == "stopped"
    assert result.failure is not None and "inadmissible, heading error" in result.failure
    assert result.log.metadata["failure"] == result.failure
    statuses = result.log["status"][-round(STOPPED_S / scenario.dt) :]
    assert len(set(statuses.tolist())) == 1  # the last 2 s: one refusal after the other
    t_end = float(result.log["t"][-1])
    assert t_end < 20.0 and result.log["speed"][-1] == pytest.approx(0.0, abs=0.05)


README = Path(__file__).resolve().parents[2] / "README.md"


@pytest.mark.slow
def test_the_readmes_race_example_runs_as_the_readme_says(tmp_path, monkeypatch):
    """The race example of the README, as written there: a completed lap at race pace (about 30 s)."""
    import json
    import shlex

    from rkmpc.cli import main

    lines = README.read_text().splitlines()
    (line,) = [x for x in lines if x.startswith("rkmpc run") and "f1tenth-race" in x]
    argv = shlex.split(line.split("#")[0])[1:]
    monkeypatch.chdir(README.parent)
    argv[argv.index("--out") + 1] = str(tmp_path / "race")
    assert main(argv) == 0
    metrics = json.loads((tmp_path / "race" / "metrics.json").read_text())
    assert metrics["completed"] and metrics["config"]["scenario"]["speed_limits"]["max_speed"] == 5.0
    assert "22.1 s" in README.read_text() and round(metrics["lap_time_s"], 1) == 22.1
