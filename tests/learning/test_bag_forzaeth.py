"""A bag of a car the project never saw (issue 25): ForzaETH's topics, no steering topic; every kind trains.

One LMPC lap of the built-in track driven through a real F1TENTH car's sensors (``f1tenth-real``:
a late, noisy localiser, the VESC's speed, a biased gyro, no wheel angle) is recorded as an MCAP
bag with ForzaETH's race_stack topics: odometry on ``/car_state/odom`` (its lateral velocity 0, as
a VESC publishes it) and commands on ``/vesc/high_level/ackermann_cmd_mux/input/nav_1``. Imported
with those topics, it has no wheel angle in any row; every model kind is learned from it, the
Koopman kinds from the state estimator's smoothed estimates (with the servo identified from the
yaw rate's response to the commands).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rkmpc.core.errors import RkmpcError
from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.estimation.labels import ESTIMATION_KEY
from rkmpc.estimation.steering import SteeringModel
from rkmpc.experiments.training import estimated_for, train_to_file
from rkmpc.learning.data.bags import BagImportConfig, BagWriteConfig, import_bag, write_bag
from rkmpc.learning.io import load_any_model
from rkmpc.learning.learn import learn
from rkmpc.learning.recipes import recipe_of_kind
from rkmpc.sim.build import steering_of
from rkmpc.sim.run import RunSpec, drive
from rkmpc.sim.scenario import Scenario

ODOM = "/car_state/odom"
DRIVE = "/vesc/high_level/ackermann_cmd_mux/input/nav_1"
FORZAETH = BagImportConfig(odom_topic=ODOM, drive_topic=DRIVE, lateral_velocity=False)
_SLIP = OBSERVATION_FIELDS.index("slip_angle")
_STEER = OBSERVATION_FIELDS.index("steer_angle")


@pytest.fixture(scope="module")
def recorded(builtin_scenario, tmp_path_factory):
    """The lap through the real car's sensors, its bag, and the bag imported with ForzaETH's topics."""
    scenario = Scenario.from_car(builtin_scenario.car.with_sensors("f1tenth-real"), "builtin")
    log = drive(scenario, RunSpec("lmpc")).log
    obs = np.column_stack([log[name] for name in OBSERVATION_FIELDS])
    assert np.isnan(obs[:, _STEER]).all() and np.isnan(obs[:, _SLIP]).all()
    obs[:, _SLIP] = 0.0  # the VESC's odometry: twist.linear.y = 0
    command = np.column_stack([log["cmd_speed"], log["cmd_steer"]])
    bag = tmp_path_factory.mktemp("forzaeth") / "run"
    write_bag(bag, log["t"], obs, command, BagWriteConfig(odom_topic=ODOM, drive_topic=DRIVE))
    data = import_bag(bag, scenario.vehicle, FORZAETH, scale=scenario.track.scale)
    return scenario, log, bag, data


def test_the_bag_imports_with_forzaeths_topics_and_no_wheel_angle(recorded):
    scenario, log, _, data = recorded
    assert data.metadata["topics"] == {"odom": ODOM, "drive": DRIVE, "steer": None}
    assert data.metadata["messages"] == {"odom": len(log), "drive": len(log), "steer": None}
    # Every period of the lap, one episode.
    assert len(data) == len(log) - 1 and set(data.episode.tolist()) == {0}
    assert np.isnan(data.obs[:, _STEER]).all() and np.isnan(data.next_obs[:, _STEER]).all()
    # The odometry's lateral velocity of 0 is not a measurement: no side slip, not a side slip of 0.
    assert np.isnan(data.obs[:, _SLIP]).all() and data.metadata["measured"]["lateral_velocity"] is False
    assert np.isfinite(data.obs[:, :5]).all()
    np.testing.assert_allclose(data.obs[:, 0], log["x"][:-1], atol=1e-9)
    np.testing.assert_allclose(data.command[:, 1], log["cmd_steer"][:-1], rtol=2.0**-23, atol=1e-12)
    contract = data.contract
    assert (contract.vehicle, contract.dt, contract.scale) == ("f1tenth", 0.05, scenario.track.scale)


def test_read_as_measured_the_lateral_velocity_of_0_is_a_side_slip_of_0(recorded):
    scenario, _, bag, _ = recorded
    as_measured = BagImportConfig(odom_topic=ODOM, drive_topic=DRIVE)
    data = import_bag(bag, scenario.vehicle, as_measured, scale=scenario.track.scale)
    moving = data.obs[:, 3] > 1.0
    assert moving.any() and (data.obs[moving, _SLIP] == 0.0).all()


def test_the_simulators_topics_are_not_in_the_bag_and_the_error_names_the_ones_it_has(recorded):
    scenario, _, bag, _ = recorded
    with pytest.raises(
        RkmpcError, match=r"\[/ego_racecar/odom\]: no such topic; the bag has: /car_state/odom"
    ):
        import_bag(bag, scenario.vehicle)


def test_without_a_wheel_angle_the_model_learns_from_the_estimators_states(recorded):
    scenario, _, _, data = recorded
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        estimated = estimated_for(recipe_of_kind("residual"), data, scenario.vehicle)
    record = estimated.metadata[ESTIMATION_KEY]
    steering = SteeringModel.from_json(record["steering"])
    assert steering.max_angle == scenario.vehicle.steering.max_angle
    assert np.isfinite(estimated.obs).all() and len(estimated) >= 0.95 * len(data)
    counts = record["counts"]
    assert counts["poses_used"] > 0.9 * len(data) and counts["restarts_diverged"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["residual", "paper", "koopman", "identified"])
def test_every_kind_trains_from_the_bag(recorded, tmp_path, kind):
    scenario, _, _, data = recorded
    out = tmp_path / (f"{kind}.json" if kind == "identified" else f"{kind}.npz")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lines = train_to_file(
            data, scenario.provenance(), scenario.vehicle, kind, out, epochs=2, source=str(out)
        )
    assert out.is_file() and lines
    model = load_any_model(out)
    if kind == "identified":
        assert lines[0].startswith("identified servo ") and "fitted on the yaw rate" in lines[0]
        assert model.fitted_on == "yaw_rate" and model.status in ("identified", "nominal")
        assert json.loads(out.read_text())["metadata"]["data_metadata"]["source"] == "bag"
        return
    assert lines[0].startswith(f"{kind} model: ") and lines[1].startswith("held-out prediction error")
    # A residual model is shown beside no correction on the same windows (and was not refused).
    assert (kind == "residual") == any(line.startswith("no correction (U_p = the command)") for line in lines)
    metadata = model.metadata_["data_metadata"]
    assert metadata["source"] == "bag" and metadata["topics"]["odom"] == ODOM
    # Learned from the estimates: the steering they were propagated with is the one to drive with.
    recorded_steering = SteeringModel.from_json(metadata[ESTIMATION_KEY]["steering"])
    assert steering_of(model, scenario.vehicle) == recorded_steering


def test_learning_from_the_bag_as_recorded_is_refused_naming_the_wheel_angle(recorded):
    """What the issue found: without estimation, the residual model's wheel-angle feature is missing."""
    scenario, _, _, data = recorded
    with pytest.raises(RkmpcError, match=r"steer_angle"):
        learn(recipe_of_kind("residual"), data, made_for=scenario.provenance(), vehicle=scenario.vehicle)
