"""``rkmpc sim-node`` and ``rkmpc node`` together on loopback: a lap over ROS 2, and a dead car.

Both run as their own processes through the command line, as on a car: the whole path is tested
(argument parsing, the per-car YAML, DDS discovery between processes, shutdown on SIGINT), and
killing the simulated car is a real loss of the odometry's publisher. Discovery is limited to
this machine and each test has its own domain id. Every wait below is a bound against a hang,
never what an assertion measures: the lap runs in lock-step, so its result does not depend on
how busy the machine is, and the stop is judged on the node's own record of odometry ages.
"""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="ROS 2 is not installed (make ros)", exc_type=ImportError)
pytest.importorskip("ackermann_msgs", reason="ackermann_msgs is not built (make ros)", exc_type=ImportError)

pytestmark = pytest.mark.filterwarnings("ignore:module 'sre_:DeprecationWarning")

SRC = Path(__file__).resolve().parents[1] / "src"
#: Upper bound of any wait (s): a hang fails the test instead of stalling CI.
HANG = 300.0


@pytest.fixture
def ros_env(tmp_path, request):
    """The environment of the test's ROS processes: localhost only, a domain id of its own."""
    domain = 1 + (os.getpid() * 31 + sum(map(ord, request.node.name))) % 200
    env = dict(os.environ)
    env.update(
        PYTHONPATH=os.pathsep.join([str(SRC), *filter(None, [env.get("PYTHONPATH")])]),
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        ROS_LOG_DIR=str(tmp_path / "ros-log"),
    )
    return env


def start(args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen:
    with log.open("w") as out:
        return subprocess.Popen(
            [sys.executable, "-m", "rkmpc.cli", *args], env=env, stdout=out, stderr=subprocess.STDOUT
        )


def finish(process: subprocess.Popen, log: Path) -> int:
    """SIGINT (Ctrl-C), then the exit status."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        return process.wait(timeout=60)
    except subprocess.TimeoutExpired:
        process.kill()
        raise AssertionError(f"{process.args} did not stop on SIGINT:\n{log.read_text()}") from None


def node_rows(folder: Path) -> list[dict[str, str]]:
    with (folder / "node_log.csv").open() as f:
        return list(csv.DictReader(f))


def test_a_lap_over_ros_in_lock_step_matches_the_in_process_run(tmp_path, ros_env):
    from rkmpc.analysis.metrics import lap_metrics
    from rkmpc.sim.run import RunSpec, drive
    from rkmpc.sim.scenario import load_scenario

    car = tmp_path / "car.yaml"
    car.write_text("controller: lmpc\ntrigger: odometry\ntopics: {steering: /rkmpc/steering}\n")
    node_log, sim_log = tmp_path / "node.log", tmp_path / "sim.log"
    node = start(["node", "--config", str(car), "--out", str(tmp_path / "node")], ros_env, node_log)
    try:
        sim_args = ["sim-node", "--clock", "lockstep", "--laps", "1", "--steering-topic", "/rkmpc/steering"]
        sim_args += [
            "--startup-timeout",
            str(HANG),
            "--answer-timeout",
            str(HANG),
            "--out",
            str(tmp_path / "sim"),
        ]
        sim = start(sim_args, ros_env, sim_log)
        try:
            code = sim.wait(timeout=HANG)
        finally:
            if sim.poll() is None:
                sim.kill()
    finally:
        node_code = finish(node, node_log)
    assert code == 0, sim_log.read_text()
    assert node_code == 0, node_log.read_text()
    summary = json.loads((tmp_path / "sim" / "summary.json").read_text())
    over_ros = summary["metrics"]
    in_process = lap_metrics(drive(load_scenario("builtin"), RunSpec("lmpc")))
    assert summary["outcome"] == "completed" and over_ros["completed"]
    assert over_ros["lateral_error_mean_m"] == pytest.approx(in_process.lateral_error_mean_m, rel=0.2)
    assert over_ros["heading_error_mean_rad"] == pytest.approx(in_process.heading_error_mean_rad, rel=0.2)
    assert over_ros["lap_time_s"] == pytest.approx(in_process.lap_time_s, rel=0.02)
    assert summary["commands_received"] == over_ros["steps"]  # one answer per odometry, none lost
    rows = node_rows(tmp_path / "node")
    answers = [r for r in rows if r["state"] == "running"]
    assert len(answers) == over_ros["steps"]
    # The wheel angle the car measured reached the controller with its own odometry.
    assert all(math.isfinite(float(r["obs_steer_angle"])) for r in answers)
    assert rows[-1]["state"] == "shutdown" and float(rows[-1]["speed"]) == 0.0


def test_the_node_stops_the_car_when_its_odometry_dies(tmp_path, ros_env, monkeypatch):
    import rclpy
    from ackermann_msgs.msg import AckermannDriveStamped
    from rclpy.signals import SignalHandlerOptions

    timeout = 0.5
    car = tmp_path / "car.yaml"
    car.write_text(f"controller: lmpc\nsafety: {{odometry_timeout: {timeout}}}\n")
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
    node = start(["node", "--config", str(car), "--out", str(tmp_path / "node")], ros_env, node_log)
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
