"""RosSettings: the ``[ros]`` section of a car file (topics, frames, rate, safety, latency, recording)."""

from __future__ import annotations

import math
from dataclasses import asdict

import pytest

from rkmpc.config.ros import (
    Frames,
    LatencySettings,
    OdometrySettings,
    RecordSettings,
    RosSettings,
    SafetySettings,
    Topics,
)
from rkmpc.core.errors import ParameterError


def test_the_defaults_are_the_f1tenth_simulators_conventions_and_the_papers_rate():
    ros = RosSettings()
    assert ros.topics == Topics(
        odometry="/ego_racecar/odom", drive="/drive", steering=None, diagnostics="/diagnostics"
    )
    assert ros.frames == Frames(map="map", drive="base_link")
    assert ros.odometry == OdometrySettings(pose="cog", reliability="reliable")
    assert ros.latency == LatencySettings(compensate=False, odometry=0.0, actuation=0.0)
    assert ros.safety == SafetySettings(
        odometry_timeout=0.5, max_lateral_error=1.0, max_heading_error=1.0, latch=True, max_speed=None
    )
    assert ros.record == RecordSettings(bag=None, storage="mcap")
    assert (ros.rate_hz, ros.trigger, ros.steering_estimate) == (20.0, "timer", False)
    assert math.isclose(ros.period, 0.05) and RosSettings(rate_hz=40.0).period == 0.025
    assert asdict(ros)["safety"]["odometry_timeout"] == 0.5


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: RosSettings(rate_hz=0.0), "rate_hz must be finite and > 0"),
        (lambda: RosSettings(rate_hz=math.inf), "rate_hz must be finite and > 0"),
        (lambda: RosSettings(trigger="sometimes"), r"trigger must be one of \['timer', 'odometry'\]"),
        (lambda: OdometrySettings(pose="front_axle"), r"pose must be one of \['cog', 'rear_axle'\]"),
        (lambda: OdometrySettings(reliability="maybe"), "reliability must be one of"),
        (lambda: LatencySettings(odometry=-0.01), "odometry must be finite and >= 0"),
        (lambda: LatencySettings(actuation=math.nan), "actuation must be finite and >= 0"),
        (lambda: SafetySettings(odometry_timeout=0.0), "odometry_timeout must be finite and > 0"),
        (lambda: SafetySettings(max_lateral_error=-1.0), "max_lateral_error"),
        (lambda: SafetySettings(max_heading_error=math.nan), "max_heading_error"),
        (lambda: SafetySettings(max_speed=0.0), "max_speed must be finite and > 0"),
        # Only max_speed may be left unset: a missing timeout or limit would leave the car unguarded.
        (lambda: SafetySettings(odometry_timeout=None), r"SafetySettings\.odometry_timeout must be"),
        (lambda: SafetySettings(max_lateral_error=None), r"SafetySettings\.max_lateral_error must be"),
        (lambda: RosSettings(rate_hz=None), r"RosSettings\.rate_hz must be finite and > 0"),
        (lambda: RosSettings(rate_hz=True), r"RosSettings\.rate_hz must be finite and > 0"),
        (lambda: RecordSettings(storage="ros1"), r"storage must be one of \['mcap', 'sqlite3'\]"),
    ],
)
def test_bad_settings_are_refused_naming_the_field(make, match):
    with pytest.raises(ParameterError, match=match):
        make()


def test_settings_are_keyword_only_and_frozen():
    with pytest.raises(TypeError):
        RosSettings(20.0)  # type: ignore[misc]
    ros = RosSettings()
    with pytest.raises(AttributeError):
        ros.rate_hz = 10.0  # type: ignore[misc]
    assert SafetySettings(max_speed=None).max_speed is None  # no clip beyond the controller's own
