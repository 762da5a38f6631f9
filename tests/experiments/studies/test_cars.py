"""The cars study: configuration, jobs on zoo cars, targets, tables and the plot."""

from __future__ import annotations

import io
import json

import pytest

from rkmpc.analysis.statistics import stats
from rkmpc.analysis.study_plots import plot_cars_study
from rkmpc.config.loader import load_preset
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.studies.cars import CarsStudy, CarsStudyConfig, CarTargets, targets_table
from rkmpc.experiments.studies.tracks import TracksStudyConfig
from rkmpc.experiments.study import Parallel, run_study
from rkmpc.sim.scenario import load_scenario
from rkmpc.vehicle.plants.composed import ComposedPlant
from rkmpc.vehicle.plants.dynamic import DynamicPlant


def test_a_scenario_drives_its_zoo_car_and_records_it() -> None:
    scenario = load_scenario("oval", car="gym")
    assert isinstance(scenario.make_plant(), ComposedPlant)
    assert scenario.vehicle.wheelbase == pytest.approx(0.307)  # the controllers keep the nominal car
    assert scenario.describe()["car"]["name"] == "gym"
    assert isinstance(load_scenario("oval").make_plant(), DynamicPlant)
    with pytest.raises(ValueError, match="zoo cars are 1:10 cars: car 'gym' needs the f1tenth plant"):
        load_scenario("oval", vehicle="fullsize", car="gym")


def test_config_validates() -> None:
    tracks = TracksStudyConfig(tracks=("oval",), controllers=("pp", "lmpc"))
    assert CarsStudyConfig(cars="gym,overshoot", tracks=tracks).cars == ("gym", "overshoot")
    with pytest.raises(ParameterError, match=r"CarsStudyConfig\.cars: unknown zoo car 'tank'"):
        CarsStudyConfig(cars=("gym", "tank"), tracks=tracks)
    with pytest.raises(ParameterError, match="1:10 cars"):
        CarsStudyConfig(
            cars=("gym",), tracks=TracksStudyConfig(tracks=("oval",), car=load_preset("fullsize"))
        )
    with pytest.raises(ParameterError, match="TracksStudyConfig"):
        CarsStudyConfig(cars=("gym",), tracks="oval")  # type: ignore[arg-type]
    job = CarsStudyConfig(cars=("gym",), tracks=tracks).job_config("gym", "oval", 0)
    assert job.car.plant.car == "gym" and job.controllers == ("pp", "lmpc")
    assert job.car == load_preset("f1tenth").with_zoo_car("gym")
    # Each job drives its own zoo car, whatever car the tracks' settings drive.
    on_gym = TracksStudyConfig(tracks=("oval",), car=load_preset("f1tenth").with_zoo_car("gym"))
    job = CarsStudyConfig(cars=("overshoot",), tracks=on_gym).job_config("overshoot", "oval", 3)
    assert job.car.plant.car == "overshoot" and job.seed == 3
    study = CarsStudy(CarsStudyConfig(cars=("gym", "overshoot"), tracks=tracks))
    assert [j.name for j in study.jobs()] == ["gym oval seed 0", "overshoot oval seed 0"]


def test_targets_are_judged_against_their_limits() -> None:
    good = CarTargets("gym", "oval", 0, -45.0, -35.0, -1.0, -5.0, True)
    assert good.missed() == []
    worse_max = CarTargets("gym", "oval", 0, -45.0, -35.0, 12.0, -5.0, True)
    assert worse_max.missed() == ["lateral_max_pct"]
    weak = CarTargets("gym", "oval", 0, -39.0, -10.0, 0.0, 0.0, True)
    assert weak.missed() == ["lateral_pct", "heading_pct"]
    off = CarTargets("gym", "oval", 0, None, None, None, None, False)
    assert len(off.missed()) == 4
    refused = CarTargets("gym", "oval", 0, None, None, None, None, False, not_learned=True)
    assert len(refused.missed()) == 4
    table = targets_table([good, worse_max, off, refused])
    assert "| gym | oval | 0 | -45% | -35% | -1% | -5% | - |" in table
    assert "| gym | oval | 0 | - | - | - | - | not completed |" in table
    assert "| gym | oval | 0 | - | - | - | - | not learned |" in table and "met on 1 of 4 runs" in table


def test_plot_has_a_bar_per_controller_and_car() -> None:
    lateral = {c: {"lmpc": stats([0.03, 0.04]), "rkmpc": stats([0.02])} for c in ("gym", "overshoot")}
    done = {c: {"lmpc": 1.0, "rkmpc": 0.5} for c in ("gym", "overshoot")}
    figure = plot_cars_study(["gym", "overshoot"], ["lmpc", "rkmpc"], lateral, done)
    left, right = figure.axes
    assert len(left.patches) == 4 and len(right.patches) == 4
    assert [p.get_height() for p in right.patches] == [1.0, 1.0, 0.5, 0.5]


def test_plot_of_a_study_where_no_lap_was_completed_says_so() -> None:
    # low-grip on Yas Marina through the real sensors: the LMPC leaves the track, rkmpc is not
    # learned; the plot used to fail on its logarithmic axis with nothing to put on it.
    lateral = {"low-grip": {"lmpc": stats([]), "rkmpc": stats([])}}
    done = {"low-grip": {"lmpc": 0.0, "rkmpc": 0.0}}
    figure = plot_cars_study(["low-grip"], ["lmpc", "rkmpc"], lateral, done)
    left, _ = figure.axes
    assert left.get_yscale() == "linear" and [t.get_text() for t in left.texts] == ["no completed lap"]
    figure.savefig(io.BytesIO(), format="png")


@pytest.mark.slow
def test_study_cars_drives_each_car() -> None:
    tracks = TracksStudyConfig(tracks=("oval",), controllers=("pp", "lmpc"))
    study = CarsStudy(CarsStudyConfig(cars=("gym", "light-short"), tracks=tracks))
    result = run_study(study, parallel=Parallel(n_jobs=2))
    data = result.to_json()
    json.dumps(data, allow_nan=False)
    assert [j["car"] for j in data["jobs"]] == ["gym", "light-short"]
    assert all(j["ok"] for j in data["jobs"]), [j["error"] for j in data["jobs"]]
    assert data["cars_described"]["gym"]["steering"]["type"] == "DelayedRateServo"
    # The two cars differ, so the same controller tracks them differently.
    lat = [j["controllers"]["lmpc"]["lateral_error_mean_m"] for j in data["jobs"]]
    assert lat[0] != lat[1]
    md = result.to_markdown()
    assert "### gym: F1TENTH gym car" in md and "### light-short" in md


def test_plot_survives_a_mean_rounded_outside_its_range() -> None:
    from rkmpc.analysis.statistics import Stats

    odd = Stats(n=3, mean=0.1 + 1e-15, std=0.0, min=0.1, max=0.1)
    figure = plot_cars_study(["gym"], ["lmpc"], {"gym": {"lmpc": odd}}, {"gym": {"lmpc": 1.0}})
    assert len(figure.axes[0].patches) == 1
