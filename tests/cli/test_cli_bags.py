"""``rkmpc collect --from-bag``: a bag in, a data set out, and clear errors without tracebacks."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rkmpc.cli import main
from rkmpc.learning.data.bags import BagWriteConfig, write_log_bag
from rkmpc.learning.data.dataset import TransitionDataset


@pytest.fixture(scope="module")
def bag(builtin_scenario, tmp_path_factory):
    """5 s of the LMPC on the built-in track as a ROS 1 bag, odometry of the rear axle, a steer topic."""
    from rkmpc.control.registry import make_controller
    from rkmpc.sim.closed_loop import SimConfig, simulate

    sc = builtin_scenario
    controller = make_controller("lmpc", sc.reference, sc.vehicle)
    log = simulate(sc.make_plant(0), controller, sc.track, sc.reference, SimConfig(dt=0.05, max_time=5.0)).log
    path = tmp_path_factory.mktemp("bags") / "lmpc.bag"
    config = BagWriteConfig(
        storage="ros1",
        odom_topic="/car_state/odom",
        steer_topic="/steer",
        odom_frame="rear-axle",
        lr=sc.vehicle.lr,
    )
    write_log_bag(path, log, config)
    return path, TransitionDataset.from_log(log, dt=0.05)


def test_collect_from_a_bag_writes_the_data_set(tmp_path, bag, capsys):
    path, ref = bag
    out = tmp_path / "data.npz"
    args = ["collect", "--from-bag", str(path), "--out", str(out), "--odom-topic", "/car_state/odom"]
    assert main([*args, "--steer-topic", "/steer", "--odom-frame", "rear-axle"]) == 0
    assert f"100 transitions in 1 episode(s) from {path}" in capsys.readouterr().out
    data = TransitionDataset.load(out)
    np.testing.assert_allclose(data.obs[:, :2], ref.obs[:, :2], atol=1e-9)
    assert data.metadata["bag"] == str(path) and data.metadata["odom_frame"] == "rear-axle"
    assert data.contract.vehicle == "f1tenth" and data.contract.dt == 0.05


@pytest.mark.parametrize(
    ("extra", "slip_measured"),
    [([], True), (["--sensors", "f1tenth-real"], False), (["--no-lateral-velocity"], False)],
)
def test_the_lateral_velocity_is_read_only_where_the_car_measures_it(tmp_path, bag, extra, slip_measured):
    path, _ = bag
    out = tmp_path / "data.npz"
    args = ["collect", "--from-bag", str(path), "--out", str(out), "--odom-topic", "/car_state/odom"]
    assert main([*args, *extra]) == 0
    data = TransitionDataset.load(out)
    moving = data.obs[:, 3] > 1.0
    assert moving.any() and np.isfinite(data.obs[moving, 5]).all() == slip_measured
    assert data.metadata["measured"]["lateral_velocity"] is slip_measured


def test_rkmpc_train_accepts_an_imported_data_set(tmp_path, bag, capsys):
    path, _ = bag
    data, model = tmp_path / "data.npz", tmp_path / "identified.json"
    args = ["collect", "--from-bag", str(path), "--out", str(data), "--odom-topic", "/car_state/odom"]
    assert main([*args, "--steer-topic", "/steer", "--odom-frame", "rear-axle"]) == 0
    assert main(["train", "--data", str(data), "--kind", "identified", "--out", str(model)]) == 0
    assert json.loads(model.read_text())["metadata"]["data_metadata"]["source"] == "bag"


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        ([], ["/ego_racecar/odom", "no such topic", "/car_state/odom (nav_msgs/msg/Odometry, 101)"]),
        (["--odom-topic", "/steer"], ["/steer", "std_msgs/msg/Float64, expected nav_msgs/msg/Odometry"]),
        (["--odom-topic", "/car_state/odom", "--min-samples", "500"], ["too little data: 100 transitions"]),
        (["--odom-topic", "/car_state/odom", "--from-log", "log.csv"], ["exclude each other"]),
        (["--odom-topic", "/car_state/odom", "--dt", "0"], ["BagImportConfig.dt"]),
    ],
)
def test_collect_from_a_bag_reports_problems_without_a_traceback(tmp_path, bag, capsys, extra, expected):
    path, _ = bag
    assert main(["collect", "--from-bag", str(path), "--out", str(tmp_path / "d.npz"), *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rkmpc: error: ") and "Traceback" not in err
    for text in expected:
        assert text in err
    assert not (tmp_path / "d.npz").exists()


def test_a_missing_bag(tmp_path, capsys):
    assert main(["collect", "--from-bag", str(tmp_path / "none"), "--out", str(tmp_path / "d.npz")]) == 2
    assert f"{tmp_path / 'none'}: file not found" in capsys.readouterr().err
