"""Drive any rkmpc controller in an environment with the F1TENTH gym's conventions, and record it.

The F1TENTH gym (and :class:`rkmpc.envs.f1tenth.F1TenthTrackEnv`) observe a dict of arrays with one
value per agent and take an action of shape ``(num_agents, 2)``, ``[steer (rad), speed (m/s)]``,
per physics step (0.01 s). rkmpc's controllers take an :class:`~rkmpc.core.observation.Observation`
and return a :class:`~rkmpc.core.observation.Command` once per control period (0.05 s).
:class:`ControllerPolicy` joins the two for one agent:

* the observation of agent ``agent`` becomes an ``Observation``: ``x, y, yaw`` from ``poses_x,
  poses_y, poses_theta``; ``speed`` (along the heading) is ``linear_vels_x``; the yaw rate is
  ``ang_vels_z``; the side-slip angle is ``atan2(linear_vels_y, linear_vels_x)``; the wheel angle
  is ``steering_angles`` when the observation has it, else NaN (not measured);
* its time stamp is the policy's own clock, the number of environment steps since
  :meth:`ControllerPolicy.reset` times ``timestep`` (the F1TENTH gym's ``lap_times`` stop when its
  laps are done, so they are not a clock);
* the controller is stepped on the first environment step of each control period and its command
  is held for ``hold_steps = control_period / timestep`` steps (an integer).

:func:`run_episode` drives one episode with a policy and keeps, per control period, the
observation the controller saw and the command it sent (a :class:`~rkmpc.sim.log.StepLog`), from
which :meth:`Episode.dataset` builds a :class:`~rkmpc.learning.data.dataset.TransitionDataset` as
:func:`rkmpc.sim.collect.collect` does from the project's own closed loop. Nothing here needs
``gymnasium``: any environment with ``reset(seed=, options=)`` and ``step(action)`` works.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from rkmpc.control.base import Controller
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS, Command, Observation
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.learning.contract import CONTRACT_KEY, Provenance
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.sim.log import StepLog

__all__ = [
    "ControllerPolicy",
    "Episode",
    "F1TenthLikeEnv",
    "action_from_command",
    "observation_from_f1tenth",
    "run_episode",
]

#: Keys an F1TENTH observation must hold for :func:`observation_from_f1tenth`.
REQUIRED_KEYS = ("poses_x", "poses_y", "poses_theta", "linear_vels_x", "linear_vels_y", "ang_vels_z")
#: Columns of the log of :class:`ControllerPolicy`: time (s), the observation, the command.
LOG_COLUMNS = ("t", *OBSERVATION_FIELDS, "cmd_speed", "cmd_steer")
# Two periods whose ratio is this close to an integer are a whole number of steps.
_RATIO_TOL = 1e-6


class F1TenthLikeEnv(Protocol):
    """What :func:`run_episode` needs of an environment: Gymnasium's ``reset`` and ``step``."""

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]: ...

    def step(self, action: np.ndarray) -> tuple[Any, Any, bool, bool, dict[str, Any]]: ...


def _value(observation: Mapping[str, Any], key: str, agent: int) -> float:
    values = np.asarray(observation[key], dtype=np.float64).reshape(-1)
    if agent >= values.size:
        raise ParameterError(f"the observation's {key!r} has {values.size} agent(s); agent {agent} asked for")
    return float(values[agent])


def observation_from_f1tenth(
    observation: Mapping[str, Any], *, agent: int = 0, time: float = 0.0
) -> Observation:
    """The :class:`Observation` of agent ``agent`` in an F1TENTH-style observation dict.

    Parameters
    ----------
    observation : mapping
        ``poses_x, poses_y`` (m), ``poses_theta`` (rad), ``linear_vels_x, linear_vels_y`` (m/s, in
        the car's frame), ``ang_vels_z`` (rad/s), one value per agent; optionally
        ``steering_angles`` (rad).
    agent : int
        Index of the agent.
    time : float
        Time stamp of the observation (s).

    Raises
    ------
    ParameterError
        When a key is missing, the agent does not exist, or the pose or speed is not finite.
    """
    missing = [key for key in REQUIRED_KEYS if key not in observation]
    if missing:
        raise ParameterError(
            f"the observation lacks the F1TENTH keys {missing}; it has {sorted(observation)}"
        )
    x, y, yaw, vx, vy, r = (_value(observation, key, agent) for key in REQUIRED_KEYS)
    if not all(math.isfinite(v) for v in (x, y, yaw, vx)):
        raise ParameterError(
            f"agent {agent}'s pose and speed must be finite, got x={x}, y={y}, yaw={yaw}, vx={vx}"
        )
    steer = _value(observation, "steering_angles", agent) if "steering_angles" in observation else math.nan
    slip = math.atan2(vy, vx) if math.isfinite(vy) else math.nan
    return Observation(x=x, y=y, yaw=yaw, speed=vx, yaw_rate=r, slip_angle=slip, steer_angle=steer, time=time)


def action_from_command(command: Command) -> np.ndarray:
    """The F1TENTH action of one agent for ``command``: ``[[steer (rad), speed (m/s)]]``, shape (1, 2)."""
    return np.array([[command.steer, command.speed]], dtype=np.float64)


class ControllerPolicy:
    """An rkmpc controller as a policy of an F1TENTH-style environment (one agent).

    Call :meth:`reset` at the start of every episode (after the environment's ``reset``), then the
    policy once per environment step with the observation; it returns the action, shape (1, 2).

    Parameters
    ----------
    controller : Controller
        Any controller (:func:`rkmpc.control.make_controller`).
    timestep : float
        Duration of one environment step (s), > 0 (0.01 in the F1TENTH gym).
    control_period : float or None
        Period at which the controller is stepped (s); None for the period it plans with
        (``controller.dt``). Must be a whole number of ``timestep``.
    agent : int
        Index of the agent the controller drives in the observation.

    Attributes
    ----------
    hold_steps : int
        Environment steps each command is held for.
    """

    def __init__(
        self,
        controller: Controller,
        timestep: float,
        *,
        control_period: float | None = None,
        agent: int = 0,
    ) -> None:
        if not is_positive_number(timestep):
            raise ParameterError(f"ControllerPolicy: timestep must be finite and > 0, got {timestep!r}")
        period = controller.dt if control_period is None else control_period
        if period is None:
            raise ParameterError(
                f"ControllerPolicy: the controller {controller.name!r} plans with no period; "
                "give control_period"
            )
        if not is_positive_number(period):
            raise ParameterError(f"ControllerPolicy: control_period must be finite and > 0, got {period!r}")
        ratio = period / timestep
        if round(ratio) < 1 or abs(ratio - round(ratio)) > _RATIO_TOL * ratio:
            raise ParameterError(
                f"ControllerPolicy: the control period {period} s must be a whole number of environment "
                f"steps of {timestep} s"
            )
        if not is_integer(agent, 0):
            raise ParameterError(f"ControllerPolicy: agent must be an integer >= 0, got {agent!r}")
        self.controller = controller
        self.timestep = float(timestep)
        self.control_period = float(period)
        self.hold_steps = round(ratio)
        self.agent = int(agent)
        self._steps = 0
        self._command: Command | None = None
        self._rows: list[np.ndarray] = []

    def reset(self) -> None:
        """Start an episode: reset the controller, the clock and the record."""
        self.controller.reset()
        self._steps = 0
        self._command = None
        self._rows = []

    @property
    def time(self) -> float:
        """Time of the next observation the policy expects (s), from its own step count."""
        return self._steps * self.timestep

    def command(self, observation: Mapping[str, Any]) -> Command:
        """The command for this environment step: a new one at the start of each control period."""
        if self._command is None or self._steps % self.hold_steps == 0:
            obs = observation_from_f1tenth(observation, agent=self.agent, time=self.time)
            self._command = self.controller.step(obs)
            self._rows.append(np.array([obs.time, *obs.as_array(), self._command.speed, self._command.steer]))
        self._steps += 1
        return self._command

    def __call__(self, observation: Mapping[str, Any]) -> np.ndarray:
        """The action ``[[steer, speed]]`` (shape (1, 2)) for this step; one agent only.

        With several agents, drive the ego with :meth:`command` and build the
        ``(num_agents, 2)`` action yourself.
        """
        agents = np.asarray(observation["poses_x"]).size if "poses_x" in observation else 0
        if agents != 1:
            raise ParameterError(
                f"ControllerPolicy returns one agent's action; the observation has {agents} agent(s): "
                "use policy.command(observation) and build the (num_agents, 2) action"
            )
        return action_from_command(self.command(observation))

    def log(self, final_observation: Mapping[str, Any] | None = None) -> StepLog:
        """What the controller saw and sent, one row per control period (:data:`LOG_COLUMNS`).

        ``final_observation`` (the environment's observation after the last step) is added as a
        row without a command, so the last period makes a transition when it was driven in full
        (left out when its pose or speed is not finite: a car whose simulation diverged).
        """
        log = StepLog(LOG_COLUMNS, capacity=len(self._rows) + 1)
        for row in self._rows:
            log.append(row)
        if final_observation is not None:
            try:
                obs = observation_from_f1tenth(final_observation, agent=self.agent, time=self.time)
            except ParameterError:
                return log
            log.append(np.array([obs.time, *obs.as_array(), math.nan, math.nan]))
        return log


@dataclass
class Episode:
    """One episode driven by :func:`run_episode`.

    Parameters
    ----------
    log : StepLog
        One row per control period (:data:`LOG_COLUMNS`), the last one the final observation.
    control_period : float
        Period of the log's rows (s).
    steps : int
        Environment steps driven.
    total_reward : float
        Sum of the rewards.
    terminated, truncated : bool
        How the episode ended (both False when ``max_steps`` ended it).
    info : dict
        The environment's last ``info``.
    """

    log: StepLog
    control_period: float
    steps: int
    total_reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any] = field(default_factory=dict)

    def dataset(
        self, metadata: Mapping[str, Any] | None = None, made_with: Provenance | None = None
    ) -> TransitionDataset:
        """The episode's transitions at the control period (:meth:`TransitionDataset.from_log`).

        Parameters
        ----------
        metadata : mapping, optional
            Added to the data set's metadata (``source`` is ``"gym"`` unless given).
        made_with : Provenance, optional
            The car and track scale the data were recorded with (for the environments of
            :mod:`rkmpc.envs.f1tenth`, ``env.unwrapped.provenance()``); its period becomes the
            control period and the data set records it as its contract.
        """
        meta: dict[str, Any] = {
            "source": "gym",
            "steps": self.steps,
            "terminated": self.terminated,
            "truncated": self.truncated,
        }
        meta.update(metadata or {})
        if made_with is not None:
            meta[CONTRACT_KEY] = replace(made_with, dt=self.control_period).to_json()
        return TransitionDataset.from_log(self.log, metadata=meta, dt=self.control_period)


def run_episode(
    env: F1TenthLikeEnv,
    policy: ControllerPolicy,
    *,
    seed: int | None = None,
    options: dict[str, Any] | None = None,
    max_steps: int | None = None,
) -> Episode:
    """Reset ``env`` and ``policy`` and drive until the episode ends or ``max_steps`` steps.

    Parameters
    ----------
    env : F1TenthLikeEnv
        An environment with the F1TENTH gym's observation and action (one agent).
    policy : ControllerPolicy
        The controller and its hold; ``policy.timestep`` must be the environment's step.
    seed : int or None
        Passed to ``env.reset``.
    options : dict or None
        Passed to ``env.reset`` (for instance ``{"poses": ...}``).
    max_steps : int or None
        Largest number of environment steps (>= 1); None: until the environment ends the episode.
    """
    if max_steps is not None and not is_integer(max_steps, 1):
        raise ParameterError(f"run_episode: max_steps must be None or an integer >= 1, got {max_steps!r}")
    observation, info = env.reset(seed=seed, options=options)
    policy.reset()
    steps, total = 0, 0.0
    terminated = truncated = False
    while not (terminated or truncated) and (max_steps is None or steps < max_steps):
        observation, reward, terminated, truncated, info = env.step(policy(observation))
        total += float(reward)
        steps += 1
    return Episode(
        log=policy.log(observation),
        control_period=policy.control_period,
        steps=steps,
        total_reward=total,
        terminated=bool(terminated),
        truncated=bool(truncated),
        info=dict(info),
    )
