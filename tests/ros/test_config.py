"""What ``rkmpc node`` drives: the car file every command reads (its ``[ros]`` section overridden by
ROS parameters) and the task of its command line. None of it needs ROS."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from rkmpc.config.loader import load_car_config, load_preset
from rkmpc.config.ros import RosSettings, SafetySettings
from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.ros.config import NodeTask, flatten, load_node_car

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def write(tmp_path: Path, text: str, name: str = "car.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_an_empty_file_gives_the_f1tenth_simulators_conventions(tmp_path):
    car = load_node_car(write(tmp_path, ""))
    config = car.ros
    assert config == RosSettings()
    assert config.topics.odometry == "/ego_racecar/odom" and config.topics.drive == "/drive"
    assert config.rate_hz == 20.0 and math.isclose(config.period, 0.05)
    assert config.frames.map == "map" and config.trigger == "timer"
    assert replace(car, source=None, sha256=None) == load_preset("f1tenth")


def test_the_repos_car_file_is_what_the_node_reads():
    # `rkmpc node --config configs/f1tenth.toml` reads the file `rkmpc run --config` takes.
    path = CONFIGS / "f1tenth.toml"
    assert load_node_car(path) == load_car_config(path)
    assert load_node_car(path).source == str(path.resolve())


def test_sections_and_ros_parameter_overrides(tmp_path):
    path = write(
        tmp_path,
        "[limits]\nmax_speed = 3\n"
        "[ros.topics]\nodometry = '/car_state/odom'\n"
        "[ros.safety]\nodometry_timeout = 0.3\nmax_lateral_error = 0.8\n"
        "[ros.latency]\ncompensate = true\nactuation = 0.05\n",
    )
    car = load_node_car(path, {"safety.odometry_timeout": 1, "rate_hz": 40, "frames.map": ""})
    config = car.ros
    assert config.topics.odometry == "/car_state/odom" and config.topics.steering is None
    # The ROS parameter wins over the file; integers are accepted where seconds are asked for.
    assert config.safety == SafetySettings(odometry_timeout=1.0, max_lateral_error=0.8)
    assert config.rate_hz == 40.0 and config.frames.map is None
    assert config.latency.compensate and config.latency.actuation == 0.05
    assert (
        car.limits.max_speed == 3.0
        and car.limits.lateral_accel == load_preset("f1tenth").limits.lateral_accel
    )
    flat = flatten(config)
    assert flat["safety.odometry_timeout"] == 1.0 and flat["topics.drive"] == "/drive"
    assert flat["rate_hz"] == 40.0 and flat["record.bag"] is None
    # A ROS parameter sets [ros] keys only: the car's other sections stay the file's.
    assert replace(car, ros=load_car_config(path).ros) == load_car_config(path)


def test_overrides_of_a_car_already_read(tmp_path):
    car = load_car_config(write(tmp_path, "[ros]\nrate_hz = 25.0\n"))
    assert load_node_car(car) is car and load_node_car(car, {}) is car
    fast = load_node_car(car, {"safety.max_speed": 2.5, "trigger": "odometry"})
    assert fast.ros.safety.max_speed == 2.5 and fast.ros.trigger == "odometry" and fast.ros.rate_hz == 25.0
    assert replace(fast, ros=car.ros) == car
    preset = load_node_car(load_preset("f1tenth"), {"rate_hz": 10})
    assert preset.ros.rate_hz == 10.0 and preset.ros.period == 0.1


def test_the_recorded_bag_is_relative_to_the_file_and_its_storage_checked(tmp_path):
    assert load_node_car(write(tmp_path, "")).ros.record.bag is None
    config = load_node_car(
        write(tmp_path, "[ros.record]\nbag = 'bags/run-{time}'\nstorage = 'sqlite3'\n")
    ).ros
    assert config.record.bag == str(tmp_path / "bags/run-{time}") and config.record.storage == "sqlite3"
    with pytest.raises(InputFileError, match="storage must be one of") as info:
        load_node_car(write(tmp_path, "[ros.record]\nstorage = 'ros1'\n"))
    assert info.value.field == "ros.record.storage"


@pytest.mark.parametrize(
    ("text", "overrides", "key", "words"),
    [
        ("[ros]\ncontroler = 'lmpc'\n", {}, "ros.controler", "unknown key"),
        ("[ros.safety]\nodometry_timout = 1\n", {}, "ros.safety.odometry_timout", "unknown key"),
        ("", {"safety.timeout": 1.0}, "ros.safety.timeout", "unknown key 'timeout'"),
        ("", {"controller": "lmpc"}, "ros.controller", "unknown key 'controller'"),
        ("", {"rate_hz": "fast"}, "ros.rate_hz", "a number"),
        ("[ros]\nrate_hz = 'fast'\n", {}, "ros.rate_hz", "a number"),
        ("[ros.safety]\nlatch = 1\n", {}, "ros.safety.latch", "true or false"),
        ("[ros.topics]\ndrive = 3\n", {}, "ros.topics.drive", "string"),
        ("[ros]\nsafety = 3\n", {}, "ros.safety", "mapping"),
        (
            "[ros.safety]\nodometry_timeout = -1\n",
            {},
            "ros.safety.odometry_timeout",
            "must be finite and > 0",
        ),
        ("", {"safety.odometry_timeout": -1}, "ros.safety.odometry_timeout", "must be finite and > 0"),
        ("[ros]\ntrigger = 'sometimes'\n", {}, "ros.trigger", "trigger must be one of"),
        ("[ros.odometry]\npose = 'front_axle'\n", {}, "ros.odometry.pose", "pose must be one of"),
        ("[ros.latency]\nactuation = nan\n", {}, "ros.latency.actuation", "actuation must be finite"),
    ],
)
def test_errors_name_the_file_and_the_key(tmp_path, text, overrides, key, words):
    path = write(tmp_path, text)
    with pytest.raises(InputFileError, match=words) as info:
        load_node_car(path, overrides)
    assert info.value.path == path
    assert info.value.field == key


def test_an_unknown_parameter_given_to_a_car_already_read_is_named(tmp_path):
    car = load_car_config(write(tmp_path, ""))
    with pytest.raises(InputFileError, match=r"unknown key 'odometry_timout' \(a ROS parameter\)") as info:
        load_node_car(car, {"safety.odometry_timout": 1.0})
    assert info.value.field == "ros.safety.odometry_timout"
    with pytest.raises(InputFileError, match="a ROS parameter") as info:
        load_node_car(load_preset("f1tenth"), {"controller": "pp"})
    assert info.value.field == "ros.controller"


def test_yaml_car_files_are_read_too(tmp_path):
    pytest.importorskip("yaml", reason="PyYAML comes with the ros extra")
    path = write(tmp_path, "ros:\n  rate_hz: 40\n  topics: {odometry: /odom, steering: null}\n", "car.yaml")
    config = load_node_car(path, {"safety.odometry_timeout": 0.2}).ros
    assert (config.rate_hz, config.topics.odometry, config.topics.steering) == (40.0, "/odom", None)
    assert config.safety.odometry_timeout == 0.2


def test_unreadable_files(tmp_path):
    with pytest.raises(InputFileError, match="file not found"):
        load_node_car(tmp_path / "missing.toml")
    with pytest.raises(InputFileError, match="not a valid TOML file"):
        load_node_car(write(tmp_path, "[ros\n"))
    pytest.importorskip("yaml", reason="PyYAML comes with the ros extra")
    with pytest.raises(InputFileError, match="not a valid YAML file"):
        load_node_car(write(tmp_path, "a: [1,\n", "car.yaml"))
    with pytest.raises(InputFileError, match="expected a mapping"):
        load_node_car(write(tmp_path, "- 1\n- 2\n", "car.yaml"))


def test_the_task_is_what_the_command_line_asks_for():
    task = NodeTask()
    assert (task.track, task.raceline, task.scale, task.controller, task.model, task.allow_mismatch) == (
        "builtin",
        None,
        None,
        "lmpc",
        None,
        False,
    )
    given = NodeTask(track="oval", controller="rkmpc", model="m.rkm", scale=0.1, allow_mismatch=True)
    assert flatten(given) == {
        "track": "oval",
        "raceline": None,
        "scale": 0.1,
        "controller": "rkmpc",
        "model": "m.rkm",
        "allow_mismatch": True,
    }
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ParameterError, match=r"NodeTask\.scale"):
            NodeTask(scale=bad)
    with pytest.raises(TypeError):
        NodeTask("oval")  # type: ignore[misc]  # keyword-only


def test_flatten_takes_mappings_and_nested_records():
    assert flatten({"a": 1, "b": {"c": 2, "d": {"e": None}}}) == {"a": 1, "b.c": 2, "b.d.e": None}
    assert flatten(SafetySettings(), "safety.")["safety.latch"] is True


def test_the_package_and_its_command_line_load_no_ros():
    code = (
        "import sys, rkmpc, rkmpc.cli, rkmpc.sim.run, rkmpc.ros.config, rkmpc.config.ros;"
        " print(sorted(m for m in sys.modules if 'rclpy' in m))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_without_ros_the_commands_say_how_to_install_it(tmp_path, capsys, monkeypatch):
    from rkmpc.cli import main

    monkeypatch.setitem(sys.modules, "rclpy", None)  # as if the ros extra were not installed
    monkeypatch.delitem(sys.modules, "rkmpc.ros.node", raising=False)
    monkeypatch.delitem(sys.modules, "rkmpc.ros.sim_node", raising=False)
    monkeypatch.delitem(sys.modules, "rkmpc.ros.remote", raising=False)
    assert main(["node", "--config", str(write(tmp_path, ""))]) == 2
    assert main(["sim-node", "--clock", "lockstep"]) == 2
    err = capsys.readouterr().err
    assert err.count("ROS 2 is not installed") == 2 and "make ros" in err
