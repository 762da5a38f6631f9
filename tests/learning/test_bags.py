"""Bags: a simulated run written as ROS 1, ROS 2 sqlite3 and MCAP bags and imported back.

The run is 10 s of the LMPC on the built-in track (201 steps at 50 ms). Tolerances: odometry is
float64 on the wire and the samples fall on the odometry's stamps, so poses and rates come back to
rounding (1e-9); the commands are float32 in ``AckermannDrive``, so they come back to float32's
relative precision (2^-23 ~ 1.2e-7).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rkmpc.core.angles import wrap_angle
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.learning.data.bags import BagImportConfig, BagWriteConfig, import_bag, write_bag, write_log_bag
from rkmpc.learning.data.dataset import TransitionDataset

F32 = 2.0**-23
_SLIP = OBSERVATION_FIELDS.index("slip_angle")
_EXACT = [OBSERVATION_FIELDS.index(n) for n in ("x", "y", "speed", "yaw_rate", "steer_angle")]


@pytest.fixture(scope="module")
def run(builtin_scenario):
    """10 s of the LMPC on the built-in track: the step log and its transitions."""
    from rkmpc.control.registry import make_controller
    from rkmpc.sim.closed_loop import SimConfig, simulate

    sc = builtin_scenario
    controller = make_controller("lmpc", sc.reference, sc.vehicle)
    result = simulate(sc.make_plant(0), controller, sc.track, sc.reference, SimConfig(dt=0.05, max_time=10.0))
    return result.log, TransitionDataset.from_log(result.log, dt=0.05)


def _bag(tmp_path, storage: str) -> str:
    return str(tmp_path / ("run.bag" if storage == "ros1" else f"run_{storage}"))


def assert_same_transitions(data: TransitionDataset, ref: TransitionDataset, slip_speed: float = 0.5) -> None:
    """Observations to rounding, commands to float32, slip where the speed defines it."""
    assert len(data) == len(ref)
    np.testing.assert_array_equal(data.episode, ref.episode)
    for got, want in ((data.obs, ref.obs), (data.next_obs, ref.next_obs)):
        np.testing.assert_allclose(got[:, _EXACT], want[:, _EXACT], rtol=0, atol=1e-9)
        assert np.max(np.abs(wrap_angle(got[:, 2] - want[:, 2]))) < 1e-9
        fast = want[:, 3] >= slip_speed
        np.testing.assert_allclose(got[fast, _SLIP], want[fast, _SLIP], rtol=0, atol=1e-9)
        assert np.all(np.isnan(got[~fast, _SLIP]))
    np.testing.assert_allclose(data.command, ref.command, rtol=F32, atol=1e-12)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3", "ros1"])
def test_round_trip_reproduces_the_run(tmp_path, builtin_scenario, run, storage):
    log, ref = run
    path = _bag(tmp_path, storage)
    write_log_bag(path, log, BagWriteConfig(storage=storage, steer_topic="/steer", start_time=1.7e9))
    data = import_bag(path, builtin_scenario.vehicle, BagImportConfig(steer_topic="/steer"))
    assert_same_transitions(data, ref)
    meta = data.metadata
    assert meta["source"] == "bag" and meta["bag_storage"] == {"ros1": "ros1"}.get(storage, f"ros2-{storage}")
    assert meta["topics"] == {"odom": "/ego_racecar/odom", "drive": "/drive", "steer": "/steer"}
    assert meta["frames"] == {"frame_id": "map", "child_frame_id": "ego_racecar/base_link"}
    assert meta["messages"] == {"odom": len(log), "drive": len(log), "steer": len(log)}
    assert meta["start_stamp"] == pytest.approx(1.7e9)
    contract = data.contract
    assert (contract.vehicle, contract.dt, contract.wheelbase) == (
        "f1tenth",
        0.05,
        builtin_scenario.vehicle.wheelbase,
    )
    assert "speed" in contract.features
    # The data set saves and loads like any other.
    data.save(tmp_path / "data.npz")
    assert TransitionDataset.load(tmp_path / "data.npz").content_hash() == data.content_hash()


def test_a_ros2_bag_file_stands_for_its_folder(tmp_path, builtin_scenario, run):
    path = tmp_path / "run"
    write_log_bag(path, run[0])
    (inner,) = path.glob("*.mcap")
    assert len(import_bag(inner, builtin_scenario.vehicle)) == len(run[1])


def test_without_a_steer_topic_the_wheel_angle_is_not_measured(tmp_path, builtin_scenario, run):
    path = _bag(tmp_path, "mcap")
    write_log_bag(path, run[0])
    data = import_bag(path, builtin_scenario.vehicle)
    assert np.all(np.isnan(data.obs[:, OBSERVATION_FIELDS.index("steer_angle")]))
    assert data.metadata["messages"]["steer"] is None


def test_a_late_pose_is_recorded_for_the_labels_smoother(tmp_path, builtin_scenario, run):
    from rkmpc.core.errors import ParameterError
    from rkmpc.estimation.labels import ESTIMATION_KEY
    from rkmpc.experiments.training import estimated_for
    from rkmpc.learning.recipes import recipe_of_kind

    path = _bag(tmp_path, "mcap")
    write_log_bag(path, run[0])
    assert import_bag(path, builtin_scenario.vehicle).metadata["pose_latency"] == 0.0
    late = import_bag(path, builtin_scenario.vehicle, BagImportConfig(pose_latency=0.03))
    assert late.metadata["pose_latency"] == 0.03
    # No wheel angle in the bag: the residual learns from the smoother's states, the poses dated back.
    estimated = estimated_for(recipe_of_kind("residual"), late, builtin_scenario.vehicle)
    assert estimated.metadata[ESTIMATION_KEY]["pose_latency_s"] == 0.03
    with pytest.raises(ParameterError, match="pose_latency"):
        BagImportConfig(pose_latency=-0.01)


def test_servo_gain_and_offset_give_the_wheel_angle(tmp_path, builtin_scenario, run):
    """A VESC ``servo_position_command`` topic (``gain * angle + offset``) read back as the angle."""
    log, ref = run
    gain, offset = -1.2135, 0.5304
    servo = {name: np.asarray(log[name]) for name in log.columns}
    obs = np.stack([servo[n] for n in OBSERVATION_FIELDS], axis=1)
    obs[:, -1] = gain * obs[:, -1] + offset
    command = np.stack([servo["cmd_speed"], servo["cmd_steer"]], axis=1)
    path = _bag(tmp_path, "mcap")
    write_bag(path, servo["t"], obs, command, BagWriteConfig(steer_topic="/sensors/servo_position_command"))
    config = BagImportConfig(
        steer_topic="/sensors/servo_position_command", steer_gain=gain, steer_offset=offset
    )
    data = import_bag(path, builtin_scenario.vehicle, config)
    np.testing.assert_allclose(data.obs[:, -1], ref.obs[:, -1], rtol=0, atol=1e-12)


def test_commands_stamped_after_their_odometry_set_the_sampling_instants(tmp_path, builtin_scenario, run):
    """Commands 10 ms after their odometry: samples at the commands' stamps, poses interpolated."""
    log, ref = run
    path = _bag(tmp_path, "mcap")
    write_log_bag(path, log, BagWriteConfig(command_delay=0.01))
    data = import_bag(path, builtin_scenario.vehicle)
    assert len(data) == len(ref) - 1  # the last sample (9.96 s) has no successor within the odometry
    np.testing.assert_allclose(data.command, ref.command[:-1], rtol=F32, atol=1e-12)
    t = np.asarray(log["t"])
    for name in ("x", "y", "speed", "yaw_rate"):
        want = np.interp(t[:-2] + 0.01, t, np.asarray(log[name]))
        np.testing.assert_allclose(data.obs[:, OBSERVATION_FIELDS.index(name)], want, atol=1e-9)


def test_odometry_is_interpolated_onto_the_control_period(tmp_path, builtin_scenario):
    """A circle driven at 2 m/s on a 1 m radius, odometry at 100 Hz, samples 3 ms off its stamps.

    The heading passes +-pi twice (unwrapped before interpolating). Linear interpolation of a
    circle between points h = 10 ms apart errs by at most v^2 h^2 / (8 R) = 5e-5 m; the heading
    (linear in time), the speed and the yaw rate (constant) come back exactly.
    """
    v, radius = 2.0, 1.0
    omega = v / radius
    t = np.arange(400) * 0.01
    yaw = omega * t
    obs = np.stack(
        [radius * np.sin(yaw), radius * (1 - np.cos(yaw)), yaw, np.full_like(t, v), np.full_like(t, omega),
         np.zeros_like(t), np.full_like(t, np.nan)],
        axis=1,
    )  # fmt: skip
    command = np.full((len(t), 2), np.nan)
    every = np.arange(2, len(t), 5)  # one command every 50 ms
    command[every] = np.stack([v + 0.01 * every, 0.3 + 1e-3 * every], axis=1)
    path = _bag(tmp_path, "mcap")
    write_bag(path, t, obs, command, BagWriteConfig(command_delay=0.003))
    data = import_bag(path, builtin_scenario.vehicle)
    sample_t = 0.023 + 0.05 * np.arange(len(data))
    assert len(data) == 79
    assert np.max(np.hypot(data.obs[:, 0] - radius * np.sin(omega * sample_t),
                           data.obs[:, 1] - radius * (1 - np.cos(omega * sample_t)))) < 5.1e-5  # fmt: skip
    assert np.max(np.abs(wrap_angle(data.obs[:, 2] - omega * sample_t))) < 1e-9
    np.testing.assert_allclose(data.obs[:, 3:6], [[v, omega, 0.0]] * len(data), atol=1e-9)
    np.testing.assert_allclose(data.command, command[every[: len(data)]], rtol=F32)


def test_rear_axle_odometry_is_moved_to_the_centre_of_gravity(tmp_path, builtin_scenario, run):
    log, ref = run
    vehicle = builtin_scenario.vehicle
    path = _bag(tmp_path, "mcap")
    write_log_bag(path, log, BagWriteConfig(odom_frame="rear-axle", lr=vehicle.lr, steer_topic="/steer"))
    moved = import_bag(path, vehicle, BagImportConfig(odom_frame="rear-axle", steer_topic="/steer"))
    assert_same_transitions(moved, ref)
    # Read as if it were the centre of gravity: the pose is lr behind it, the slip is the rear axle's.
    as_is = import_bag(path, vehicle, BagImportConfig(odom_frame="cog", steer_topic="/steer"))
    np.testing.assert_allclose(np.hypot(*(as_is.obs[:, :2] - ref.obs[:, :2]).T), vehicle.lr, atol=1e-9)
    turning = np.abs(ref.obs[:, 4]) > 0.5
    assert np.all(np.abs(as_is.obs[turning, _SLIP] - ref.obs[turning, _SLIP]) > 1e-3)


def test_an_odometry_gap_starts_a_new_episode(tmp_path, builtin_scenario, run):
    log, ref = run
    rows = {name: np.asarray(log[name]) for name in log.columns}
    obs = np.stack([rows[n] for n in OBSERVATION_FIELDS], axis=1)
    command = np.stack([rows["cmd_speed"], rows["cmd_steer"]], axis=1)
    keep = np.ones(len(obs), dtype=bool)
    keep[80:90] = False  # 0.55 s without odometry (nor commands): longer than 3 periods
    keep[150] = False  # 0.1 s: shorter, interpolated over
    path = _bag(tmp_path, "mcap")
    write_bag(path, rows["t"][keep], obs[keep], command[keep], BagWriteConfig(steer_topic="/steer"))
    data = import_bag(path, builtin_scenario.vehicle, BagImportConfig(steer_topic="/steer"))
    assert np.bincount(data.episode).tolist() == [79, 110]
    first, second = data.episode == 0, data.episode == 1
    same = np.arange(len(ref)) != 150  # row 150's command was not recorded: 149's is held over it
    np.testing.assert_allclose(data.obs[first], ref.obs[:79], atol=1e-9)
    np.testing.assert_allclose(data.obs[second][:, _EXACT], ref.obs[90:][:, _EXACT], atol=0.02)
    np.testing.assert_allclose(data.command[second][same[90:]], ref.command[90:][same[90:]], rtol=F32)
    # A shorter threshold splits at the 0.1 s gap too.
    split = import_bag(path, builtin_scenario.vehicle, BagImportConfig(max_gap=0.08))
    assert np.bincount(split.episode).tolist() == [79, 59, 49]


def test_the_learning_code_accepts_an_imported_data_set(tmp_path, builtin_scenario, run):
    from rkmpc.learning.data.augmentation import AugmentConfig, local_frame_windows
    from rkmpc.learning.data.residuals import control_residuals
    from rkmpc.learning.pipeline import training_arrays

    log, ref = run
    path = _bag(tmp_path, "ros1")
    write_log_bag(path, log, BagWriteConfig(storage="ros1", steer_topic="/steer"))
    data = import_bag(path, builtin_scenario.vehicle, BagImportConfig(steer_topic="/steer"))
    wheelbase = builtin_scenario.vehicle.wheelbase
    labels = control_residuals(data, wheelbase)
    np.testing.assert_allclose(labels.delta, control_residuals(ref, wheelbase).delta, atol=1e-6)
    windows = local_frame_windows(data, AugmentConfig(ratio=0.3, seed=0))
    states, inputs, outputs = training_arrays(data, wheelbase, "residual", windows)
    assert outputs is not None and states.shape[0] == inputs.shape[0] == outputs.shape[0] > 0
    assert np.all(np.isfinite(states)) and np.all(np.isfinite(outputs))
    # What `rkmpc train` checks first: the data were made with this car and period.
    assert data.contract.check(builtin_scenario.provenance(), source=path, made="recorded") == ()


def test_the_writer_refuses_what_no_bag_holds(tmp_path, run):
    from rkmpc.core.errors import ParameterError

    log, _ = run
    with pytest.raises(ParameterError, match=r"must end in \.bag"):
        write_log_bag(tmp_path / "run.mcap", log, BagWriteConfig(storage="ros1"))
    with pytest.raises(ParameterError, match="needs lr"):
        BagWriteConfig(odom_frame="rear-axle")
    t = np.array([0.0, 0.05])
    bad = np.zeros((2, 7))
    bad[1, 0] = math.nan
    with pytest.raises(ParameterError, match=r"obs\.x is not finite at row 1"):
        write_bag(tmp_path / "x", t, bad, np.zeros((2, 2)))
    write_log_bag(tmp_path / "once", log)
    with pytest.raises(FileExistsError, match="never overwritten"):
        write_log_bag(tmp_path / "once", log)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["once"]  # no temporary folder left behind
