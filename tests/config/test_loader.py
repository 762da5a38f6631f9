"""The one loader of car files (``--config car.toml``): every validation error names the file and the key."""

from __future__ import annotations

import argparse
import json
import os
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rkmpc.cli import main
from rkmpc.cli.common import car_config
from rkmpc.config.loader import MAX_FILE_BYTES, load_car_config, load_preset
from rkmpc.control.nonlinear.settings import NMPCConfig
from rkmpc.control.registry import make_controller
from rkmpc.core.errors import InputFileError
from rkmpc.sim.build import build_controller
from rkmpc.sim.closed_loop import SimConfig, simulate
from rkmpc.sim.scenario import Scenario

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
MONZA = Path(__file__).resolve().parents[3] / "shared" / "tracks" / "centerlines" / "Monza.csv"


def _write(tmp_path: Path, text: str, name: str = "car.toml") -> Path:
    path = tmp_path / name
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
            "unknown car preset 'kart'; known: f1tenth, fullsize",
        ),
        ("[vehicle]\npreset = 1\n", "vehicle.preset", "expected a non-empty string"),
        ("[plant]\ncar = 'tank'\n", "plant.car", "unknown zoo car 'tank'"),
        (
            "[vehicle]\npreset = 'fullsize'\n[plant]\ncar = 'gym'\n",
            "plant.car",
            "zoo cars are 1:10 cars: car 'gym' needs the f1tenth plant",
        ),
        ("[plant]\nmodel = 'tank'\n", "plant.model", "unknown plant 'tank'"),
        # Only a packaged preset names its parameter set; a user's file names the preset.
        ("[vehicle]\nparams = 'f1tenth'\n", "vehicle.params", "only a packaged preset sets params"),
        ("[vehicle]\nfile_scale = 0\n", "vehicle.file_scale", "file_scale must be finite and > 0"),
        # rkmpc-paper reads none of rkmpc's own settings: refused where they are written.
        (
            "[controllers.rkmpc-paper]\nslip_drift = true\n",
            "controllers.rkmpc-paper.slip_drift",
            "unknown key",
        ),
        (
            "[controllers.rkmpc-paper]\nlateral_accel_weight = 0.1\n",
            "controllers.rkmpc-paper.lateral_accel_weight",
            "unknown key 'lateral_accel_weight'",
        ),
        (
            "[controllers.rkmpc-paper.trust]\nenabled = true\n",
            "controllers.rkmpc-paper.trust",
            "unknown key 'trust'",
        ),
        ("[controllers.rkmpc]\nslip_drift = 1\n", "controllers.rkmpc.slip_drift", "expected true or false"),
        ("[controllers.nmpc]\nhorizn = 3\n", "controllers.nmpc.horizn", "unknown key"),
        ("[controllers.nmpc]\nhorizon = 0\n", "controllers.nmpc.horizon", "NMPCConfig.horizon"),
        ("[ros]\nrate_hz = -1\n", "ros.rate_hz", "rate_hz must be finite and > 0"),
        ("[ros]\ntrigger = 'never'\n", "ros.trigger", "trigger must be one of ['timer', 'odometry']"),
        ("[ros.topics]\nodom = 'x'\n", "ros.topics.odom", "unknown key 'odom'"),
        ("[ros.safety]\nodometry_timeout = 'x'\n", "ros.safety.odometry_timeout", "expected a number"),
        ("[ros.record]\nstorage = 'zip'\n", "ros.record.storage", "storage must be one of"),
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


# ---------------------------------------------------------------------------- what is read


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_fifo_is_refused_without_reading_it(tmp_path):
    fifo = tmp_path / "car.toml"
    os.mkfifo(fifo)  # reading it would block until a writer comes
    with pytest.raises(InputFileError, match="not a regular file") as info:
        load_car_config(fifo)
    assert str(info.value).startswith(f"{fifo}: ")


def test_a_folder_is_refused_naming_it(tmp_path):
    folder = tmp_path / "car.toml"
    folder.mkdir()
    with pytest.raises(InputFileError, match="not a regular file") as info:
        load_car_config(folder)
    assert str(info.value).startswith(f"{folder}: ")


def test_a_file_over_one_mebibyte_is_refused_naming_it(tmp_path):
    assert MAX_FILE_BYTES == 1 << 20
    big = _write(tmp_path, "# padding\n" + "#" * MAX_FILE_BYTES + "\n[limits]\nmax_speed = 3.0\n")
    with pytest.raises(
        InputFileError, match=rf"{big.stat().st_size} bytes; a settings file is at most"
    ) as info:
        load_car_config(big)
    assert str(info.value).startswith(f"{big}: ")
    exactly = _write(tmp_path, "#" * (MAX_FILE_BYTES - 1) + "\n", name="full.toml")
    assert exactly.stat().st_size == MAX_FILE_BYTES
    assert load_car_config(exactly).limits == load_preset("f1tenth").limits  # the limit itself is read


def test_a_file_that_is_not_utf8_is_named(tmp_path):
    path = tmp_path / "car.toml"
    path.write_bytes(b"[limits]\nmax_speed = 3.0 # \xff\xfe\n")
    with pytest.raises(InputFileError, match=r"car\.toml: not UTF-8 text"):
        load_car_config(path)


# ---------------------------------------------------------------------------- sections


def test_a_section_overrides_only_the_keys_it_names(tmp_path):
    path = _write(tmp_path, "[vehicle]\npreset = 'fullsize'\n[controllers.lmpc]\nhorizon = 20\n")
    config = load_car_config(path)
    preset = load_preset("fullsize")
    assert config.controllers.lmpc == replace(preset.controllers.lmpc, horizon=20)
    assert config.limits == preset.limits and config.vehicle == preset.vehicle
    assert config.controllers.rkmpc == preset.controllers.rkmpc
    assert config.plant == preset.plant and config.file_scale == preset.file_scale == 1.0
    # The rkmpc's baseline is the file's LMPC.
    with pytest.warns(UserWarning, match="made at 1:10"):
        scenario = Scenario.from_car(config, "builtin")
    identity = SimpleNamespace(
        A_=np.eye(5), B_=np.zeros((5, 2)), C_=np.zeros((2, 5)), D_=np.eye(2), lift=lambda x: np.asarray(x)
    )
    controller = build_controller("rkmpc", scenario, identity)
    assert controller.lmpc.config.horizon == 20
    assert controller.config == preset.controllers.rkmpc


def test_the_nmpc_section_reaches_the_nonlinear_mpcs(tmp_path):
    path = _write(tmp_path, "[controllers.nmpc]\nhorizon = 12\nmax_iterations = 40\n")
    config = load_car_config(path)
    assert config.controllers.nmpc == replace(NMPCConfig(), horizon=12, max_iterations=40)
    assert config.controllers.lmpc == load_preset("f1tenth").controllers.lmpc
    scenario = Scenario.from_car(config, "builtin")
    nmpc = build_controller("nmpc", scenario)
    assert nmpc.config.horizon == 12 and nmpc.config.max_iterations == 40
    assert config.to_json()["controllers"]["nmpc"]["horizon"] == 12


def test_the_ros_section_loads_and_a_relative_bag_is_beside_the_file(tmp_path):
    text = """
[ros]
rate_hz = 40.0
trigger = "odometry"
steering_estimate = true
[ros.topics]
odometry = "/car_state/odom"
steering = "/car_state/steer"
[ros.frames]
map = "world"
[ros.odometry]
pose = "rear_axle"
reliability = "best_effort"
[ros.latency]
compensate = true
odometry = 0.03
[ros.safety]
odometry_timeout = 0.3
max_speed = 4.0
[ros.record]
bag = "bags/run-{time}"
storage = "sqlite3"
"""
    config = load_car_config(_write(tmp_path, text))
    ros = config.ros
    assert (ros.rate_hz, ros.period, ros.trigger, ros.steering_estimate) == (40.0, 0.025, "odometry", True)
    assert (ros.topics.odometry, ros.topics.steering, ros.topics.drive) == (
        "/car_state/odom",
        "/car_state/steer",
        "/drive",  # the default, the file leaves it out
    )
    assert ros.frames.map == "world" and ros.frames.drive == "base_link"
    assert (ros.odometry.pose, ros.odometry.reliability) == ("rear_axle", "best_effort")
    assert ros.latency.compensate and ros.latency.odometry == 0.03 and ros.latency.actuation == 0.0
    assert ros.safety.odometry_timeout == 0.3 and ros.safety.max_speed == 4.0 and ros.safety.latch
    assert ros.record.bag == str(tmp_path / "bags" / "run-{time}") and ros.record.storage == "sqlite3"
    assert config.to_json()["ros"]["safety"]["odometry_timeout"] == 0.3
    # Everything else is the preset's.
    assert replace(config, ros=load_preset("f1tenth").ros, source=None, sha256=None) == load_preset("f1tenth")


def test_dotted_overrides_set_keys_over_the_file(tmp_path):
    path = _write(tmp_path, "[ros.safety]\nodometry_timeout = 0.3\n")
    config = load_car_config(path, {"ros.safety.odometry_timeout": 1.5, "limits.max_speed": 3.0})
    assert config.ros.safety.odometry_timeout == 1.5 and config.limits.max_speed == 3.0
    with pytest.raises(InputFileError) as info:
        load_car_config(path, {"ros.safety.odometry_timout": 1.0})
    assert info.value.field == "ros.safety.odometry_timout"
    assert "unknown key 'odometry_timout'" in str(info.value)


def test_a_yaml_car_file_loads_as_the_same_toml_file(tmp_path):
    pytest.importorskip("yaml")
    toml = _write(
        tmp_path,
        """
[vehicle]
preset = "f1tenth"
mass = 3.74
[vehicle.steering]
max_angle = 0.41
[limits]
lateral_accel = 5.0
max_speed = 4.0
[controllers.lmpc]
horizon = 25
[controllers.rkmpc]
max_steer_correction = 0.1
slip_drift = true
[training]
seed = 3
[ros]
rate_hz = 25.0
[ros.topics]
odometry = "/odom"
""",
    )
    yaml_text = """
vehicle:
  preset: f1tenth
  mass: 3.74
  steering:
    max_angle: 0.41
limits:
  lateral_accel: 5.0
  max_speed: 4.0
controllers:
  lmpc:
    horizon: 25
  rkmpc:
    max_steer_correction: 0.1
    slip_drift: true
training:
  seed: 3
ros:
  rate_hz: 25.0
  topics:
    odometry: /odom
"""
    for suffix in (".yaml", ".yml"):
        yaml = _write(tmp_path, yaml_text, name=f"car{suffix}")
        from_yaml, from_toml = load_car_config(yaml), load_car_config(toml)
        assert replace(from_yaml, source=None, sha256=None) == replace(from_toml, source=None, sha256=None)
        assert from_yaml.source == str(yaml.resolve())
        assert from_yaml.controllers.rkmpc.slip_drift and from_yaml.vehicle.steering.max_angle == 0.41


def test_a_bad_yaml_file_names_the_file_and_the_key(tmp_path):
    pytest.importorskip("yaml")
    path = _write(tmp_path, "limits:\n  lateral_accel: -1\n", name="car.yaml")
    with pytest.raises(InputFileError) as info:
        load_car_config(path)
    assert str(info.value).startswith(f"{path} [limits.lateral_accel]: ")
    broken = _write(tmp_path, "limits: [1, 2\n", name="broken.yaml")
    with pytest.raises(InputFileError, match=r"broken\.yaml: not a valid YAML file"):
        load_car_config(broken)
    listed = _write(tmp_path, "- 1\n- 2\n", name="list.yaml")
    with pytest.raises(InputFileError, match=r"list\.yaml: expected a mapping of sections, got list"):
        load_car_config(listed)
    empty = _write(tmp_path, "", name="empty.yaml")
    assert replace(load_car_config(empty), source=None, sha256=None) == load_preset("f1tenth")


def test_the_file_and_its_hash_are_recorded(tmp_path):
    import hashlib

    path = _write(tmp_path, "[limits]\nmax_speed = 3.0\n")
    config = load_car_config(path)
    assert config.source == str(path.resolve())
    assert config.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()
    record = config.to_json()
    assert (record["file"], record["sha256"]) == (config.source, config.sha256)
    assert load_preset("f1tenth").source is None and load_preset("f1tenth").sha256 is None


# ---------------------------------------------------------------------------- flags and files


def test_the_cli_reports_a_bad_file_with_its_key(tmp_path, capsys):
    path = _write(tmp_path, "[limits]\nlateral_accel = -1\n")
    assert main(["run", "--controller", "pp", "--config", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"{path} [limits.lateral_accel]: SpeedLimits.lateral_accel must be finite and > 0, got -1" in err
    assert not (tmp_path / "o").exists()


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
    assert (config.training.seed, config.training.epochs, config.plant.car) == (9, 7, "gym")
    assert config.limits.max_speed == 3.0
    assert car_config(_args()).training == load_preset("f1tenth").training
    assert car_config(_args()) == load_preset("f1tenth")
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


@pytest.mark.parametrize("name", ["f1tenth", "fullsize"])
def test_the_repos_car_files_are_their_presets_written_out(name):
    # configs/f1tenth.toml writes out the f1tenth preset's values; configs/fullsize.toml the full-size car's.
    config = load_car_config(CONFIGS / f"{name}.toml")
    assert replace(config, source=None, sha256=None) == load_preset(name)


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
    scenario = Scenario.from_car(config, MONZA, scale=1.0)
    assert scenario.limits == config.limits and scenario.vehicle == config.vehicle
    for name in ("pp", "lmpc"):
        controller = build_controller(name, scenario)
        assert controller.name == name
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


def test_make_controller_reads_the_cars_settings():
    # The typed path: a car's settings reach the controller; no options dictionary.
    config = load_preset("fullsize")
    with pytest.warns(UserWarning, match="made at 1:10"):
        scenario = Scenario.from_car(config, "builtin")
    lmpc = make_controller("lmpc", scenario.reference, scenario.vehicle, settings=config.controllers)
    assert lmpc.config == config.controllers.lmpc
    pp = make_controller("pp", scenario.reference, scenario.vehicle, settings=config.controllers)
    assert pp.config == config.controllers.pp
