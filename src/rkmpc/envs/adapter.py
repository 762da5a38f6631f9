"""Drive any rkmpc controller in an environment with the F1TENTH gym's conventions, and record it.

The F1TENTH gym (and :class:`rkmpc.envs.f1tenth.F1TenthTrackEnv`) observe a dict of arrays with one
value per agent and take an action of shape ``(num_agents, 2)``, ``[steer (rad), speed (m/s)]``,
per physics step (0.01 s). rkmpc's controllers take an :class:`~rkmpc.core.observation.Observation`
and return a :class:`~rkmpc.core.observation.Command` once per control period (0.05 s).
:class:`ControllerPolicy` joins the two for one agent:

* the observation of agent ``agent`` becomes an ``Observation`` through an
  :class:`~rkmpc.envs.layouts.ObservationLayout` (given, or found from the first observation by
  :func:`~rkmpc.envs.layouts.detect_layout`): ``x, y, yaw`` from ``poses_x, poses_y, poses_theta``,
  ``speed`` from ``linear_vels_x``, the yaw rate from ``ang_vels_z``, the side-slip angle from
  ``linear_vels_y`` where that is measured and the wheel angle from ``steering_angles`` (or the
  F1TENTH gym's per-agent features ``pose_x, ..., delta, beta``); whatever the environment does not
  measure is NaN, never 0;
* its time stamp is the policy's own clock, the number of environment steps since
  :meth:`ControllerPolicy.reset` times ``timestep`` (the F1TENTH gym's ``lap_times`` stop when its
  laps are done, so they are not a clock);
* the controller is stepped on the first environment step of each control period and its command
  is held for ``hold_steps = control_period / timestep`` steps (an integer);
* the status of every control step is kept (:data:`rkmpc.control.base.STATUSES`): a controller that
  falls back (a learned controller without the wheel angle it reads keeps its baseline, status
  ``"guard"``) is counted in :attr:`Episode.status_counts`, and :func:`run_episode` logs a warning
  when more than :data:`DEGRADED_SHARE` of the steps were fall-backs.

Any :class:`~rkmpc.control.base.Controller` drives, a wrapped one too: where the environment does
not measure a field (the F1TENTH gym's default observation has no wheel angle and no lateral
velocity), build the controller for a car that declares those sensors
(:func:`rkmpc.sim.build.build_controller` for a scenario whose car has ``with_sensors("no-steer")``):
it is then an :class:`~rkmpc.control.estimated.EstimatedController`, whose state estimator fills the
wheel angle from the commands and estimates the slip before the controller sees the observation.
Its estimator must step at the policy's control period (checked).

:func:`run_episode` drives one episode with a policy and keeps, per control period, the
observation the controller saw and the command it sent (a :class:`~rkmpc.sim.log.StepLog`), from
which :meth:`Episode.dataset` builds a :class:`~rkmpc.learning.data.dataset.TransitionDataset` as
:func:`rkmpc.sim.collect.collect` does from the project's own closed loop. Nothing here needs
``gymnasium``: any environment with ``reset(seed=, options=)`` and ``step(action)`` works.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Callable, Mapping
from typing import Any, Protocol

import numpy as np

from rkmpc.control.base import STATUS_CODES, STATUSES, Controller
from rkmpc.control.estimated import EstimatedController
from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import OBSERVATION_FIELDS, Command, Observation
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.envs.episode import DEGRADED_SHARE, Episode
from rkmpc.envs.layouts import ObservationLayout, detect_layout
from rkmpc.sim.log import StepLog

__all__ = [
    "DEGRADED_SHARE",
    "ControllerPolicy",
    "Episode",
    "F1TenthLikeEnv",
    "action_from_command",
    "observation_from_f1tenth",
    "run_episode",
]

_LOG = logging.getLogger(__name__)

#: Columns of the log of :class:`ControllerPolicy`: time (s), the observation, the command and the
#: step's status (its code in :data:`rkmpc.control.base.STATUS_CODES`; NaN on the final row).
LOG_COLUMNS = ("t", *OBSERVATION_FIELDS, "cmd_speed", "cmd_steer", "status")
# Two periods whose ratio is this close to an integer are a whole number of steps.
_RATIO_TOL = 1e-6


class F1TenthLikeEnv(Protocol):
    """What :func:`run_episode` needs of an environment: Gymnasium's ``reset`` and ``step``."""

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]: ...

    def step(self, action: np.ndarray) -> tuple[Any, Any, bool, bool, dict[str, Any]]: ...


def observation_from_f1tenth(
    observation: Mapping[str, Any],
    *,
    agent: int = 0,
    time: float = 0.0,
    layout: ObservationLayout | None = None,
) -> Observation:
    """The :class:`Observation` of agent ``agent`` in an F1TENTH-style observation.

    Parameters
    ----------
    observation : mapping
        Flat (``poses_x, poses_y`` (m), ``poses_theta`` (rad), ``linear_vels_x, linear_vels_y``
        (m/s, in the car's frame), ``ang_vels_z`` (rad/s), one value per agent; optionally
        ``steering_angles`` (rad)) or the F1TENTH gym's per-agent features.
    agent : int
        Index of the agent.
    time : float
        Time stamp of the observation (s).
    layout : ObservationLayout or None
        How to read it; None: :func:`~rkmpc.envs.layouts.detect_layout`.

    Raises
    ------
    ParameterError
        When a key is missing, the agent does not exist, or the pose or speed is not finite.
    """
    found = detect_layout(observation) if layout is None else layout
    return found.read(observation, agent=agent, time=time)


def _check_measured(controller: Controller, layout: ObservationLayout) -> None:
    """Refuse a controller that needs a field ``layout`` never measures (it would only ever fall back)."""
    missing = [name for name in controller.measured_fields if name in layout.never_measured]
    if missing:
        raise ParameterError(
            f"ControllerPolicy: the controller {controller.name!r} needs {missing} measured, which the "
            f"observation ({layout.name}) never gives; estimate them first (a controller that fills them "
            "from the commands, such as a state estimator wrapping it)"
        )


def _check_estimator_period(controller: Controller, period: float) -> None:
    """Refuse a state estimator whose wheel-angle model steps with another period than the policy's."""
    if not isinstance(controller, EstimatedController):
        return
    own = controller.estimator.config.control_period
    if not math.isclose(own, period, rel_tol=_RATIO_TOL):
        raise ParameterError(
            f"ControllerPolicy: the state estimator of {controller.name!r} propagates the wheel angle "
            f"every {own} s, the policy steps the controller every {period} s; build the controller "
            "for a scenario with the policy's period (rkmpc.sim.build.build_controller)"
        )


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
    layout : ObservationLayout or None
        How the environment's observation reads (:mod:`rkmpc.envs.layouts`); None: found from the
        first observation (:func:`~rkmpc.envs.layouts.detect_layout`) and kept.

    Attributes
    ----------
    hold_steps : int
        Environment steps each command is held for.
    layout : ObservationLayout or None
        The layout in use (None until the first observation when it is detected).
    """

    def __init__(
        self,
        controller: Controller,
        timestep: float,
        *,
        control_period: float | None = None,
        agent: int = 0,
        layout: ObservationLayout | None = None,
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
        _check_estimator_period(controller, float(period))
        self.controller = controller
        self.timestep = float(timestep)
        self.control_period = float(period)
        self.hold_steps = round(ratio)
        self.agent = int(agent)
        if layout is not None:
            _check_measured(controller, layout)
        self.layout = layout
        self._detect = layout is None
        self._steps = 0
        self._command: Command | None = None
        self._rows: list[np.ndarray] = []

    def reset(self) -> None:
        """Start an episode: reset the controller, the clock and the record."""
        self.controller.reset()
        self._steps = 0
        self._command = None
        self._rows = []
        if self._detect:
            self.layout = None

    @property
    def time(self) -> float:
        """Time of the next observation the policy expects (s), from its own step count."""
        return self._steps * self.timestep

    def _layout(self, observation: Mapping[str, Any]) -> ObservationLayout:
        if self.layout is None:
            layout = detect_layout(observation)
            _check_measured(self.controller, layout)
            self.layout = layout
        return self.layout

    def read(self, observation: Mapping[str, Any]) -> Observation:
        """The controller's :class:`Observation` of ``observation``, stamped with the policy's clock."""
        return self._layout(observation).read(observation, agent=self.agent, time=self.time)

    def command(self, observation: Mapping[str, Any]) -> Command:
        """The command for this environment step: a new one at the start of each control period."""
        if self._command is None or self._steps % self.hold_steps == 0:
            obs = self.read(observation)
            self._command = self.controller.step(obs)
            status = STATUS_CODES[self.controller.info.status]
            row = [obs.time, *obs.as_array(), self._command.speed, self._command.steer, status]
            self._rows.append(np.array(row))
        self._steps += 1
        return self._command

    @property
    def status_counts(self) -> dict[str, int]:
        """Control steps since :meth:`reset` by status (:data:`rkmpc.control.base.STATUSES`)."""
        codes = Counter(int(row[-1]) for row in self._rows)
        return {status: codes[code] for code, status in enumerate(STATUSES) if codes[code]}

    def __call__(self, observation: Mapping[str, Any]) -> np.ndarray:
        """The action ``[[steer, speed]]`` (shape (1, 2)) for this step; one agent only.

        With several agents, drive the ego with :meth:`command` and build the
        ``(num_agents, 2)`` action yourself.
        """
        agents = self._layout(observation).agents(observation)
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
                obs = self.read(final_observation)
            except ParameterError:
                return log
            log.append(np.array([obs.time, *obs.as_array(), math.nan, math.nan, math.nan]))
        return log


def _check_period(env: F1TenthLikeEnv, policy: ControllerPolicy) -> None:
    """Refuse a policy whose step is not the environment's (its commands would be held too long
    or too short, its clock wrong); environments that do not say their step are not checked."""
    step = getattr(getattr(env, "unwrapped", env), "timestep", None)
    if isinstance(step, int | float) and not math.isclose(float(step), policy.timestep, rel_tol=1e-9):
        raise ParameterError(
            f"run_episode: the policy was built for {policy.timestep:g} s steps, the environment "
            f"steps {float(step):g} s; build it with ControllerPolicy(controller, {float(step):g})"
        )


def run_episode(
    env: F1TenthLikeEnv,
    policy: ControllerPolicy,
    *,
    seed: int | None = None,
    options: dict[str, Any] | None = None,
    max_steps: int | None = None,
    on_step: Callable[[Mapping[str, Any]], None] | None = None,
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
    on_step : callable, optional
        Called with the ``info`` of every environment step (for instance to record the true
        lateral error of :class:`rkmpc.envs.f1tenth_gym.TrackProgress` at every 0.01 s step).

    Returns
    -------
    Episode
        With the control steps' statuses; when more than :data:`DEGRADED_SHARE` of them fell back,
        a warning says so on the ``rkmpc.envs.adapter`` logger (:meth:`Episode.degraded`).
    """
    if max_steps is not None and not is_integer(max_steps, 1):
        raise ParameterError(f"run_episode: max_steps must be None or an integer >= 1, got {max_steps!r}")
    _check_period(env, policy)
    observation, info = env.reset(seed=seed, options=options)
    policy.reset()
    steps, total = 0, 0.0
    terminated = truncated = False
    while not (terminated or truncated) and (max_steps is None or steps < max_steps):
        observation, reward, terminated, truncated, info = env.step(policy(observation))
        total += float(reward)
        steps += 1
        if on_step is not None:
            on_step(info)
    episode = Episode(
        log=policy.log(observation),
        control_period=policy.control_period,
        steps=steps,
        total_reward=total,
        terminated=bool(terminated),
        truncated=bool(truncated),
        info=dict(info),
        controller=policy.controller.name,
        status_counts=policy.status_counts,
    )
    message = episode.degraded()
    if message is not None:
        _LOG.warning("%s", message)
    return episode
