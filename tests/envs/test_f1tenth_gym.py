"""rkmpc on the real F1TENTH gym v1.0.0: a track put into it in one call, its own observations read.

The gym is on no package index: ``make f1tenth-gym`` installs it from ``../shared/vendor`` (the
``test`` and ``test-slow`` targets do). Without it these tests skip.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

pytest.importorskip("gymnasium")
pytest.importorskip("f1tenth_gym", reason="the F1TENTH gym v1.0.0 is not installed: `make f1tenth-gym`")

from rkmpc.control.estimated import EstimatedController
from rkmpc.core.errors import ContractError, InputFileError, ParameterError
from rkmpc.envs.adapter import run_episode
from rkmpc.envs.f1tenth_gym import (
    gym_car,
    gym_map,
    gym_policy,
    gym_sensors,
    load_gym_track,
    make_gym_env,
    start_pose,
)
from rkmpc.envs.gym_map import DEFAULT_RESOLUTION
from rkmpc.estimation.labels import ESTIMATION_KEY
from rkmpc.experiments.training import estimated_for
from rkmpc.learning.data.augmentation import AugmentConfig
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.learn import learn
from rkmpc.learning.pipeline import TrainConfig, train_model
from rkmpc.learning.recipes import recipe_for
from rkmpc.sim.build import build_controller
from rkmpc.sim.scenario import Scenario

LAYOUTS = ("original", "dynamic_state")


@pytest.fixture(scope="module")
def map_dir(builtin_scenario, tmp_path_factory):
    """The built-in track as a gym map, with the reference the controllers track as its race line."""
    sc = builtin_scenario
    return gym_map(sc.track, tmp_path_factory.mktemp("gym-maps"), reference=sc.reference)


def _lmpc(scenario):
    return build_controller("lmpc", scenario)


def _start(scenario):
    return {"poses": start_pose(scenario.reference.path)}


def test_the_map_is_the_gyms_format_and_the_track(builtin_scenario, map_dir):
    sc = builtin_scenario
    assert sorted(p.name for p in map_dir.iterdir()) == [
        "builtin_centerline.csv",
        "builtin_map.png",
        "builtin_map.yaml",
        "builtin_raceline.csv",
    ]
    gym_track = load_gym_track(map_dir)
    assert gym_track.spec.resolution == DEFAULT_RESOLUTION
    # The gym's own lines: its spline through our centre line, and the race line with our speeds.
    assert gym_track.centerline.length == pytest.approx(sc.track.length, rel=2e-3)
    race = gym_track.raceline
    path = sc.reference.path
    np.testing.assert_allclose([race.xs[0], race.ys[0]], path.position(0.0), atol=1e-5)
    np.testing.assert_allclose(race.vxs[:50], sc.reference.profile.speed(race.ss[:50]), rtol=1e-5)
    np.testing.assert_allclose(race.yaws[:50], path.heading(race.ss[:50]), atol=1e-5)
    # Free cells are the track: points a few pixels away from its boundaries agree with rkmpc's check.
    occupancy, (x0, y0, _) = gym_track.occupancy_map, gym_track.spec.origin
    rng = np.random.default_rng(0)
    height, width = occupancy.shape
    size = DEFAULT_RESOLUTION * np.array([width, height])
    xy = np.array([x0, y0]) + rng.uniform(0.0, 1.0, (3000, 2)) * size
    checked = 0
    for x, y in xy:
        _, _, margin = sc.track.boundary_offsets(x, y)
        if abs(margin) < 3 * DEFAULT_RESOLUTION:
            continue
        free = occupancy[int((y - y0) / DEFAULT_RESOLUTION), int((x - x0) / DEFAULT_RESOLUTION)] == 255.0
        assert free == (margin > 0.0), (x, y, margin)
        checked += 1
    assert checked > 2500


def test_settings_the_gym_does_not_have_are_refused(builtin_scenario, map_dir, tmp_path):
    sc = builtin_scenario
    with pytest.raises(ParameterError, match="observation must be one of"):
        make_gym_env(sc, map_dir, observation="scans")
    with pytest.raises(ParameterError, match="model must be one of"):
        make_gym_env(sc, map_dir, model="mb")
    with pytest.raises(ParameterError, match=r"params\['mu'\] must be a finite number"):
        make_gym_env(sc, map_dir, params={"mu": math.nan})
    with pytest.raises(ParameterError, match=r"params\['grip'\]"):
        make_gym_env(sc, map_dir, params={"grip": 1.0})
    with pytest.raises(InputFileError, match="missing: not a map folder"):
        load_gym_track(tmp_path)
    with pytest.raises(ParameterError, match="resolution must be finite"):
        gym_map(sc.track, tmp_path, resolution=0.0)
    with pytest.raises(ParameterError, match="choose a coarser resolution"):
        gym_map(sc.track, tmp_path, resolution=1e-4)


@pytest.mark.parametrize("observation", LAYOUTS)
def test_the_gyms_own_observations_are_read_and_unmeasured_fields_are_nan(
    builtin_scenario, map_dir, observation
):
    sc = builtin_scenario
    env = make_gym_env(sc, map_dir, observation=observation, max_laps=1)
    policy = gym_policy(_lmpc(sc), env)
    assert policy.hold_steps == 5  # 0.05 s control period over the gym's 0.01 s steps
    episode = run_episode(env, policy, options=_start(sc), max_steps=150)
    assert episode.status_counts == {"ok": 30} and episode.info["outcome"] == "running"
    log = episode.log
    assert np.all(np.isfinite(log["yaw_rate"])) and log["speed"][-1] > 1.0
    # The last row is the gym's final observation; its true state is the gym's.
    state = env.gym_env.sim.agents[0].state  # x, y, delta, v, yaw, yaw rate, beta
    np.testing.assert_allclose([log["x"][-1], log["y"][-1]], state[:2], atol=1e-5)
    assert log["yaw_rate"][-1] == pytest.approx(state[5], abs=1e-5)
    data = episode.dataset()
    if observation == "original":
        # The gym gives no wheel angle and a fixed 0 lateral velocity: both NaN, never 0.
        assert episode.unmeasured == ("slip_angle", "steer_angle")
        assert np.all(np.isnan(data.obs[:, 5:])) and np.all(np.isnan(data.next_obs[:, 5:]))
        assert log["speed"][-1] == pytest.approx(state[3], rel=1e-6)  # the speed of the centre of gravity
    else:
        assert episode.unmeasured == ()
        wheel_and_slip = (log["steer_angle"][-1], log["slip_angle"][-1])
        assert wheel_and_slip == pytest.approx((state[2], state[6]), abs=1e-6)
        assert log["speed"][-1] == pytest.approx(state[3] * math.cos(state[6]), rel=1e-6)  # along the heading
        assert np.all(np.isfinite(data.obs))


@pytest.fixture(scope="module")
def small_residual_model(builtin_scenario, builtin_lap):
    """An ``rkmpc`` model in a second: the residual recipe's features (speed, yaw rate, wheel angle,
    past commands) with no lifting network, fitted by least squares on one LMPC lap."""
    sc = builtin_scenario
    config = TrainConfig(kind="residual", augment=AugmentConfig(ratio=0.2), model=KoopmanModel(None))
    model, _ = train_model(builtin_lap, sc.vehicle.wheelbase, config, vehicle=sc.vehicle_name)
    return model


def test_a_learned_controller_without_a_wheel_angle_falls_back_and_says_so(
    builtin_scenario, map_dir, small_residual_model, caplog
):
    """rkmpc's model reads the wheel angle; the gym's default observation has none: every step is the
    LMPC's command, counted as ``guard`` and reported, not passed off as the residual MPC."""
    sc = builtin_scenario
    controller = build_controller("rkmpc", sc, small_residual_model)
    env = make_gym_env(sc, map_dir)
    with caplog.at_level(logging.WARNING, logger="rkmpc.envs.adapter"):
        episode = run_episode(env, gym_policy(controller, env), options=_start(sc), max_steps=100)
    assert episode.status_counts == {"guard": 20}
    assert "rkmpc: 20 of 20 control steps (100.0 %) fell back (guard 20)" in caplog.text
    assert "not measured: slip_angle, steer_angle" in caplog.text
    # With the gym's dynamic_state the wheel angle is there, and the residual MPC drives.
    env = make_gym_env(sc, map_dir, observation="dynamic_state")
    episode = run_episode(env, gym_policy(controller, env), options=_start(sc), max_steps=100)
    assert episode.status_counts.get("guard", 0) == 0 and episode.fallback_count <= 1
    # ... unless it is declared unmeasured, as on a real car.
    policy = gym_policy(controller, env, unmeasured=("steer_angle",))
    assert run_episode(env, policy, options=_start(sc), max_steps=50).status_counts == {"guard": 10}


@pytest.mark.slow
@pytest.mark.parametrize("observation", LAYOUTS)
def test_the_lmpc_drives_a_lap_of_the_builtin_track_in_the_real_gym(builtin_scenario, map_dir, observation):
    """The documented loop: the track put into the gym by gym_map, the gym's own observations."""
    sc = builtin_scenario
    env = make_gym_env(sc, map_dir, observation=observation, max_laps=1)
    policy = gym_policy(_lmpc(sc), env)
    obs, info = env.reset(options=_start(sc))
    policy.reset()
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(policy(obs))
        done = terminated or truncated
    assert info["outcome"] == "max_laps" and not terminated
    (lap,) = info["completed_lap_times"]
    assert 25.0 < lap < 32.0  # from a standing start (27.5 s flying in rkmpc's own closed loop)
    assert policy.status_counts == {"ok": len(policy.log())}
    log = policy.log(obs)
    _, lateral = sc.reference.path.project_many(np.column_stack([log["x"], log["y"]]))
    assert np.mean(np.abs(lateral)) < 0.04 and np.max(np.abs(lateral)) < 0.12
    unmeasured = {"original": ("slip_angle", "steer_angle"), "dynamic_state": ()}[observation]
    nan = [f for f in ("yaw_rate", "slip_angle", "steer_angle") if np.all(np.isnan(log[f]))]
    assert nan == list(unmeasured)


@pytest.mark.slow
def test_a_shared_track_at_one_tenth_goes_into_the_gym(shared_tracks, tmp_path):
    """Monza at scale 0.1 (579 m, about 1.2 m wide): its map, and the LMPC driving 20 s on it in the gym."""
    from rkmpc.sim.scenario import load_scenario

    sc = load_scenario(shared_tracks / "centerlines" / "Monza.csv")
    folder = gym_map(sc.track, tmp_path, reference=sc.reference)
    assert folder.name == "Monza"
    env = make_gym_env(sc, folder, max_laps=1)
    assert env.gym_env.track.centerline.length == pytest.approx(sc.track.length, rel=2e-3)
    episode = run_episode(env, gym_policy(_lmpc(sc), env), options=_start(sc), max_steps=2000)
    assert episode.info["outcome"] == "running" and episode.status_counts == {"ok": 400}
    assert episode.info["progress_laps"] > 0.08 and abs(episode.info["lateral_error"]) < 0.1


def test_the_gyms_sensors_are_a_profile_and_its_car_declares_them():
    assert gym_sensors() == "no-steer"  # no wheel angle, no side-slip
    assert gym_sensors("dynamic_state") == "ideal"
    assert gym_sensors("dynamic_state", unmeasured=("steer_angle",)) == "no-steer"
    assert gym_sensors("dynamic_state", model="ks") == "no-steer"  # its yaw rate is a placeholder
    car = gym_car()
    assert car.sensors.name == "no-steer" and car.plant.car == "gym" and car.preset == "f1tenth"
    assert gym_car(observation="dynamic_state").sensors.is_ideal
    with pytest.raises(ParameterError, match="observation must be one of"):
        gym_sensors("scans")
    with pytest.raises(ParameterError, match="model must be one of"):
        gym_car(model="mb")


@pytest.fixture(scope="module")
def gym_scenario():
    """The built-in track for the car that drives in the gym: its sensors, its plant."""
    return Scenario.from_car(gym_car(), "builtin")


@pytest.fixture(scope="module")
def gym_residual(gym_scenario, map_dir):
    """An ``rkmpc`` model learned in seconds from 10 s of the LMPC in the gym, as documented: the data
    set of the episode (no wheel angle), the estimator's smoothed states, least squares only."""
    sc = gym_scenario
    env = make_gym_env(sc, map_dir)
    episode = run_episode(
        env, gym_policy(build_controller("lmpc", sc), env), options=_start(sc), max_steps=1000
    )
    data = episode.dataset(made_with=sc.provenance())
    recipe = recipe_for("rkmpc")
    learned = learn(
        recipe,
        estimated_for(recipe, data, sc.vehicle, sc.car.estimator),
        made_for=sc.provenance(),
        vehicle=sc.vehicle,
        model=KoopmanModel(None),
        augment=AugmentConfig(ratio=0.2),
    )
    return data, learned.model


def test_rkmpc_built_for_the_gyms_sensors_drives_through_the_estimator(gym_scenario, map_dir, gym_residual):
    """The documented way: the controller built for the gym's car stands behind the state estimator,
    which fills the wheel angle the gym does not give, so the residual MPC drives (no ``guard``)."""
    sc = gym_scenario
    data, model = gym_residual
    assert np.all(np.isnan(data.obs[:, 5:]))  # recorded: no slip, no wheel angle
    estimation = model.metadata_["data_metadata"][ESTIMATION_KEY]
    assert estimation["steering"]["max_angle_rad"] == sc.vehicle.steering.max_angle
    controller = build_controller("rkmpc", sc, model)
    assert isinstance(controller, EstimatedController)
    assert controller.estimator.config.control_period == sc.dt
    env = make_gym_env(sc, map_dir)
    episode = run_episode(env, gym_policy(controller, env), options=_start(sc), max_steps=200)
    assert episode.status_counts == {"ok": 40}
    assert episode.unmeasured == ("slip_angle", "steer_angle")  # the raw observations, as the gym gives them
    assert math.isfinite(controller.estimate.steer_angle) and math.isfinite(controller.estimate.slip_angle)
    # The model's contract names the gym's car: refused for the project's own plant.
    with pytest.raises(ContractError, match=r"plant = 'gym'; this run uses plant = 'f1tenth'"):
        build_controller("rkmpc", Scenario.from_car(sc.car.with_zoo_car(None), "builtin"), model)


def _lap_two(env, scenario, controller):
    """Two laps from a standing start; the episode and the true lateral errors of the second lap."""
    progress = []
    episode = run_episode(
        env,
        gym_policy(controller, env),
        options=_start(scenario),
        max_steps=8000,
        on_step=lambda info: progress.append((info["progress_laps"], abs(info["lateral_error"]))),
    )
    rows = np.array(progress)
    return episode, rows[(rows[:, 0] >= 1.0) & (rows[:, 0] < 2.0), 1]


@pytest.mark.slow
def test_rkmpc_learned_from_two_lmpc_laps_in_the_gym_beats_the_lmpc(gym_scenario, map_dir, tmp_path):
    """The documented pipeline on the built-in track: two LMPC laps in the gym (no wheel angle), the
    residual model learned from the estimator's smoothed states, rkmpc driving behind the estimator."""
    from rkmpc.experiments.training import train_to_file
    from rkmpc.learning.io import load_model

    sc = gym_scenario
    env = make_gym_env(sc, map_dir, max_laps=2)
    lmpc, lmpc_lap = _lap_two(env, sc, build_controller("lmpc", sc))
    # max_laps=2 overrides the gym's own end, which comes some 0.3 m short of the second lap.
    assert lmpc.info["outcome"] == "max_laps" and len(lmpc.info["completed_lap_times"]) == 2
    data = lmpc.dataset(made_with=sc.provenance())
    made_for = sc.provenance()
    train_to_file(data, made_for, sc.vehicle, "residual", tmp_path / "r.npz", estimator=sc.car.estimator)
    model = load_model(tmp_path / "r.npz", "residual")
    rkmpc, rkmpc_lap = _lap_two(env, sc, build_controller("rkmpc", sc, model))
    assert rkmpc.info["outcome"] == "max_laps" and rkmpc.status_counts == {"ok": rkmpc.control_steps}
    # benchmarks/gym_study.py measures 0.0238 m (LMPC) and 0.0103 m (rkmpc) on this track (docs/gym.md).
    assert rkmpc_lap.mean() < 0.9 * lmpc_lap.mean()
