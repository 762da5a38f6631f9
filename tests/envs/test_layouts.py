"""Reading F1TENTH-style observations: what is measured is read, what is not is NaN, never 0."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from rkmpc.control.base import Controller
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command, Observation
from rkmpc.envs.adapter import ControllerPolicy, observation_from_f1tenth, run_episode
from rkmpc.envs.layouts import F1TENTH_GYM, GYM_FEATURES, RKMPC_ENV, detect_layout


def _flat(n=1, **values):
    base = {key: np.zeros(n, dtype=np.float32) for key in ("poses_x", "poses_y", "poses_theta", "ang_vels_z")}
    base["linear_vels_x"] = np.full(n, 2.0, dtype=np.float32)
    base["linear_vels_y"] = np.zeros(n, dtype=np.float32)
    base.update({k: np.asarray(v, dtype=np.float32) for k, v in values.items()})
    return base


def _gym_default(n=1, **values):
    """The F1TENTH gym's default observation: lidar scans, ``linear_vels_y`` its fixed 0."""
    return {**_flat(n, **values), "ego_idx": 0, "scans": np.ones((n, 1080), dtype=np.float32)}


def _features(n=1, **values):
    """The gym's ``dynamic_state`` observation: one dict of float32 scalars per agent."""
    agent = {"pose_x": 1.0, "pose_y": 2.0, "delta": 0.1, "linear_vel_x": 3.0, "pose_theta": 0.5}
    agent.update(ang_vel_z=0.4, beta=0.02)
    agent.update(values)
    return {f"agent_{i}": {k: np.float32(v) for k, v in agent.items()} for i in range(n)}


def test_the_layout_is_found_from_the_observations_shape():
    assert detect_layout(_gym_default()) is F1TENTH_GYM
    assert detect_layout(_flat()) is RKMPC_ENV
    assert detect_layout(_features()) is GYM_FEATURES
    with pytest.raises(ParameterError, match="neither the F1TENTH gym's flat dict"):
        detect_layout({"x": 1.0})


def test_the_gyms_default_observation_leaves_slip_and_wheel_angle_unmeasured():
    obs = observation_from_f1tenth(_gym_default(ang_vels_z=[0.3]), time=0.1)
    assert (obs.speed, obs.time) == (2.0, 0.1)
    assert obs.yaw_rate == pytest.approx(0.3)
    # linear_vels_y is the gym's fixed 0: no side-slip angle of 0 is made of it.
    assert math.isnan(obs.slip_angle) and math.isnan(obs.steer_angle)
    assert F1TENTH_GYM.never_measured == ("slip_angle", "steer_angle")
    # The same values without the lidar are rkmpc's own environment, whose lateral velocity is measured.
    assert observation_from_f1tenth(_flat(linear_vels_y=[2.0])).slip_angle == pytest.approx(math.pi / 4)


def test_the_gyms_dynamic_state_reads_every_agent_and_its_wheel_and_slip_angles():
    obs = observation_from_f1tenth(_features(2), agent=1)
    assert (obs.x, obs.y, obs.speed) == pytest.approx((1.0, 2.0, 3.0))
    assert (obs.yaw, obs.yaw_rate, obs.slip_angle, obs.steer_angle) == pytest.approx((0.5, 0.4, 0.02, 0.1))
    assert GYM_FEATURES.agents(_features(3)) == 3
    # kinematic_state has no yaw rate or slip: NaN. A lateral velocity gives the slip when beta is absent.
    dynamic = _features()["agent_0"]
    kinematic = {"agent_0": {k: v for k, v in dynamic.items() if k not in ("ang_vel_z", "beta")}}
    obs = observation_from_f1tenth(kinematic)
    assert math.isnan(obs.yaw_rate) and math.isnan(obs.slip_angle) and obs.steer_angle == pytest.approx(0.1)
    kinematic["agent_0"]["linear_vel_y"] = np.float32(3.0)
    assert observation_from_f1tenth(kinematic).slip_angle == pytest.approx(math.pi / 4)
    # What a real car does not measure can be dropped though the gym gives it.
    real = GYM_FEATURES.without("steer_angle", "slip_angle")
    obs = real.read(_features())
    assert math.isnan(obs.steer_angle) and math.isnan(obs.slip_angle) and obs.yaw_rate == pytest.approx(0.4)
    with pytest.raises(ParameterError, match="unmeasured may name only"):
        GYM_FEATURES.without("x")
    with pytest.raises(ParameterError, match=r"agent 2 \('agent_2'\) asked for"):
        observation_from_f1tenth(_features(2), agent=2)
    with pytest.raises(ParameterError, match=r"lacks the features \['pose_theta'\]"):
        observation_from_f1tenth({"agent_0": {k: 0.0 for k in ("pose_x", "pose_y", "linear_vel_x")}})
    with pytest.raises(ParameterError, match="must be finite"):
        observation_from_f1tenth(_features(pose_x=math.nan))


class _Steady(Controller):
    """Sends 1 m/s straight; reports ``status`` for every step."""

    name = "steady"
    dt = 0.05

    def __init__(self, status="ok", needs=()):
        super().__init__()
        self._status = status
        self.measured_fields = needs

    def _reset(self):
        pass

    def _step(self, observation: Observation):
        return Command(1.0, 0.0), self._status, "made up"


class _Env:
    """A stand-in with the gym's per-agent observation: ``steps`` steps, then truncated."""

    def __init__(self, steps=20, agents=1):
        self.steps, self.agents, self.k = steps, agents, 0

    def reset(self, *, seed=None, options=None):
        self.k = 0
        return _features(self.agents, pose_x=0.0), {}

    def step(self, action):
        self.k += 1
        return _features(self.agents, pose_x=0.01 * self.k), 0.01, False, self.k >= self.steps, {}


def test_the_policy_drives_the_gyms_per_agent_observation():
    policy = ControllerPolicy(_Steady(), 0.01)
    episode = run_episode(_Env(), policy)
    assert policy.layout is GYM_FEATURES and episode.status_counts == {"ok": 4}
    assert episode.fallback_count == 0 and episode.degraded() is None
    with pytest.raises(ParameterError, match="one agent's action; the observation has 2"):
        run_episode(_Env(agents=2), ControllerPolicy(_Steady(), 0.01))


def test_fallbacks_are_counted_reported_and_kept_in_the_data_set(caplog):
    policy = ControllerPolicy(_Steady(status="guard"), 0.01, layout=GYM_FEATURES.without("steer_angle"))
    with caplog.at_level(logging.WARNING, logger="rkmpc.envs.adapter"):
        episode = run_episode(_Env(steps=40), policy)
    assert episode.status_counts == {"guard": 8} and episode.fallback_count == 8
    assert episode.unmeasured == ("steer_angle",)
    message = episode.degraded()
    assert message == "steady: 8 of 8 control steps (100.0 %) fell back (guard 8); not measured: steer_angle"
    assert message in caplog.text
    assert list(episode.log["status"][:-1]) == [7.0] * 8 and math.isnan(episode.log["status"][-1])
    data = episode.dataset()
    assert np.all(np.isnan(data.obs[:, 6])) and np.all(np.isfinite(data.obs[:, :6]))
    assert data.metadata["status_counts"] == {"guard": 8} and data.metadata["unmeasured"] == ["steer_angle"]


def test_a_controller_that_needs_what_is_never_measured_is_refused_when_built():
    needs_wheel = _Steady(needs=("yaw_rate", "steer_angle"))
    with pytest.raises(ParameterError, match=r"needs \['steer_angle'\] measured, which the observation"):
        ControllerPolicy(needs_wheel, 0.01, layout=F1TENTH_GYM)
    ControllerPolicy(needs_wheel, 0.01, layout=RKMPC_ENV)  # its steering_angles give the wheel angle
    policy = ControllerPolicy(needs_wheel, 0.01)  # detected from the first observation: refused there
    policy.reset()
    with pytest.raises(ParameterError, match="f1tenth-gym"):
        policy(_gym_default())
