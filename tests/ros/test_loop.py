"""``rkmpc sim-node`` and ``rkmpc node`` together on loopback: a lap over ROS 2, and a dead car.

Both run as their own processes through the command line, as on a car: the whole path is tested
(argument parsing, the car file every command reads with its ``[ros]`` section and ROS-parameter
overrides of it, DDS discovery between processes, shutdown on SIGINT), and
killing the simulated car is a real loss of the odometry's publisher. Discovery is limited to
this machine and each test has its own domain id. Every wait below is a bound against a hang,
never what an assertion measures: the lap runs in lock-step, so its result does not depend on
how busy the machine is, and the stop is judged on the node's own record of odometry ages.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy", reason="ROS 2 is not installed (make ros)", exc_type=ImportError)
pytest.importorskip("ackermann_msgs", reason="ackermann_msgs is not built (make ros)", exc_type=ImportError)

from ros_processes import HANG, REPO_CAR, finish, lockstep_lap, node_rows, ros_environment, start

pytestmark = pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning")


@pytest.fixture
def ros_env(tmp_path, request):
    """The environment of the test's ROS processes."""
    return ros_environment(tmp_path / "ros-log", request.node.name)


STEERING = "/rkmpc/steering"


@pytest.fixture(scope="module")
def lap(tmp_path_factory):
    """A lap of the built-in track over ROS 2 in lock-step with the LMPC, recorded to a bag by the node.

    The node reads the repository's car file (``rkmpc node --config configs/f1tenth.toml``, the file
    ``rkmpc run --config`` takes); ROS parameters set the lock-step trigger and the wheel-angle topic
    over its ``[ros]`` section.
    """
    folder = tmp_path_factory.mktemp("lap")
    env = ros_environment(folder / "ros-log", "lap")
    node_args = ["node", "--config", str(REPO_CAR), "--controller", "lmpc", "--out", str(folder / "node")]
    node_args += ["--record", str(folder / "bag")]
    node_args += ["--ros-args", "-p", "trigger:=odometry", "-p", f"topics.steering:={STEERING}"]
    lockstep_lap(folder, env, node_args, ["--steering-topic", STEERING])
    return folder


def test_the_node_drove_with_the_repos_car_file_and_the_ros_parameters(lap):
    import hashlib

    summary = json.loads((lap / "node" / "node_summary.json").read_text())
    car = summary["car"]
    assert car["file"] == str(REPO_CAR.resolve())
    assert car["sha256"] == hashlib.sha256(REPO_CAR.read_bytes()).hexdigest()
    assert car["vehicle"]["preset"] == "f1tenth" and car["controllers"]["lmpc"]["horizon"] == 30
    # The ROS parameters set the [ros] keys they name; the rest is the file's (its defaults).
    config = summary["config"]
    assert (config["trigger"], config["topics.steering"]) == ("odometry", STEERING)
    assert (config["rate_hz"], config["topics.odometry"], config["topics.drive"]) == (
        20.0,
        "/ego_racecar/odom",
        "/drive",
    )
    assert car["ros"]["trigger"] == "odometry" and car["ros"]["topics"]["steering"] == STEERING
    assert summary["task"] == {
        "track": "builtin",
        "raceline": None,
        "scale": None,
        "controller": "lmpc",
        "model": None,
        "allow_mismatch": False,
    }
    assert summary["controller_errors"] == 0 and summary["nonfinite_commands"] == 0


def test_a_lap_over_ros_in_lock_step_matches_the_in_process_run(lap):
    from rkmpc.analysis.metrics import lap_metrics
    from rkmpc.config.loader import load_car_config
    from rkmpc.sim.run import RunSpec, drive
    from rkmpc.sim.scenario import Scenario

    summary = json.loads((lap / "sim" / "summary.json").read_text())
    over_ros = summary["metrics"]
    # The same car file driven in-process (`rkmpc run --config configs/f1tenth.toml`).
    in_process = lap_metrics(drive(Scenario.from_car(load_car_config(REPO_CAR), "builtin"), RunSpec("lmpc")))
    assert summary["outcome"] == "completed" and over_ros["completed"]
    assert over_ros["lateral_error_mean_m"] == pytest.approx(in_process.lateral_error_mean_m, rel=0.2)
    assert over_ros["heading_error_mean_rad"] == pytest.approx(in_process.heading_error_mean_rad, rel=0.2)
    assert over_ros["lap_time_s"] == pytest.approx(in_process.lap_time_s, rel=0.02)
    assert summary["commands_received"] == over_ros["steps"]  # one answer per odometry, none lost
    rows = node_rows(lap / "node")
    answers = [r for r in rows if r["state"] == "running"]
    assert len(answers) == over_ros["steps"]
    # The wheel angle the car measured reached the controller with its own odometry.
    assert all(math.isfinite(float(r["obs_steer_angle"])) for r in answers)
    assert rows[-1]["state"] == "shutdown" and float(rows[-1]["speed"]) == 0.0


def test_the_recorded_bag_is_the_lap_the_simulated_car_drove(lap):
    """Imported, the node's bag gives the simulated car's own log: poses, wheel angles, commands."""
    import yaml

    from rkmpc.core.angles import wrap_angle
    from rkmpc.core.observation import OBSERVATION_FIELDS
    from rkmpc.learning.data.bags import BagImportConfig, import_bag
    from rkmpc.sim.log import StepLog
    from rkmpc.vehicle.params import f1tenth

    bag = lap / "bag"
    assert sorted(p.name for p in lap.iterdir() if p.name.startswith(".")) == []  # no draft left
    data = import_bag(bag, f1tenth(), BagImportConfig(steer_topic=STEERING))
    log = StepLog.from_csv(lap / "sim" / "log.csv")
    n = len(log)
    assert len(data) == n - 1 and set(data.episode.tolist()) == {0}  # every step, one episode
    # The log has 9 significant digits; odometry and wheel angle are float64 on the wire.
    for name in ("x", "y", "yaw", "speed", "yaw_rate", "steer_angle"):
        column = OBSERVATION_FIELDS.index(name)
        logged = wrap_angle(log[name]) if name == "yaw" else log[name]  # the log's yaw is unwrapped
        for got, want in ((data.obs, logged[: n - 1]), (data.next_obs, logged[1:])):
            np.testing.assert_allclose(got[:, column], want, rtol=1e-8, atol=1e-8, err_msg=name)
    # The commands are float32 on the wire.
    np.testing.assert_allclose(data.command[:, 0], log["cmd_speed"][: n - 1], rtol=2.0**-23)
    np.testing.assert_allclose(data.command[:, 1], log["cmd_steer"][: n - 1], rtol=2.0**-23, atol=1e-12)
    # The bag is what ros2 bag would make: the types' names and the RIHS01 hashes ROS 2 announces.
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["storage_identifier"] == "mcap"
    topics = {t["topic_metadata"]["name"]: t["topic_metadata"] for t in info["topics_with_message_count"]}
    share = Path(sys.prefix) / "share"
    for topic, kind in [
        ("/ego_racecar/odom", "nav_msgs/msg/Odometry"),
        ("/drive", "ackermann_msgs/msg/AckermannDriveStamped"),
        (STEERING, "std_msgs/msg/Float64"),
    ]:
        package, _, name = kind.split("/")
        described = json.loads((share / package / "msg" / f"{name}.json").read_text())
        hashes = {h["type_name"]: h["hash_string"] for h in described["type_hashes"]}
        assert topics[topic]["type"] == kind and topics[topic]["type_description_hash"] == hashes[kind]


@pytest.mark.slow  # several seconds: the slow tier (make test-slow, run by CI)
def test_the_node_stops_the_car_when_its_odometry_dies(tmp_path, ros_env, monkeypatch):
    import rclpy
    from ackermann_msgs.msg import AckermannDriveStamped
    from rclpy.signals import SignalHandlerOptions

    timeout = 0.5
    car = tmp_path / "car.yaml"  # a car file in YAML, its [ros] section read by the node
    car.write_text(f"vehicle: {{preset: f1tenth}}\nros:\n  safety: {{odometry_timeout: {timeout}}}\n")
    for key in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOG_DIR"):
        monkeypatch.setenv(key, ros_env[key])
    context = rclpy.Context()
    rclpy.init(
        context=context,
        domain_id=int(ros_env["ROS_DOMAIN_ID"]),
        signal_handler_options=SignalHandlerOptions.NO,
    )
    heard: list[tuple[float, float]] = []
    probe = rclpy.create_node("probe", context=context)
    probe.create_subscription(
        AckermannDriveStamped, "/drive", lambda m: heard.append((m.drive.speed, m.drive.steering_angle)), 100
    )
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(probe)

    def spin_until(condition, what: str) -> None:
        deadline = time.monotonic() + HANG
        while not condition():
            assert time.monotonic() < deadline, f"no {what} within {HANG} s"
            executor.spin_once(timeout_sec=0.05)

    node_log, sim_log = tmp_path / "node.log", tmp_path / "sim.log"
    bag = tmp_path / "bag"
    node_args = ["node", "--config", str(car), "--controller", "lmpc", "--out", str(tmp_path / "node")]
    node = start([*node_args, "--record", str(bag), "--record-storage", "sqlite3"], ros_env, node_log)
    sim = start(["sim-node", "--laps", "1"], ros_env, sim_log)
    try:
        spin_until(lambda: sum(speed > 0 for speed, _ in heard) >= 20, "driving commands")  # a second driving
        sim.kill()  # the odometry's publisher dies mid-lap, without a word
        sim.wait(timeout=60)
        killed_at = len(heard)
        spin_until(lambda: any(speed == 0.0 for speed, _ in heard[killed_at:]), "stop command")
    finally:
        if sim.poll() is None:
            sim.kill()
        node_code = finish(node, node_log)
        executor.shutdown()
        probe.destroy_node()
        rclpy.try_shutdown(context=context)
    assert node_code == 0, node_log.read_text()
    rows = node_rows(tmp_path / "node")
    states = [r["state"] for r in rows]
    last_driving = max(i for i, state in enumerate(states) if state == "running")
    before, stop = rows[last_driving], rows[last_driving + 1]
    assert stop["state"] == "no_odometry"
    # The first command after the odometry grew older than the timeout is the stop: speed 0, the
    # wheel held where the last driving command put it.
    assert before["state"] == "running" and float(before["odometry_age_s"]) <= timeout
    assert float(stop["odometry_age_s"]) > timeout
    assert float(stop["speed"]) == 0.0 and stop["steer"] == before["steer"]
    # Every command made from odometry older than the timeout is a stop, until the end.
    for row in rows:
        if row["state"] != "waiting" and float(row["odometry_age_s"]) > timeout:
            assert row["state"] in ("no_odometry", "shutdown") and float(row["speed"]) == 0.0
    assert states[-1] == "shutdown"
    # What went over the wire: the stop, with the held wheel angle (float32 on the wire).
    stops = [(speed, steer) for speed, steer in heard[killed_at:] if speed == 0.0]
    assert stops[0][1] == pytest.approx(float(before["steer"]), abs=1e-6)
    # The node was stopped (SIGINT) mid-lap, recording in real time: its bag is complete, under its
    # own name, with every command it sent (the final stop last) and the odometry it drove on.
    from rkmpc.learning.data.bags import BagImportConfig, import_bag
    from rkmpc.learning.data.bags.read import read_streams
    from rkmpc.learning.data.bags.stream import RECORDING_KEY, read_metadata
    from rkmpc.vehicle.params import f1tenth

    info = read_metadata(bag)  # closed segments of 2 s, all listed, the bag marked closed
    assert sorted(info["relative_file_paths"]) == sorted(p.name for p in bag.glob("*.db3"))
    assert info["custom_data"] == {RECORDING_KEY: "closed"} and not (bag / ".recording").exists()
    assert [p for p in tmp_path.iterdir() if p.name.startswith(".bag")] == []
    streams = read_streams(bag, BagImportConfig())
    assert len(streams.drive) == len(rows) and streams.drive.values[-1][0] == 0.0
    np.testing.assert_allclose(streams.drive.values[:, 0], [float(r["speed"]) for r in rows], rtol=2.0**-23)
    assert len(streams.odom) >= sum(r["fresh"] == "1" for r in rows)
    data = import_bag(bag, f1tenth(), BagImportConfig(min_samples=10))
    assert len(data) >= 10 and np.all(np.isfinite(data.obs[:, :5]))


@pytest.mark.slow
def test_a_node_killed_with_sigkill_after_a_lap_leaves_a_bag_with_that_lap(tmp_path, ros_env, capsys):
    """``kill -9`` of ``rkmpc node --record`` (a crash, the out-of-memory killer, a power cut on the
    car): the bag is there under its name and ``collect --from-bag`` imports at least 90 % of the lap
    driven before (all but the segment being written when the node died, 2 s at most)."""
    from rkmpc.cli import main
    from rkmpc.learning.data.dataset import TransitionDataset
    from rkmpc.sim.log import StepLog

    bag = tmp_path / "bag"
    node_args = ["node", "--config", str(REPO_CAR), "--controller", "lmpc", "--record", str(bag)]
    node_args += ["--ros-args", "-p", "trigger:=odometry", "-p", f"topics.steering:={STEERING}"]
    node = start(node_args, ros_env, tmp_path / "node.log")
    try:
        sim_args = ["sim-node", "--clock", "lockstep", "--laps", "1", "--steering-topic", STEERING]
        sim_args += ["--startup-timeout", str(HANG), "--answer-timeout", str(HANG)]
        sim = start([*sim_args, "--out", str(tmp_path / "sim")], ros_env, tmp_path / "sim.log")
        try:
            assert sim.wait(timeout=HANG) == 0, (tmp_path / "sim.log").read_text()
        finally:
            if sim.poll() is None:
                sim.kill()
        assert node.poll() is None, (tmp_path / "node.log").read_text()
    finally:
        node.send_signal(signal.SIGKILL)  # no chance to close the bag
        node.wait(timeout=60)
    assert node.returncode == -signal.SIGKILL
    out = tmp_path / "lap.npz"
    capsys.readouterr()
    assert main(["collect", "--from-bag", str(bag), "--steer-topic", STEERING, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "a recording that never ended" in err, err
    data = TransitionDataset.load(out)
    lap = len(StepLog.from_csv(tmp_path / "sim" / "log.csv")) - 1  # transitions of the lap driven
    assert data.metadata["recording"] == "unfinished"
    assert len(data) >= 0.9 * lap, (len(data), lap)


def test_a_bag_name_may_carry_the_start_time():
    import datetime

    from rkmpc.ros.bag_record import bag_path

    moment = datetime.datetime(2025, 1, 31, 14, 25, 1)
    assert bag_path("runs/laps-{time}", moment) == Path("runs/laps-20250131-142501")
    assert bag_path("runs/laps", moment) == Path("runs/laps")
