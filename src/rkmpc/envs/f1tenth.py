"""A Gymnasium environment of the project's simulator with the F1TENTH gym's conventions.

:class:`F1TenthTrackEnv` drives one car (the ego, ``num_agents = 1``) of a
:class:`~rkmpc.sim.scenario.Scenario` (any track, the preset's plant or a zoo car) the way the
F1TENTH gym drives its cars:

* the **action** is an array of shape ``(1, 2)``, ``[[steer (rad), speed (m/s)]]``, held for one
  environment step of :attr:`F1TenthEnvConfig.timestep` (0.01 s by default, the F1TENTH gym's
  physics step); the plant integrates it at its own internal step (1 ms). Values outside the action
  space are clipped to it (the car's steering and speed limits); a wrong shape or a non-finite
  value raises :class:`~rkmpc.core.errors.ParameterError`;
* the **observation** is a dict of arrays of shape ``(1,)`` with the F1TENTH gym's keys
  (``poses_x``, ``poses_y``, ``poses_theta``, ``linear_vels_x``, ``linear_vels_y``, ``ang_vels_z``,
  ``collisions``, ``lap_times``, ``lap_counts``, and ``ego_idx``), plus ``steering_angles``, the
  measured front wheel angle (the F1TENTH gym's ``dynamic_state`` observation carries it as
  ``delta``; :attr:`F1TenthEnvConfig.measured_steering` False leaves it out). There is no lidar
  (``scans``): the project's tracks are centre lines with widths, not occupancy maps. Values are
  ``float64`` (the F1TENTH gym uses ``float32``), so the observation a controller sees through
  :mod:`rkmpc.envs.adapter` is the one it sees in the project's own closed loop;
* ``reset(seed=...)`` seeds :attr:`np_random`, which draws the plant's noise seed and, when
  :attr:`F1TenthEnvConfig.random_start` is set, the start; ``options`` may give ``{"poses":
  array of shape (1, 3)}`` (the F1TENTH gym's start poses, ``[x, y, theta]``) or ``{"start_s": s}``
  (an arc length on the reference path, m);
* the **reward** of a step is the distance the car advanced along the reference path (m; negative
  when it drives backwards);
* the episode **terminates** when the car's centre of gravity leaves the track (the project's
  off-track check, :meth:`rkmpc.track.track.Track.boundary_offsets`; ``collisions`` becomes 1), when
  its state turns non-finite or when the plant cannot integrate a step; it is **truncated** after
  :attr:`F1TenthEnvConfig.max_laps` laps. A time limit is Gymnasium's ``TimeLimit`` wrapper
  (``gymnasium.make(ENV_ID, max_episode_steps=...)``), not a setting.

Importing this module needs ``gymnasium`` (``pip install rkmpc[gym]``) and registers
:data:`ENV_ID`. Rendering is not supported (``render_mode=None`` only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from rkmpc.core.errors import ParameterError, PlantIntegrationError
from rkmpc.core.observation import Command
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.envs.progress import progress_info
from rkmpc.learning.contract import Provenance
from rkmpc.sim.laps import LapCounter
from rkmpc.sim.scenario import Scenario, load_scenario
from rkmpc.track.path import Projection
from rkmpc.vehicle.plants.base import Plant
from rkmpc.vehicle.wrappers import NoiseStd, ObservationNoise

__all__ = ["ENV_ID", "F1TENTH_TIMESTEP", "F1TenthEnvConfig", "F1TenthTrackEnv"]

#: The id under which importing this module registers :class:`F1TenthTrackEnv`.
ENV_ID = "rkmpc/F1TenthTrack-v0"
#: The F1TENTH gym's physics step (s).
F1TENTH_TIMESTEP = 0.01
#: Keys of the F1TENTH gym's observation that have one value per agent, in its order.
AGENT_KEYS = (
    "poses_x",
    "poses_y",
    "poses_theta",
    "linear_vels_x",
    "linear_vels_y",
    "ang_vels_z",
    "collisions",
    "lap_times",
    "lap_counts",
)
#: Key of the measured front wheel angles (rad), an addition to the F1TENTH gym's keys.
STEERING_KEY = "steering_angles"
# Bound of the unbounded quantities (as the F1TENTH gym's: finite, so every Box is bounded).
_LARGE = 1e30
_OPTION_KEYS = ("poses", "start_s")


#: Longest environment step (s) :class:`F1TenthEnvConfig` takes: the controllers plan at 0.05 s,
#: and the plant integrates each step in 1 ms substeps.
MAX_TIMESTEP = 1.0


@dataclass(frozen=True)
class F1TenthEnvConfig:
    """Settings of :class:`F1TenthTrackEnv`.

    Parameters
    ----------
    timestep : float
        Duration of one environment step (s), in (0, :data:`MAX_TIMESTEP`]: 0.01 (the F1TENTH
        gym's) by default; the
        project's controllers plan at 0.05 s, so :class:`rkmpc.envs.adapter.ControllerPolicy` holds
        each command for five steps (or set 0.05 and it holds it for one).
    max_laps : int or None
        Laps after which the episode is truncated (>= 1); None: never.
    flying_start : bool
        Start at the reference speed and feed-forward wheel angle of the start (True), or at
        standstill with straight wheels (False, the F1TENTH gym's start).
    random_start : bool
        Start at an arc length drawn uniformly along the reference path from :attr:`np_random`
        (when ``options`` give no start).
    start_s : float
        Arc length of the start on the reference path (m), when neither ``options`` nor
        ``random_start`` give one.
    noise : NoiseStd or None
        Gaussian odometry noise added to the observation (seeded from :attr:`np_random` at each
        reset), on top of a zoo car's own; None for none.
    measured_steering : bool
        Add ``steering_angles`` (the front wheel angle, rad) to the observation.
    """

    timestep: float = F1TENTH_TIMESTEP
    max_laps: int | None = None
    flying_start: bool = True
    random_start: bool = False
    start_s: float = 0.0
    noise: NoiseStd | None = None
    measured_steering: bool = True

    def __post_init__(self) -> None:
        if not is_positive_number(self.timestep) or self.timestep > MAX_TIMESTEP:
            # The plant integrates at 1 ms: a 1000 s step is a million substeps (an hour's wait).
            raise ParameterError(
                f"F1TenthEnvConfig.timestep must be in (0, {MAX_TIMESTEP:g}] s, got {self.timestep!r}"
            )
        for name in ("flying_start", "random_start", "measured_steering"):
            value = getattr(self, name)
            if not isinstance(value, bool):
                raise ParameterError(f"F1TenthEnvConfig.{name} must be a bool (True or False), got {value!r}")
        if self.noise is not None and not isinstance(self.noise, NoiseStd):
            raise ParameterError(
                "F1TenthEnvConfig.noise must be None or a rkmpc.vehicle.wrappers.NoiseStd, "
                f"got {self.noise!r}"
            )
        if self.max_laps is not None and not is_integer(self.max_laps, 1):
            raise ParameterError(
                f"F1TenthEnvConfig.max_laps must be None or an integer >= 1, got {self.max_laps!r}"
            )
        if not math.isfinite(self.start_s):
            raise ParameterError(f"F1TenthEnvConfig.start_s must be finite, got {self.start_s!r}")


class F1TenthTrackEnv(gym.Env[dict[str, Any], np.ndarray]):
    """One car of a scenario, as a Gymnasium environment with the F1TENTH gym's conventions.

    See the module docstring for the action, observation, reward and episode ends.

    Parameters
    ----------
    scenario : Scenario or None
        Track, car and reference; None for ``load_scenario("builtin")``.
    config : F1TenthEnvConfig or None
        Step length, laps, start, noise; None for the defaults.
    render_mode : None
        Rendering is not supported; anything else raises :class:`ParameterError`.

    Attributes
    ----------
    scenario : Scenario
    config : F1TenthEnvConfig
    timestep : float
        Duration of one step (s).
    num_agents : int
        Always 1 (the ego).
    """

    def __init__(
        self,
        scenario: Scenario | None = None,
        config: F1TenthEnvConfig | None = None,
        render_mode: str | None = None,
    ) -> None:
        if render_mode is not None:
            raise ParameterError(
                f"F1TenthTrackEnv renders nothing; render_mode must be None, got {render_mode!r}"
            )
        self.scenario = scenario if scenario is not None else load_scenario("builtin")
        self.config = config if config is not None else F1TenthEnvConfig()
        self.render_mode = render_mode
        self.timestep = self.config.timestep
        self.num_agents = 1
        self.metadata = {"render_modes": [], "render_fps": 1.0 / self.timestep}
        params = self.scenario.make_plant(0).params
        steer, drive = params.steering.max_angle, params.drive
        self._action_low = np.array([[-steer, drive.min_speed]])
        self._action_high = np.array([[steer, drive.max_speed]])
        self.action_space = spaces.Box(low=self._action_low, high=self._action_high, dtype=np.float64)
        self.observation_space = spaces.Dict(self._spaces())
        self._plant: Plant | None = None
        self._progress: LapCounter | None = None
        self._s_track: float | None = None

    def _spaces(self) -> dict[str, spaces.Space[Any]]:
        def box(low: float, high: float) -> spaces.Box:
            return spaces.Box(low=low, high=high, shape=(1,), dtype=np.float64)

        found: dict[str, spaces.Space[Any]] = {"ego_idx": spaces.Discrete(1)}
        for key in AGENT_KEYS:
            found[key] = box(-_LARGE, _LARGE)
        found.update(collisions=box(0.0, 1.0), lap_times=box(0.0, _LARGE), lap_counts=box(0.0, _LARGE))
        if self.config.measured_steering:
            found[STEERING_KEY] = box(-_LARGE, _LARGE)
        return found

    def provenance(self, dt: float | None = None) -> Provenance:
        """The scenario's contract (car, track scale), at the control period ``dt`` (s) data are made at."""
        made_with = self.scenario.provenance()
        return made_with if dt is None else replace(made_with, dt=dt)

    # ------------------------------------------------------------------ episode

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Start an episode; see the module docstring for ``seed`` and ``options``."""
        super().reset(seed=seed)
        given = {} if options is None else dict(options)
        unknown = sorted(set(given) - set(_OPTION_KEYS))
        if unknown or len(given) > 1:
            raise ParameterError(
                f"F1TenthTrackEnv.reset: options may hold one of {_OPTION_KEYS}, got {sorted(given)}"
            )
        plant_seed = int(self.np_random.integers(2**31 - 1))
        plant = self.scenario.make_plant(plant_seed)
        if self.config.noise is not None:
            plant = ObservationNoise(plant, self.config.noise, seed=plant_seed)
        path = self.scenario.reference.path
        x, y, yaw, s0 = self._start(given)
        speed, steer = 0.0, 0.0
        if self.config.flying_start:
            limit = plant.params.steering.max_angle
            speed = float(self.scenario.reference.profile.speed(s0))
            steer = min(
                max(math.atan(self.scenario.reference.wheelbase * float(path.curvature(s0))), -limit), limit
            )
        plant.reset(x, y, yaw, speed, steer)
        self._plant = plant
        self._s_track = None
        progress = self._progress = LapCounter(path, s0)
        margin = self._margin(plant)
        info = _info(plant, progress, path.project(x, y, s0), margin, "running", None)
        return self._observation(plant, margin), info

    def _start(self, given: dict[str, Any]) -> tuple[float, float, float, float]:
        """Start pose ``(x, y, yaw)`` (m, m, rad) and its arc length on the reference path (m)."""
        path = self.scenario.reference.path
        if "poses" in given:
            x, y, yaw = _start_pose(given["poses"])
            return x, y, yaw, path.project(x, y).s
        if "start_s" in given:
            try:
                s0 = float(given["start_s"])
            except (TypeError, ValueError):
                s0 = math.nan
            if not math.isfinite(s0):
                raise ParameterError(
                    "F1TenthTrackEnv.reset: options['start_s'] must be a finite number, "
                    f"got {given['start_s']!r}"
                )
        elif self.config.random_start:
            s0 = float(self.np_random.uniform(0.0, path.length))
        else:
            s0 = self.config.start_s
        s0 %= path.length
        x, y = (float(v) for v in path.position(s0))
        return x, y, float(path.heading(s0)), s0

    def step(self, action: np.ndarray) -> tuple[dict[str, Any], SupportsFloat, bool, bool, dict[str, Any]]:
        """Hold ``action`` (``[[steer, speed]]``) for one :attr:`timestep`; see the module docstring."""
        plant, progress = self._plant, self._progress
        if plant is None or progress is None:
            raise gym.error.ResetNeeded("F1TenthTrackEnv.step called before reset")
        steer, speed = self._check_action(action)
        failure: str | None = None
        try:
            plant.step(Command(speed=speed, steer=steer), self.timestep)
        except PlantIntegrationError as exc:
            failure = str(exc)
        state = plant.state
        if failure is not None or not np.all(np.isfinite(state)):
            outcome = "plant_failure" if failure is not None else "diverged"
            proj = Projection(progress.s, math.nan, math.nan)
            info = _info(plant, progress, proj, -1.0, outcome, failure)
            return self._observation(plant, -1.0), 0.0, True, False, info
        names = plant.STATE_NAMES
        x, y = float(state[names.index("x")]), float(state[names.index("y")])
        proj, ds = progress.update(x, y, plant.time, self.timestep)
        margin = self._margin(plant)
        max_laps = self.config.max_laps
        truncated = max_laps is not None and len(progress.crossings) >= max_laps
        terminated = margin < 0.0
        outcome = "off_track" if terminated else "max_laps" if truncated else "running"
        info = _info(plant, progress, proj, margin, outcome, None)
        return self._observation(plant, margin), float(ds), terminated, truncated, info

    def _check_action(self, action: np.ndarray) -> tuple[float, float]:
        """``(steer, speed)`` of a valid action, clipped to the action space."""
        try:
            array = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise ParameterError(
                f"F1TenthTrackEnv.step: the action must be numeric, got {action!r}"
            ) from None
        if array.shape != (self.num_agents, 2):
            raise ParameterError(
                "F1TenthTrackEnv.step: the action must have shape (num_agents, 2) = (1, 2), "
                f"[[steer (rad), speed (m/s)]], got shape {array.shape}"
            )
        if not np.all(np.isfinite(array)):
            raise ParameterError(f"F1TenthTrackEnv.step: the action must be finite, got {array.tolist()}")
        clipped = np.clip(array, self._action_low, self._action_high)
        return float(clipped[0, 0]), float(clipped[0, 1])

    def _margin(self, plant: Plant) -> float:
        """Distance (m) of the true centre of gravity to the nearer track boundary, < 0 outside."""
        state = plant.state
        names = plant.STATE_NAMES
        x, y = float(state[names.index("x")]), float(state[names.index("y")])
        self._s_track, _, margin = self.scenario.track.boundary_offsets(x, y, self._s_track)
        return float(margin)

    def _observation(self, plant: Plant, margin: float) -> dict[str, Any]:
        """The F1TENTH-style observation of what the car reports (possibly noisy or late)."""
        obs = plant.observe()
        slip = obs.slip_angle if math.isfinite(obs.slip_angle) else 0.0
        laps = 0 if self._progress is None else len(self._progress.crossings)
        values = {
            "poses_x": obs.x,
            "poses_y": obs.y,
            "poses_theta": obs.yaw,
            "linear_vels_x": obs.speed,
            "linear_vels_y": obs.speed * math.tan(slip),
            "ang_vels_z": obs.yaw_rate if math.isfinite(obs.yaw_rate) else 0.0,
            "collisions": 1.0 if margin < 0.0 else 0.0,
            "lap_times": plant.time,
            "lap_counts": float(laps),
        }
        found: dict[str, Any] = {"ego_idx": np.int64(0)}
        found.update({key: np.array([value], dtype=np.float64) for key, value in values.items()})
        if self.config.measured_steering:
            steer = obs.steer_angle if math.isfinite(obs.steer_angle) else 0.0
            found[STEERING_KEY] = np.array([steer], dtype=np.float64)
        return found


def _start_pose(poses: Any) -> tuple[float, float, float]:
    """``(x, y, theta)`` of the ``poses`` option, shape (1, 3)."""
    array = np.asarray(poses, dtype=np.float64)
    if array.shape != (1, 3) or not np.all(np.isfinite(array)):
        raise ParameterError(
            f"F1TenthTrackEnv.reset: options['poses'] must be a finite array of shape (1, 3), got {poses!r}"
        )
    return float(array[0, 0]), float(array[0, 1]), float(array[0, 2])


def _info(
    plant: Plant, progress: LapCounter, proj: Projection, margin: float, outcome: str, failure: str | None
) -> dict[str, Any]:
    """:func:`~rkmpc.envs.progress.progress_info` of the plant's true state.

    ``outcome`` is ``"running"``, ``"off_track"``, ``"max_laps"``, ``"diverged"`` or
    ``"plant_failure"``; ``failure`` the plant's message, or None.
    """
    yaw = float(plant.state[plant.STATE_NAMES.index("yaw")])
    return progress_info(plant.time, yaw, progress, proj, margin, outcome, failure)


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="rkmpc.envs.f1tenth:F1TenthTrackEnv")
