"""Issue 27's probe: what was lost (a recording killed with ``kill -9``, results on a full disk)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from unittest import mock

from probe_cases import CLEAR_ERROR, GRACEFUL, Evidence, Probe, case, cli_error, lap

from ros_domain import ros_domain_id

GROUP = "lost (issue 27)"
SRC = Path(__file__).resolve().parents[2] / "src"
REPO_CAR = Path(__file__).resolve().parents[2] / "configs" / "f1tenth.toml"
STEERING = "/rkmpc/steering"
#: Bound of any wait on a process (s): against a hang, never what is measured.
HANG = 300.0

_RECORDER = """
import os, signal, sys
import numpy as np
from rkmpc.learning.data.bags import BagStreamWriter
from rkmpc.learning.data.bags.types import ACKERMANN_DRIVE_STAMPED, ODOMETRY, typestore

store, types = typestore(ros1=False), typestore(ros1=False).types
def header(ns):
    time = types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    return types["std_msgs/msg/Header"](stamp=time, frame_id="map")
def odometry(ns, x):
    vec, cov = types["geometry_msgs/msg/Vector3"], np.zeros(36)
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))
    zero = vec(x=0.0, y=0.0, z=0.0)
    twist = types["geometry_msgs/msg/Twist"](linear=vec(x=2.0, y=0.0, z=0.0), angular=zero)
    msg = types[ODOMETRY](header=header(ns), child_frame_id="base_link",
        pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov))
    return bytes(store.serialize_cdr(msg, ODOMETRY))
def drive(ns):
    cmd = types["ackermann_msgs/msg/AckermannDrive"](
        steering_angle=0.0, steering_angle_velocity=0.0, speed=2.0, acceleration=0.0, jerk=0.0)
    msg = types[ACKERMANN_DRIVE_STAMPED](header=header(ns), drive=cmd)
    return bytes(store.serialize_cdr(msg, ACKERMANN_DRIVE_STAMPED))
writer = BagStreamWriter(sys.argv[1], {"/ego_racecar/odom": ODOMETRY, "/drive": ACKERMANN_DRIVE_STAMPED})
for k in range(600):  # 30 s at 20 Hz (a lap), then a crash
    writer.write("/ego_racecar/odom", k * 50_000_000, odometry(k * 50_000_000, 0.1 * k))
    writer.write("/drive", k * 50_000_000, drive(k * 50_000_000))
writer.wait()
os.kill(os.getpid(), signal.SIGKILL)
"""


def _env(**extra: str) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(SRC), **extra}


@case(
    "lost.bag_recorder_kill9",
    GROUP,
    "a bag recorder killed with SIGKILL after 30 s: collect --from-bag imports all but the last seconds",
    GRACEFUL,
    problem="lost",
    see_also=("tests/learning/test_bag_stream.py",),
)
def bag_recorder_kill9(probe: Probe) -> Evidence:
    bag = probe.path("laps_bag")
    done = subprocess.run(
        [sys.executable, "-c", _RECORDER, str(bag)], env=_env(), capture_output=True, text=True, timeout=HANG
    )
    assert done.returncode == -signal.SIGKILL, done.stderr[-2000:]
    out = probe.path("laps.npz")
    run = probe.cli("collect", "--from-bag", str(bag), "--out", str(out))
    assert run.code == 0, run.err[-1000:]
    assert "a recording that never ended" in run.err, run.err
    from rkmpc.learning.data.dataset import TransitionDataset

    kept = len(TransitionDataset.load(out)) / 599
    assert kept >= 0.9, kept
    return Evidence(GRACEFUL, f"{kept:.0%} of 30 s imported; {run.err.strip().splitlines()[-1]}")


def _ros_environment(folder: Path) -> dict[str, str]:
    domain = ros_domain_id("probe.lost")
    return _env(
        ROS_DOMAIN_ID=str(domain),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        ROS_LOG_DIR=str(folder / "ros-log"),
    )


def _start(args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    with log.open("w") as out:
        return subprocess.Popen(
            [sys.executable, "-m", "rkmpc.cli", *args], env=env, stdout=out, stderr=subprocess.STDOUT
        )


@case(
    "lost.node_record_kill9",
    GROUP,
    "kill -9 of `rkmpc node --record BAG` after a lap of the loop test: at least 90 % of the lap imports",
    GRACEFUL,
    slow=True,
    problem="lost",
    see_also=(
        "tests/ros/test_loop.py::test_a_node_killed_with_sigkill_after_a_lap_leaves_a_bag_with_that_lap",
    ),
)
def node_record_kill9(probe: Probe) -> Evidence:
    import importlib.util

    if importlib.util.find_spec("rclpy") is None or importlib.util.find_spec("ackermann_msgs") is None:
        return Evidence(
            GRACEFUL, "ROS 2 not installed (make ros): replayed by tests/ros/test_loop.py when it is"
        )
    env, bag = _ros_environment(probe.tmp), probe.path("bag")
    node_args = ["node", "--config", str(REPO_CAR), "--controller", "lmpc", "--record", str(bag)]
    node_args += ["--ros-args", "-p", "trigger:=odometry", "-p", f"topics.steering:={STEERING}"]
    node = _start(node_args, env, probe.path("node.log"))
    try:
        sim_args = ["sim-node", "--clock", "lockstep", "--laps", "1", "--steering-topic", STEERING]
        sim_args += [
            "--startup-timeout",
            str(HANG),
            "--answer-timeout",
            str(HANG),
            "--out",
            str(probe.path("sim")),
        ]
        sim = _start(sim_args, env, probe.path("sim.log"))
        try:
            assert sim.wait(timeout=HANG) == 0, probe.path("sim.log").read_text()[-2000:]
        finally:
            if sim.poll() is None:
                sim.kill()
    finally:
        node.send_signal(signal.SIGKILL)
        node.wait(timeout=60)
    out = probe.path("lap.npz")
    run = probe.cli("collect", "--from-bag", str(bag), "--steer-topic", STEERING, "--out", str(out))
    assert run.code == 0 and "a recording that never ended" in run.err, run.err[-1000:]
    from rkmpc.learning.data.dataset import TransitionDataset
    from rkmpc.sim.log import StepLog

    driven = len(StepLog.from_csv(probe.path("sim") / "log.csv")) - 1
    kept = len(TransitionDataset.load(out))
    assert kept >= 0.9 * driven, (kept, driven)
    return Evidence(GRACEFUL, f"{kept} of the lap's {driven} transitions ({kept / driven:.0%}) imported")


def _full_disk(path: object, payload: object) -> None:
    raise OSError(28, "No space left on device", str(path))


@case(
    "lost.journal_full_disk",
    GROUP,
    "a study whose --journal cannot be written (disk full): it goes on, says so once, keeps its results",
    GRACEFUL,
    problem="lost",
    see_also=("tests/experiments/test_run_study.py",),
)
def journal_full_disk(probe: Probe) -> Evidence:
    journal, out = probe.path("journal"), probe.path("study")
    args = ["study", "tracks", "--tracks", "oval", "--controllers", "pp", "--seeds", "0,1", "--jobs", "1"]
    args += ["--journal", str(journal), "--out", str(out)]
    with mock.patch("rkmpc.experiments.journal.write_json_atomic", _full_disk):
        run = probe.cli(*args)
    assert run.code == 0, run.err[-1000:]
    text = " ".join(run.err.split())  # the console wraps long lines
    said = [f"journal {journal}:{part}".split(". ")[0] for part in text.split(f"journal {journal}:")[1:]]
    assert len(said) == 2 and "No space left on device" in said[0] and "goes on" in said[0], text[-1500:]
    assert "2 of 2 finished jobs not kept" in said[1], said
    assert (out / "study_tracks.json").is_file() and "Traceback" not in run.err
    return Evidence(GRACEFUL, said[0])


def _no_space(**_: object) -> object:
    return open("/dev/full", "wb")


@case(
    "lost.train_full_disk",
    GROUP,
    "train onto a full disk or an unwritable path: refused before training, naming the path",
    CLEAR_ERROR,
    problem="lost",
)
def train_full_disk(probe: Probe) -> Evidence:
    data, out = probe.path("laps.npz"), probe.path("models") / "m.rkm"
    lap().save(data)
    args = ["train", "--data", str(data), "--kind", "residual"]
    with (
        mock.patch("rkmpc.experiments.training.train_to_file") as training,
        mock.patch("rkmpc.core.io.tempfile.NamedTemporaryFile", _no_space),
    ):
        evidence = cli_error(
            probe, [*args, "--out", str(out)], f"cannot write {out}: No space left on device"
        )
    with mock.patch("rkmpc.experiments.training.train_to_file") as again:
        cli_error(probe, [*args, "--out", "/proc/m.rkm"], "cannot write /proc/m.rkm")
    assert not training.called and not again.called  # refused before any training
    assert not probe.path("models").exists()
    return evidence
