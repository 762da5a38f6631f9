"""The per-car YAML of ``rkmpc node``: defaults, overrides by ROS parameter, errors naming file and key."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("yaml", reason="PyYAML comes with the ros extra")

from rkmpc.core.errors import InputFileError
from rkmpc.ros.config import NodeConfig, SafetySettings, flatten, load_node_config
from rkmpc.track.speed_profile import SpeedLimits


def write(tmp_path, text: str):
    path = tmp_path / "car.yaml"
    path.write_text(text)
    return path


def test_an_empty_file_gives_the_f1tenth_simulators_conventions(tmp_path):
    config = load_node_config(write(tmp_path, ""))
    assert config == NodeConfig()
    assert config.topics.odometry == "/ego_racecar/odom" and config.topics.drive == "/drive"
    assert config.rate_hz == 20.0 and math.isclose(config.period, 0.05)
    assert config.frames.map == "map" and config.trigger == "timer"


def test_sections_paths_and_overrides(tmp_path):
    (tmp_path / "models").mkdir()
    path = write(
        tmp_path,
        "track: tracks/monza.csv\nscale: 0.1\ncontroller: rkmpc\nmodel: models/residual.rkm\n"
        "topics: {odometry: /car_state/odom, steering: null}\n"
        "safety: {odometry_timeout: 0.3, max_lateral_error: 0.8}\n"
        "speed_limits: {max_speed: 3}\nlatency: {compensate: true, actuation: 0.05}\n",
    )
    config = load_node_config(path, {"safety.odometry_timeout": 1, "rate_hz": 40, "frames.map": ""})
    assert config.track == str(tmp_path / "tracks/monza.csv")
    assert config.model == str(tmp_path / "models/residual.rkm")
    assert config.topics.odometry == "/car_state/odom" and config.topics.steering is None
    # The ROS parameter wins over the file; integers are accepted where seconds are asked for.
    assert config.safety == SafetySettings(odometry_timeout=1.0, max_lateral_error=0.8)
    assert config.rate_hz == 40.0 and config.frames.map is None
    assert config.latency.compensate and config.latency.actuation == 0.05
    limits = config.speed_limits.applied_to(SpeedLimits())
    assert limits.max_speed == 3.0 and limits.lateral_accel == SpeedLimits().lateral_accel
    flat = flatten(config)
    assert flat["safety.odometry_timeout"] == 1.0 and flat["topics.drive"] == "/drive"


def test_the_recorded_bag_is_relative_to_the_file_and_its_storage_checked(tmp_path):
    assert load_node_config(write(tmp_path, "")).record.bag is None
    config = load_node_config(write(tmp_path, "record: {bag: 'bags/run-{time}', storage: sqlite3}\n"))
    assert config.record.bag == str(tmp_path / "bags/run-{time}") and config.record.storage == "sqlite3"
    with pytest.raises(InputFileError, match="storage must be one of") as info:
        load_node_config(write(tmp_path, "record: {storage: ros1}\n"))
    assert info.value.field == "record.storage"


def test_built_in_track_names_stay_names(tmp_path):
    assert load_node_config(write(tmp_path, "track: oval\n")).track == "oval"


@pytest.mark.parametrize(
    ("text", "overrides", "key", "words"),
    [
        ("controler: lmpc\n", {}, "controler", "unknown key"),
        ("safety: {odometry_timout: 1}\n", {}, "safety.odometry_timout", "unknown key"),
        ("", {"safety.timeout": 1.0}, "safety.timeout", "unknown key"),
        ("rate_hz: fast\n", {}, "rate_hz", "a number"),
        ("safety: {latch: 1}\n", {}, "safety.latch", "true or false"),
        ("topics: {drive: 3}\n", {}, "topics.drive", "string"),
        ("safety: 3\n", {}, "safety", "mapping"),
        ("safety: {odometry_timeout: -1}\n", {}, "safety.odometry_timeout", "must be finite and > 0"),
        ("trigger: sometimes\n", {}, "trigger", "trigger must be one of"),
        ("odometry: {pose: front_axle}\n", {}, "odometry.pose", "pose must be one of"),
        ("latency: {actuation: .nan}\n", {}, "latency.actuation", "actuation must be finite"),
    ],
)
def test_errors_name_the_file_and_the_key(tmp_path, text, overrides, key, words):
    path = write(tmp_path, text)
    with pytest.raises(InputFileError, match=words) as info:
        load_node_config(path, overrides)
    assert info.value.path == path
    assert info.value.field == key


def test_unreadable_files(tmp_path):
    with pytest.raises(InputFileError, match="file not found"):
        load_node_config(tmp_path / "missing.yaml")
    with pytest.raises(InputFileError, match="not a readable YAML"):
        load_node_config(write(tmp_path, "a: [1,\n"))
    with pytest.raises(InputFileError, match="expected a mapping"):
        load_node_config(write(tmp_path, "- 1\n- 2\n"))


def test_the_package_and_its_command_line_load_no_ros():
    import subprocess
    import sys

    code = (
        "import sys, rkmpc, rkmpc.cli, rkmpc.sim.run; print(sorted(m for m in sys.modules if 'rclpy' in m))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_without_ros_the_commands_say_how_to_install_it(tmp_path, capsys, monkeypatch):
    import sys

    from rkmpc.cli import main

    monkeypatch.setitem(sys.modules, "rclpy", None)  # as if the ros extra were not installed
    monkeypatch.delitem(sys.modules, "rkmpc.ros.node", raising=False)
    monkeypatch.delitem(sys.modules, "rkmpc.ros.sim_node", raising=False)
    monkeypatch.delitem(sys.modules, "rkmpc.ros.remote", raising=False)
    assert main(["node", "--config", str(write(tmp_path, ""))]) == 2
    assert main(["sim-node", "--clock", "lockstep"]) == 2
    err = capsys.readouterr().err
    assert err.count("ROS 2 is not installed") == 2 and "make ros" in err
