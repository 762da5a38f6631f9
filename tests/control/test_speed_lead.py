"""speed_lead: the MPC asks for the profile's speed that much later (a lagging speed loop brakes in time)."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.control import make_controller
from rkmpc.control.linear.lmpc import LMPCConfig
from rkmpc.control.settings import ControllerSettings
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Observation


def _braking_point(scenario) -> float:
    """An arc length where the reference speed falls over the next second."""
    profile = scenario.reference.profile
    s = np.linspace(0.0, scenario.reference.path.length, 400, endpoint=False)
    v = np.array([float(profile.speed(x)) for x in s])
    drop = v - np.roll(v, -8)
    return float(s[int(np.argmax(drop))])


def _on_path(scenario, s: float, speed: float) -> Observation:
    path = scenario.reference.path
    p = path.position(s)
    return Observation(
        x=float(p[0]), y=float(p[1]), yaw=float(path.heading(s)), speed=speed, yaw_rate=0.0, steer_angle=0.0
    )


def test_the_speed_asked_for_is_the_profiles_a_lead_later(builtin_scenario):
    sc = builtin_scenario
    s0 = _braking_point(sc)
    speed = float(sc.reference.profile.speed(s0))
    plain = make_controller("lmpc", sc.reference, sc.vehicle, settings=ControllerSettings(lmpc=LMPCConfig()))
    led = make_controller(
        "lmpc", sc.reference, sc.vehicle, settings=ControllerSettings(lmpc=LMPCConfig(speed_lead=0.5))
    )
    first = plain.step(_on_path(sc, s0, speed))
    early = led.step(_on_path(sc, s0, speed))
    assert plain.fallback_count == 0 and led.fallback_count == 0
    later = sc.reference.horizon(plain.projection.s, 40, 0.05).v[10]
    assert led.reference_speed == pytest.approx(later)
    assert led.reference_speed < plain.reference_speed - 0.05
    assert early.speed < first.speed - 0.05  # it brakes earlier


@pytest.mark.parametrize("lead", [-0.1, float("nan"), 11.0])
def test_a_lead_out_of_range_is_refused(lead):
    with pytest.raises(ParameterError, match="speed_lead"):
        LMPCConfig(speed_lead=lead)
