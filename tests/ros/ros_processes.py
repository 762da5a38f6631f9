"""The ROS 2 processes of the loop tests: ``rkmpc node`` and ``rkmpc sim-node`` started as on a car.

Imported by ``tests/ros/test_loop.py`` and ``tests/ros/test_loop_sensors.py`` (after they have
skipped themselves where ROS 2 is not installed). Every wait is a bound against a hang.
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
from pathlib import Path

from ros_domain import ros_domain_id

SRC = Path(__file__).resolve().parents[2] / "src"
#: The repository's car file: the one `rkmpc run --config` takes drives the simulated car over ROS.
REPO_CAR = Path(__file__).resolve().parents[2] / "configs" / "f1tenth.toml"
#: Upper bound of any wait (s): a hang fails the test instead of stalling CI.
HANG = 300.0


def ros_environment(log_dir: Path, name: str) -> dict[str, str]:
    """The environment of ROS processes: localhost only, a domain id of their own, logs in ``log_dir``."""
    domain = ros_domain_id(name)
    env = dict(os.environ)
    env.update(
        PYTHONPATH=os.pathsep.join([str(SRC), *filter(None, [env.get("PYTHONPATH")])]),
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        ROS_LOG_DIR=str(log_dir),
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


def lockstep_lap(folder: Path, env: dict[str, str], node_args: list[str], sim_args: list[str]) -> None:
    """One lap of the built-in track in lock-step: ``rkmpc node_args...`` driving ``rkmpc sim-node``.

    The node starts first, then the simulated car (``sim_args`` added to its lock-step lap, its
    output in ``folder / "sim"``); the node is stopped by SIGINT once the car has finished. Both
    must exit with 0; their output is in ``folder / "node.log"`` and ``folder / "sim.log"``.
    """
    node_log, sim_log = folder / "node.log", folder / "sim.log"
    node = start(node_args, env, node_log)
    try:
        args = ["sim-node", "--clock", "lockstep", "--laps", "1", *sim_args]
        args += ["--startup-timeout", str(HANG), "--answer-timeout", str(HANG)]
        args += ["--out", str(folder / "sim")]
        sim = start(args, env, sim_log)
        try:
            code = sim.wait(timeout=HANG)
        finally:
            if sim.poll() is None:
                sim.kill()
    finally:
        node_code = finish(node, node_log)
    assert code == 0, sim_log.read_text()
    assert node_code == 0, node_log.read_text()
