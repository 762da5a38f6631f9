"""The car file's ``[sensors]`` and ``[estimator]`` sections, and the ``--sensors`` flag (issue 25).

``[sensors] profile = NAME`` picks a named profile (:mod:`rkmpc.vehicle.sensors`), its parts'
fields are overridden by sub-tables (``[sensors.localiser] latency = 0.05``); ``[estimator]`` sets
:class:`~rkmpc.estimation.config.EstimatorConfig`. Every error names the file and the key.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from rkmpc.cli import build_parser
from rkmpc.cli.common import car_config
from rkmpc.config.loader import load_car_config, load_preset
from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.vehicle.sensors import get_sensor_profile


def _write(tmp_path: Path, text: str, name: str = "car.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_car_file_without_sensors_has_the_ideal_ones_and_the_default_estimator(tmp_path):
    car = load_car_config(_write(tmp_path, "[vehicle]\npreset = 'f1tenth'\n"))
    assert car.sensors.name == "ideal" and car.sensors.is_ideal
    assert car.estimator == EstimatorConfig()
    assert load_preset("f1tenth").sensors.is_ideal


def test_the_sensors_section_names_a_profile_and_overrides_its_parts(tmp_path):
    text = (
        "[sensors]\nprofile = 'f1tenth-real'\n"
        "[sensors.localiser]\nlatency = 0.05\njump_probability = 0.0\n"
        "[sensors.wheel_speed]\nscale = 1.05\n"
    )
    car = load_car_config(_write(tmp_path, text))
    real = get_sensor_profile("f1tenth-real")
    sensors = car.sensors
    assert sensors.name == "f1tenth-real" and not sensors.is_ideal
    assert not sensors.measures_steer_angle and not sensors.measures_slip_angle
    assert sensors.localiser.latency == 0.05 and sensors.localiser.jump_probability == 0.0
    assert sensors.wheel_speed.scale == 1.05
    # What the file leaves out is the named profile's.
    assert sensors.localiser.along_track_std == real.localiser.along_track_std
    assert sensors.localiser.min_interval == real.localiser.min_interval
    assert sensors.yaw_rate == real.yaw_rate
    assert sensors.wheel_speed.noise_std == real.wheel_speed.noise_std
    # The summary says what was changed; the result files record it.
    assert "changed: localiser.latency, localiser.jump_probability, wheel_speed.scale" in sensors.summary
    described = car.to_json()["sensors"]
    assert described["name"] == "f1tenth-real" and described["localiser"]["latency"] == 0.05


def test_a_profile_alone_is_the_named_profile(tmp_path):
    car = load_car_config(_write(tmp_path, "[sensors]\nprofile = 'f1tenth-real'\n"))
    assert car.sensors == get_sensor_profile("f1tenth-real")
    no_steer = load_car_config(_write(tmp_path, "[sensors]\nprofile = 'no-steer'\n", "b.toml"))
    assert no_steer.sensors == get_sensor_profile("no-steer") and no_steer.sensors.localiser is None


@pytest.mark.parametrize(
    ("text", "key", "problem"),
    [
        ("[sensors]\nprofile = 'f1tenth-rea'\n", "sensors.profile", "unknown sensor profile 'f1tenth-rea'"),
        ("[sensors]\nprofile = 3\n", "sensors.profile", "expected a non-empty string"),
        (
            "[sensors]\nprofile = 'f1tenth-real'\n[sensors.localiser]\nlatancy = 0.05\n",
            "sensors.localiser.latancy",
            "unknown field; known: along_track_std",
        ),
        (
            "[sensors]\nprofile = 'f1tenth-real'\n[sensors.wheel_speed]\nbias = 0.1\n",
            "sensors.wheel_speed.bias",
            "unknown field",
        ),
        ("[sensors]\ncamera = 1\n", "sensors.camera", "unknown setting; known: localiser"),
        (
            "[sensors]\nprofile = 'f1tenth-real'\n[sensors.localiser]\nlatency = -0.01\n",
            "sensors.localiser",
            "latency",
        ),
        # The ideal profile reports the true pose: it has no localiser to change.
        ("[sensors.localiser]\nlatency = 0.05\n", "sensors.localiser", "has no localiser"),
        ("sensors = 3\n", "sensors", "expected a section"),
        ("[estimator]\nposition_std = -1\n", "estimator.position_std", "must be finite and > 0"),
        ("[estimator]\nposition_sd = 0.1\n", "estimator.position_sd", "unknown key 'position_sd'"),
        ("[estimator]\nmax_rejections = 0\n", "estimator.max_rejections", "integer >= 1"),
        ("[estimator]\ngate_probability = 'high'\n", "estimator.gate_probability", "expected a number"),
    ],
)
def test_a_bad_sensors_or_estimator_setting_names_the_file_and_the_key(tmp_path, text, key, problem):
    path = _write(tmp_path, text)
    with pytest.raises(InputFileError) as info:
        load_car_config(path)
    message = str(info.value)
    assert message.startswith(f"{path} [{key}]: "), message
    assert problem in message
    assert info.value.field == key


def test_the_estimator_section_sets_its_fields_and_keeps_the_others(tmp_path):
    text = "[estimator]\nposition_std = 0.1\nmax_rejections = 4\nundersteer_gradient = 0.002\n"
    car = load_car_config(_write(tmp_path, text))
    assert car.estimator.position_std == 0.1 and car.estimator.max_rejections == 4
    assert car.estimator.understeer_gradient == 0.002
    assert car.estimator.yaw_std == EstimatorConfig().yaw_std
    assert car.to_json()["estimator"]["position_std"] == 0.1


def test_a_sensors_section_reads_from_yaml_too(tmp_path):
    pytest.importorskip("yaml", reason="PyYAML is not installed")
    text = "sensors:\n  profile: f1tenth-real\n  localiser: {latency: 0.04}\n"
    car = load_car_config(_write(tmp_path, text, "car.yaml"))
    assert car.sensors.name == "f1tenth-real" and car.sensors.localiser.latency == 0.04


# ---------------------------------------------------------------------------- --sensors


def _args(*argv: str):
    return build_parser().parse_args(["run", "--controller", "lmpc", *argv, "--out", "unused"])


def test_the_sensors_flag_picks_a_profile():
    assert car_config(_args()).sensors.is_ideal
    car = car_config(_args("--sensors", "f1tenth-real"))
    assert car.sensors == get_sensor_profile("f1tenth-real")
    assert car_config(_args("--sensors", "no-steer")).sensors.name == "no-steer"


def test_the_sensors_flag_wins_over_the_car_files(tmp_path):
    path = _write(tmp_path, "[sensors]\nprofile = 'f1tenth-real'\n[sensors.localiser]\nlatency = 0.05\n")
    from_file = car_config(_args("--config", str(path)))
    assert from_file.sensors.name == "f1tenth-real" and from_file.sensors.localiser.latency == 0.05
    assert car_config(_args("--config", str(path), "--sensors", "ideal")).sensors.is_ideal
    # The rest of the file is kept.
    assert car_config(_args("--config", str(path), "--sensors", "ideal")).source == str(path.resolve())
    # Naming the file's own profile keeps the file's changes to it.
    same = car_config(_args("--config", str(path), "--sensors", "f1tenth-real"))
    assert same.sensors == from_file.sensors and same.sensors.localiser.latency == 0.05


def test_an_unknown_sensors_flag_is_refused_naming_the_known_profiles():
    with pytest.raises(ParameterError, match=r"unknown sensor profile 'real'.*f1tenth-real"):
        car_config(_args("--sensors", "real"))
