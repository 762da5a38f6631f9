"""Sensor profiles: the ideal one changes nothing; the real F1TENTH one measures what it says."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.vehicle.params import f1tenth
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.plants.dynamic import DynamicPlant
from rkmpc.vehicle.sensors import (
    Localiser,
    SensedPlant,
    SensorProfile,
    WheelSpeedSensor,
    YawRateSensor,
    get_sensor_profile,
    sensor_profile_names,
)
from rkmpc.vehicle.zoo import get_car

REAL_LOGS = Path(__file__).resolve().parents[2].parent / "shared" / "real" / "f1tenth-car"
REAL = get_sensor_profile("f1tenth-real")
assert REAL.localiser is not None and REAL.wheel_speed is not None and REAL.yaw_rate is not None
LOCALISER = REAL.localiser


class _Line(Plant):
    """An exact test car: a straight line at constant speed and heading, whatever the command."""

    STATE_NAMES = ("x", "y", "yaw", "v")

    def __init__(self) -> None:
        self.params = f1tenth()
        self.reset(0.0, 0.0, 0.0, 0.0)

    def reset(self, x: float, y: float, yaw: float, speed: float, steer: float = 0.0) -> None:
        self._start = (x, y, yaw, speed)
        self._t = 0.0

    def step(self, command: Command, dt: float) -> None:
        self._t += dt

    def pose_at(self, t: float) -> tuple[float, float, float]:
        x, y, yaw, v = self._start
        return x + v * t * math.cos(yaw), y + v * t * math.sin(yaw), yaw

    def observe(self) -> Observation:
        x, y, yaw = self.pose_at(self._t)
        v = self._start[3]
        return Observation(x, y, yaw, v, yaw_rate=0.0, slip_angle=0.0, steer_angle=0.0, time=self._t)

    @property
    def state(self) -> np.ndarray:
        return np.array([*self.pose_at(self._t), self._start[3]])

    @property
    def time(self) -> float:
        return self._t

    @property
    def wheel_angle(self) -> float:
        return 0.0


def _line_run(
    profile: SensorProfile, seconds: float, dt: float, seed: int = 0, yaw: float = 0.7, speed: float = 2.0
) -> tuple[_Line, list[Observation]]:
    line = _Line()
    plant = profile.wrap(line, seed=seed)
    plant.reset(1.0, -2.0, yaw, speed, 0.0)
    observations = [plant.observe()]
    for _ in range(round(seconds / dt)):
        plant.step(Command(speed, 0.0), dt)
        observations.append(plant.observe())
    return line, observations


def _samples(line: _Line, observations: list[Observation]) -> tuple[np.ndarray, np.ndarray]:
    """The distinct localiser samples seen: their pose times (s) and pose errors (along, cross, heading)."""
    times, errors = [], []
    for obs in observations:
        if times and obs.pose_time == times[-1]:
            continue
        x, y, yaw = line.pose_at(obs.pose_time)
        dx, dy = obs.x - x, obs.y - y
        errors.append(
            (dx * math.cos(yaw) + dy * math.sin(yaw), -dx * math.sin(yaw) + dy * math.cos(yaw), obs.yaw - yaw)
        )
        times.append(obs.pose_time)
    return np.array(times), np.array(errors)


def _drive(plant: Plant, steps: int = 30) -> list[Observation]:
    plant.reset(0.0, 0.0, 0.0, 2.0, 0.05)
    out = [plant.observe()]
    for k in range(steps):
        plant.step(Command(2.0 + 0.5 * math.sin(k / 7), 0.2 * math.sin(k / 5)), 0.05)
        out.append(plant.observe())
    return out


def test_registry_and_unknown_name() -> None:
    assert sensor_profile_names()[:2] == ["ideal", "no-steer"]
    assert "f1tenth-real" in sensor_profile_names()
    with pytest.raises(ParameterError, match=r"'f1tenth-fake'.*ideal, no-steer, f1tenth-real"):
        get_sensor_profile("f1tenth-fake")
    for name in sensor_profile_names():
        description = get_sensor_profile(name).describe()
        assert json.loads(json.dumps(description))["name"] == name


def test_ideal_is_the_bare_plant_bit_for_bit() -> None:
    ideal = get_sensor_profile("ideal")
    assert ideal.is_ideal and not REAL.is_ideal
    plant = DynamicPlant()
    assert ideal.wrap(plant, seed=5) is plant
    assert _drive(ideal.wrap(DynamicPlant(), seed=5)) == _drive(DynamicPlant())


def test_no_steer_hides_the_angles_only() -> None:
    bare = _drive(DynamicPlant())
    sensed = _drive(get_sensor_profile("no-steer").wrap(DynamicPlant()))
    for true, obs in zip(bare, sensed, strict=True):
        assert math.isnan(obs.steer_angle) and math.isnan(obs.slip_angle) and math.isnan(obs.pose_time)
        assert (obs.x, obs.y, obs.yaw, obs.speed, obs.yaw_rate, obs.time) == (
            true.x,
            true.y,
            true.yaw,
            true.speed,
            true.yaw_rate,
            true.time,
        )


def test_real_profile_pose_is_late_and_angles_unmeasured() -> None:
    _, observations = _line_run(REAL, seconds=10.0, dt=0.05)
    assert observations[0].pose_time == 0.0  # the sample at reset counts as arrived
    late = observations[2:]
    assert all(math.isnan(o.steer_angle) and math.isnan(o.slip_angle) for o in late)
    age = np.array([o.time - o.pose_time for o in late])
    assert np.all(age >= LOCALISER.latency - 1e-9)
    assert np.all(age <= LOCALISER.latency + LOCALISER.max_interval + 1e-9)
    assert age.min() < LOCALISER.latency + 0.01


def test_sample_intervals_and_pose_noise() -> None:
    quiet = replace(REAL, localiser=replace(LOCALISER, jump_probability=0.0))
    line, observations = _line_run(quiet, seconds=30.0, dt=0.005)  # steps shorter than any interval
    times, errors = _samples(line, observations)
    intervals = np.diff(times)
    assert intervals.min() >= LOCALISER.min_interval - 1e-9
    assert intervals.max() <= LOCALISER.max_interval + 1e-9
    assert intervals.mean() == pytest.approx(LOCALISER.mean_interval, rel=0.03)
    std = errors[1:].std(axis=0)  # the sample at reset included: every sample is noisy
    expected = [LOCALISER.along_track_std, LOCALISER.cross_track_std, LOCALISER.heading_std]
    np.testing.assert_allclose(std, expected, rtol=0.1)
    np.testing.assert_allclose(errors.mean(axis=0), 0.0, atol=0.004)


def test_jumps_happen_at_the_stated_frequency_and_size() -> None:
    spiky = replace(LOCALISER, jump_probability=0.05, jump_recovery=0.0)
    line, observations = _line_run(replace(REAL, localiser=spiky), seconds=60.0, dt=0.005, seed=3)
    _, errors = _samples(line, observations)
    size = np.hypot(errors[:, 0], errors[:, 1])
    jumps = size > 0.12  # four along-track deviations; a jump is at least 0.2 m
    expected = spiky.jump_probability * len(size)
    assert abs(jumps.sum() - expected) < 4.0 * math.sqrt(expected)
    assert size[jumps].mean() == pytest.approx(spiky.mean_jump, rel=0.15)
    assert np.all(np.abs(errors[:, 2]) < 6 * spiky.heading_std)  # the heading does not jump


def test_real_profile_jumps_recover() -> None:
    line, observations = _line_run(REAL, seconds=240.0, dt=0.015, seed=1)
    _, errors = _samples(line, observations)
    big = np.hypot(errors[:, 0], errors[:, 1]) > 0.12
    onsets = int(np.sum(big[1:] & ~big[:-1]))
    expected = LOCALISER.jump_probability * len(big)  # about 14
    assert abs(onsets - expected) < 4.0 * math.sqrt(expected)
    assert big.sum() < 3 * onsets  # a jump decays within a few samples


def test_speed_scale_and_gyro_bias_show_in_the_means() -> None:
    _, observations = _line_run(REAL, seconds=20.0, dt=0.05, speed=3.0)
    speed = np.array([o.speed for o in observations])
    yaw_rate = np.array([o.yaw_rate for o in observations])
    assert speed.mean() / 3.0 == pytest.approx(REAL.wheel_speed.scale, abs=0.002)
    assert yaw_rate.mean() == pytest.approx(REAL.yaw_rate.bias, abs=0.004)
    assert speed.std() == pytest.approx(REAL.wheel_speed.noise_std, rel=0.15)
    assert yaw_rate.std() == pytest.approx(REAL.yaw_rate.noise_std, rel=0.15)


def test_seeded_reset_reseeds_and_seeds_differ() -> None:
    a = REAL.wrap(DynamicPlant(), seed=4)
    first = _drive(a)
    assert _drive(REAL.wrap(DynamicPlant(), seed=4)) == first
    assert _drive(a) == first  # reset re-seeds
    assert a.observe() is a.observe()
    other = _drive(REAL.wrap(DynamicPlant(), seed=5))
    assert [o.x for o in other] != [o.x for o in first]
    assert [o.pose_time for o in other] != [o.pose_time for o in first]


@pytest.mark.parametrize("car", ["gym", "home", "laggy-odom"])
def test_combines_with_zoo_cars(car: str) -> None:
    spec = get_car(car)
    sensed = REAL.wrap(spec.make_plant(seed=2), seed=2)
    assert isinstance(sensed, SensedPlant)
    observations = _drive(sensed, steps=40)
    assert all(math.isnan(o.steer_angle) for o in observations)
    assert all(math.isfinite(o.x) and math.isfinite(o.pose_time) for o in observations)
    # Steps split at the sample instants move the car as whole steps do: the sample clock keeps the
    # 1 ms integration grid (laggy-odom's own delay cuts pieces into parts off the grid: 1e-7 m apart).
    bare = spec.make_plant(seed=2)
    _drive(bare, steps=40)
    np.testing.assert_allclose(sensed.state, bare.state, rtol=0, atol=1e-9 if car != "laggy-odom" else 1e-6)
    json.dumps(REAL.describe())


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: replace(LOCALISER, along_track_std=-0.1), "along_track_std"),
        (lambda: replace(LOCALISER, heading_std=math.nan), "heading_std"),
        (lambda: replace(LOCALISER, jump_probability=1.5), "jump_probability"),
        (lambda: replace(LOCALISER, min_interval=0.0), "min_interval"),
        (lambda: replace(LOCALISER, max_interval=0.01), "max_interval"),
        (lambda: replace(LOCALISER, latency=True), "latency"),
        (lambda: Localiser(**{**asdict(LOCALISER), "resolution": 0.0}), "resolution"),
        (lambda: replace(LOCALISER, min_interval=0.0171, max_interval=0.0179), "resolution"),
        (lambda: WheelSpeedSensor(scale=0.0, noise_std=0.01), "scale"),
        (lambda: WheelSpeedSensor(scale=1.0, noise_std=-1.0), "noise_std"),
        (lambda: YawRateSensor(bias=math.inf, noise_std=0.0), "bias"),
        (lambda: YawRateSensor(bias=0.0, noise_std="0.1"), "noise_std"),
        (lambda: replace(REAL, measures_steer_angle=0), "measures_steer_angle"),
        (lambda: replace(REAL, localiser=WheelSpeedSensor(scale=1.0, noise_std=0.0)), "localiser"),
        (lambda: SensedPlant(DynamicPlant(), REAL, seed=-1), "seed"),
    ],
)
def test_bad_settings_name_the_field(make, field: str) -> None:
    with pytest.raises(ParameterError, match=field):
        make()


def test_overrides_change_one_setting_or_name_the_bad_one() -> None:
    slow = REAL.with_overrides({"localiser": {"latency": 0.1}, "measures_steer_angle": True})
    assert slow.localiser == replace(LOCALISER, latency=0.1)
    assert slow.measures_steer_angle and slow.wheel_speed == REAL.wheel_speed
    assert "localiser.latency" in slow.summary
    with pytest.raises(ParameterError, match=r"sensors\.localiser\.latence: unknown field"):
        REAL.with_overrides({"localiser": {"latence": 0.1}})
    with pytest.raises(ParameterError, match=r"sensors\.gps: unknown setting"):
        REAL.with_overrides({"gps": {}})
    with pytest.raises(ParameterError, match=r"sensors\.wheel_speed: .*scale"):
        REAL.with_overrides({"wheel_speed": {"scale": -1.0}})
    with pytest.raises(ParameterError, match=r"sensors\.localiser: the profile 'ideal' has no localiser"):
        get_sensor_profile("ideal").with_overrides({"localiser": {"latency": 0.1}})


def _csv(run: str, name: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    path = REAL_LOGS / run / f"{name}.csv"
    header = path.read_text().splitlines()[0].split(",")
    values = np.loadtxt(path, delimiter=",", skiprows=1)
    columns = {h: values[:, i] for i, h in enumerate(header) if h}
    return columns["s"] + 1e-9 * columns["ns"], columns


def test_real_profile_agrees_with_the_shared_logs() -> None:
    """The pose rate and the gyro's bias (its ``wz`` read as deg/s) measured again on the real runs."""
    if not REAL_LOGS.is_dir():
        pytest.skip("../shared/real/f1tenth-car is not present")
    intervals, standstill = [], []
    for run in ("DS2", "DS3"):
        pose_t, _ = _csv(run, "pfPoseData")
        dt = np.diff(pose_t)
        intervals.append(dt[dt < 0.5])
        imu_t, imu = _csv(run, "imuData")
        odom_t, odom = _csv(run, "odomData")
        still = np.interp(imu_t, odom_t, np.abs(odom["vx"])) == 0.0
        standstill.append(np.deg2rad(imu["wz"][still]))
    assert np.concatenate(intervals).mean() == pytest.approx(LOCALISER.mean_interval, rel=0.05)
    gyro = np.concatenate(standstill)
    assert gyro.mean() == pytest.approx(REAL.yaw_rate.bias, abs=0.0015)
    assert gyro.std() == pytest.approx(REAL.yaw_rate.noise_std, rel=0.15)
