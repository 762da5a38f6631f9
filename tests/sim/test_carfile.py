"""A car in one file (``--config car.toml``): every validation error names the file and the key."""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import pytest

from rkmpc.cli import main
from rkmpc.cli.common import car_config
from rkmpc.control.registry import make_controller
from rkmpc.core.errors import InputFileError
from rkmpc.sim.carfile import CarConfig, load_car_config
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.scenario import load_scenario

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
MONZA = Path(__file__).resolve().parents[3] / "shared" / "tracks" / "centerlines" / "Monza.csv"


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "car.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "key", "problem"),
    [
        ("[vehicel]\npreset = 'f1tenth'\n", "vehicel", "unknown key 'vehicel' (a section)"),
        ("[limits]\nlateral = 4.0\n", "limits.lateral", "unknown key 'lateral'"),
        ("[controllers.lmpc]\nhorizn = 20\n", "controllers.lmpc.horizn", "unknown key"),
        ("[controllers.mpc]\nhorizon = 20\n", "controllers.mpc", "unknown key"),
        (
            "[controllers.lmpc.speed_floor]\nfractio = 0.5\n",
            "controllers.lmpc.speed_floor.fractio",
            "unknown",
        ),
        ("[vehicle]\nname = 'mine'\n", "vehicle.name", "unknown key"),
        ("[training]\nepoch = 3\n", "training.epoch", "unknown key"),
        ("[plant]\nplant = 'gym'\n", "plant.plant", "unknown key"),
        ("limits = 3\n", "limits", "expected a section"),
        ("[limits]\nlateral_accel = 'fast'\n", "limits.lateral_accel", "expected a number"),
        ("[controllers.lmpc]\nhorizon = 2.5\n", "controllers.lmpc.horizon", "expected an integer"),
        (
            "[controllers.rkmpc.trust]\nenabled = 1\n",
            "controllers.rkmpc.trust.enabled",
            "expected true or false",
        ),
        ("[controllers.lmpc]\nsolver = 3\n", "controllers.lmpc.solver", "expected a non-empty string"),
        ("[vehicle]\nsteering = 3\n", "vehicle.steering", "expected a mapping"),
        ("[limits]\nlateral_accel = -1\n", "limits.lateral_accel", "must be finite and > 0, got -1"),
        ("[limits]\nmin_speed = 5.0\n", "limits.min_speed", "must be below max_speed"),
        ("[vehicle]\nmass = 0\n", "vehicle.mass", "mass"),
        ("[vehicle.steering]\nmax_rate = -3\n", "vehicle.steering.max_rate", "> 0"),
        ("[controllers.lmpc]\nsolver = 'gurobi'\n", "controllers.lmpc.solver", "must be one of"),
        (
            "[controllers.rkmpc-paper]\nmax_steer_correction = -1\n",
            "controllers.rkmpc-paper.max_steer_correction",
            "bounds must be > 0",
        ),
        ("[controllers.pp]\nmin_lookahead = 0\n", "controllers.pp.min_lookahead", "min_lookahead"),
        ("[training]\nepochs = 0\n", "training.epochs", "integer >= 1"),
        ("[training]\nkmpc_samples = 10\n", "training.kmpc_samples", "integer >= 1000"),
        (
            "[vehicle]\npreset = 'kart'\n",
            "vehicle.preset",
            "unknown preset 'kart'; known: ['f1tenth', 'fullsize']",
        ),
        ("[vehicle]\npreset = 1\n", "vehicle.preset", "expected a non-empty string"),
        ("[plant]\ncar = 'tank'\n", "plant.car", "unknown car 'tank'"),
        ("[vehicle]\npreset = 'fullsize'\n[plant]\ncar = 'gym'\n", "plant.car", "needs preset 'f1tenth'"),
    ],
)
def test_every_validation_error_names_the_file_and_the_key(tmp_path, text, key, problem):
    path = _write(tmp_path, text)
    with pytest.raises(InputFileError) as info:
        load_car_config(path)
    message = str(info.value)
    assert message.startswith(f"{path} [{key}]: "), message
    assert problem in message
    assert info.value.field == key


def test_a_toml_syntax_error_names_the_file_and_the_line(tmp_path):
    path = _write(tmp_path, "[vehicle]\npreset = 'f1tenth'\n[limits\nmax_speed = 5\n")
    with pytest.raises(InputFileError, match=r"car\.toml: not a valid TOML file: .*line 3"):
        load_car_config(path)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(InputFileError, match=r"nope\.toml: file not found"):
        load_car_config(tmp_path / "nope.toml")


def test_the_cli_reports_a_bad_file_with_its_key(tmp_path, capsys):
    path = _write(tmp_path, "[limits]\nlateral_accel = -1\n")
    assert main(["run", "--controller", "pp", "--config", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{path} [limits.lateral_accel]: SpeedLimits.lateral_accel must be finite and > 0, got -1" in err
    assert not (tmp_path / "o").exists()


def test_a_section_overrides_only_the_keys_it_names(tmp_path):
    path = _write(tmp_path, "[vehicle]\npreset = 'fullsize'\n[controllers.lmpc]\nhorizon = 20\n")
    config = load_car_config(path)
    preset = CarConfig.from_preset("fullsize")
    assert config.controllers.lmpc == replace(preset.controllers.lmpc, horizon=20)
    assert config.limits == preset.limits and config.vehicle == preset.vehicle
    options = config.vehicle_preset().options_for("rkmpc")
    assert options["lmpc_config"].horizon == 20  # the rkmpc's baseline is the file's LMPC


def _args(**given: object) -> argparse.Namespace:
    names = (
        "config",
        "vehicle",
        "seed",
        "epochs",
        "data_laps",
        "kmpc_samples",
        "car",
        "lateral_accel",
        "max_speed",
    )
    return argparse.Namespace(**{name: given.get(name) for name in names})


def test_flags_win_over_the_file_and_the_file_over_the_preset(tmp_path):
    path = _write(tmp_path, "[training]\nseed = 4\nepochs = 7\n[limits]\nmax_speed = 3.0\n")
    config = car_config(_args(config=path, seed=9, car="gym"))
    assert (config.training.seed, config.training.epochs, config.car) == (9, 7, "gym")
    assert config.limits.max_speed == 3.0
    assert car_config(_args()).training == CarConfig.from_preset("f1tenth").training
    assert car_config(_args(vehicle="fullsize")).preset == "fullsize"
    with pytest.raises(ValueError, match="--vehicle fullsize contradicts"):
        car_config(_args(config=path, vehicle="fullsize"))


def test_the_pace_flags_give_the_race_pace_file():
    race = load_car_config(CONFIGS / "f1tenth-race.toml")
    fast = car_config(_args(config=CONFIGS / "f1tenth.toml", lateral_accel=6.0, max_speed=5.0))
    assert fast.limits == race.limits
    assert replace(fast, limits=race.limits, source=None, sha256=None) == replace(
        race, source=None, sha256=None
    )


def _metrics(out: Path) -> dict[str, object]:
    data = json.loads((out / "metrics.json").read_text())
    return {k: v for k, v in data.items() if not k.startswith("solve_ms") and k not in ("config", "training")}


def test_the_f1tenth_file_drives_as_the_preset_and_is_recorded(tmp_path):
    plain, filed = tmp_path / "plain", tmp_path / "filed"
    assert main(["run", "--controller", "lmpc", "--out", str(plain)]) == 0
    config = CONFIGS / "f1tenth.toml"
    assert main(["run", "--controller", "lmpc", "--config", str(config), "--out", str(filed)]) == 0
    assert _metrics(filed) == _metrics(plain)
    recorded = json.loads((filed / "metrics.json").read_text())["config"]["car_config"]
    assert recorded["file"] == str(config) and len(recorded["sha256"]) == 64
    assert recorded["limits"]["max_speed"] == 3.5
    assert recorded["controllers"]["lmpc"]["horizon"] == 30
    preset = json.loads((plain / "metrics.json").read_text())["config"]["car_config"]
    assert preset["file"] is None and preset["limits"] == recorded["limits"]


def test_the_race_pace_file_runs_and_sets_the_pace(tmp_path):
    out = tmp_path / "race"
    config = CONFIGS / "f1tenth-race.toml"
    assert main(["run", "--controller", "pp", "--config", str(config), "--seed", "2", "--out", str(out)]) == 0
    recorded = json.loads((out / "metrics.json").read_text())["config"]
    assert recorded["scenario"]["speed_limits"]["max_speed"] == 5.0
    assert recorded["car_config"]["training"]["seed"] == 2  # the flag's, not the file's


@pytest.mark.skipif(not MONZA.is_file(), reason="the shared tracks are not here")
def test_the_fullsize_file_drives_on_a_full_scale_track():
    config = load_car_config(CONFIGS / "fullsize.toml")
    scenario = load_scenario(MONZA, scale=1.0, vehicle=config.preset, preset=config.vehicle_preset())
    assert scenario.limits == config.limits
    for name in ("pp", "lmpc"):
        controller = make_controller(name, scenario.reference, scenario.vehicle, **scenario.options_for(name))
        result = simulate(
            scenario.make_plant(),
            controller,
            scenario.track,
            scenario.reference,
            SimConfig(dt=scenario.dt, max_time=4.0),
        )
        assert result.outcome == "timeout", (name, result.outcome, result.failure)  # on track at the end
        progress = result.log["s"] if "s" in result.log.columns else result.log["x"]
        assert abs(progress[-1] - progress[0]) > 30.0  # m: it drove
