"""The real F1TENTH gym (v1.0.0) on an rkmpc track, driven by rkmpc's controllers.

The F1TENTH gym (``f1tenth_gym``, not on the package index: ``make f1tenth-gym`` installs it from
``../shared/vendor/``) loads its tracks by name from its own ``maps`` folder, downloading unknown
ones; it also takes a track object. Here:

* :func:`gym_map` (from :mod:`rkmpc.envs.gym_map`) writes an rkmpc track as a gym map folder, and
  :func:`load_gym_track` reads such a folder into the gym's ``Track`` (no download);
* :func:`make_gym_env` makes the gym's environment on it (``gymnasium.make("f1tenth_gym:f1tenth-v0",
  config=...)``) with one agent, the gym's single-track model integrated by RK4 at its
  ``timestep`` (0.01 s), its car's parameters (``params`` change them) and the observation type
  asked for, wrapped in :class:`TrackProgress`, which adds rkmpc's ``info`` (``outcome``,
  ``completed_lap_times``, ``lateral_error`` against the reference path, ...) and ends the
  episode after ``max_laps`` laps;
* :func:`gym_car` is the car whose controllers drive there: a car (the ``f1tenth`` preset by
  default) that declares the sensors the gym's observation has (:func:`gym_sensors`) and the zoo's
  ``gym`` car as its plant (the data sets and models made in the gym record it);
  :func:`rkmpc.sim.build.build_controller` then puts the state estimator in front of its controllers
  where the gym does not measure a field (its default observation: no wheel angle, no side-slip);
* :func:`gym_policy` builds the :class:`~rkmpc.envs.adapter.ControllerPolicy` for it: the
  controller stepped every control period (0.05 s: five gym steps, its command held in between)
  and the observation read with :func:`gym_layout`.

What the gym observes: its default observation gives pose, the speed of the centre of gravity
(``linear_vels_x``) and the yaw rate; its ``linear_vels_y`` is a fixed 0 and it has no wheel angle,
so both the side-slip and the wheel angle are NaN. ``"dynamic_state"`` gives the pose, the speed
along the heading, the yaw rate, the wheel angle ``delta`` and the side-slip ``beta`` (the model's
true states); ``"kinematic_state"`` no yaw rate or slip. The kinematic model (``model="ks"``) fills
yaw rate and slip with a placeholder 0, which is read as NaN.

The gym keeps one lidar simulator, and so one map, for all its environments of a process: the
last one made sets it.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from PIL import Image

from rkmpc.config.car import CarConfig
from rkmpc.config.loader import load_preset
from rkmpc.control.base import Controller
from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.validation import is_integer, is_positive_number
from rkmpc.envs.adapter import ControllerPolicy
from rkmpc.envs.gym_map import gym_map, gym_map_name
from rkmpc.envs.layouts import F1TENTH_GYM, GYM_FEATURES, ObservationLayout
from rkmpc.envs.progress import progress_info
from rkmpc.estimation.config import EstimatorConfig
from rkmpc.sim.laps import LapCounter
from rkmpc.sim.scenario import Scenario
from rkmpc.track.path import Path as TrackPath
from rkmpc.track.track import Track

__all__ = [
    "GYM_ENV_ID",
    "GYM_ESTIMATOR",
    "OBSERVATION_TYPES",
    "TrackProgress",
    "gym_car",
    "gym_layout",
    "gym_map",
    "gym_map_name",
    "gym_policy",
    "gym_sensors",
    "load_gym_track",
    "make_gym_env",
    "start_pose",
]

#: The F1TENTH gym's registered environment (importing ``f1tenth_gym`` registers it).
GYM_ENV_ID = "f1tenth_gym:f1tenth-v0"
#: The gym's observation types and how the adapter reads each.
OBSERVATION_TYPES: dict[str, ObservationLayout] = {
    "original": F1TENTH_GYM,
    "kinematic_state": GYM_FEATURES,
    "dynamic_state": GYM_FEATURES,
    "frenet_dynamic_state": GYM_FEATURES,
}
#: Per dynamic model of the gym, the fields its observations fill with a placeholder 0.
PLACEHOLDER_FIELDS: dict[str, tuple[str, ...]] = {"st": (), "ks": ("yaw_rate", "slip_angle")}
_OUTCOMES = ("collision", "max_laps", "gym_done")
#: The state estimator's tuning for the gym's measurements, which are its model's true states (in
#: float32): the pose and the speed are exact, so a few millimetres, milliradians and centimetres
#: per second of measurement noise (what keeps the filter from following them blindly where its
#: model differs), and the filter reads the side-slip from the course the poses draw (with the
#: defaults, a real localiser's 5 cm, it rests on its tyre model and reads less slip than the gym's).
#: The yaw rate is exact too, but the gym's wheel limit-cycles around the command (bang-bang at
#: 3.2 rad/s every 0.01 s step), so the yaw rate sampled every 0.05 s differs from the rate of the
#: poses over the period around it by 0.020 rad/s (standard deviation, LMPC laps of the built-in
#: track, Monza and Silverstone): its noise.
GYM_ESTIMATOR = EstimatorConfig(position_std=0.003, yaw_std=0.0015, speed_std=0.01, yaw_rate_std=0.02)


def _gym_track_class() -> Any:
    """The gym's ``Track`` and ``Raceline`` classes (importing the gym registers its environment)."""
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")  # the renderer imports pygame
    try:
        from f1tenth_gym.envs.track import Raceline, Track
    except ImportError as exc:
        raise ImportError(
            "rkmpc.envs.f1tenth_gym needs the F1TENTH gym v1.0.0: `make f1tenth-gym`, or "
            "pip install 'rkmpc[f1tenth-gym]' and "
            "pip install --no-deps ../shared/vendor/f1tenth_gym-1.0.0.tar.gz"
        ) from exc
    return Track, Raceline


def load_gym_track(map_dir: str | Path) -> Any:
    """The gym's ``Track`` of a map folder written by :func:`gym_map` (as the gym's ``from_track_name``).

    Raises
    ------
    InputFileError
        When the folder lacks the map YAML, its image or the centre line.
    """
    track_cls, raceline_cls = _gym_track_class()
    folder = Path(map_dir)
    name = folder.name
    spec_file = folder / f"{name}_map.yaml"
    centre_file = folder / f"{name}_centerline.csv"
    for needed in (spec_file, centre_file):
        if not needed.is_file():
            raise InputFileError(needed, "missing: not a map folder written by rkmpc.envs.gym_map.gym_map")
    spec = track_cls.load_spec(track=name, filespec=str(spec_file))
    image_file = folder / str(spec.image)
    if not image_file.is_file():
        raise InputFileError(spec_file, f"its image {image_file} is missing", field="image")
    with Image.open(image_file) as image:
        occupancy = np.array(image.transpose(Image.Transpose.FLIP_TOP_BOTTOM)).astype(np.float32)
    occupancy = np.where(occupancy > 128, 255.0, 0.0).astype(np.float32)
    centerline = raceline_cls.from_centerline_file(centre_file)
    race_file = folder / f"{name}_raceline.csv"
    raceline = raceline_cls.from_raceline_file(race_file) if race_file.is_file() else centerline
    return track_cls(
        spec=spec,
        occupancy_map=occupancy,
        filepath=str((folder / image_file.stem).absolute()),
        ext=image_file.suffix,
        centerline=centerline,
        raceline=raceline,
    )


def start_pose(path: TrackPath, s: float = 0.0) -> np.ndarray:
    """The gym's reset pose ``[[x, y, theta]]`` (m, m, rad), shape (1, 3), at arc length ``s`` (m).

    Pass it as ``env.reset(options={"poses": start_pose(scenario.reference.path)})``.
    """
    x, y = (float(v) for v in path.position(s))
    return np.array([[x, y, float(path.heading(s))]])


class TrackProgress(gym.Wrapper):
    """The F1TENTH gym's environment with rkmpc's ``info`` and an episode of ``max_laps`` laps.

    The gym's own ``info`` is kept and :func:`rkmpc.envs.progress.progress_info` of the ego's true
    pose (the gym's state) against ``path`` added: ``time``, ``s``, ``progress_laps``,
    ``lateral_error``, ``heading_error``, ``track_margin`` (against ``track``'s boundaries),
    ``completed_lap_times``, ``outcome`` (``"running"``; ``"collision"`` when the gym stopped the
    ego against a wall; ``"max_laps"`` when this wrapper truncated; ``"gym_done"`` when the gym
    ended otherwise, after its own two laps, only without ``max_laps``) and ``failure`` (None).
    Observations, rewards and actions are the gym's.

    Parameters
    ----------
    env : gymnasium.Env
        The gym's environment (made by ``gymnasium.make``).
    track : Track
        The rkmpc track (its boundaries for ``track_margin``).
    path : Path
        The reference path (lateral error, laps).
    max_laps : int or None
        Laps after which the episode is truncated (>= 1), the gym's own end after two laps
        ignored (it comes some 0.3 m short of the second); None: the gym decides.
    """

    def __init__(
        self, env: gym.Env[Any, Any], track: Track, path: TrackPath, max_laps: int | None = None
    ) -> None:
        super().__init__(env)
        if max_laps is not None and not is_integer(max_laps, 1):
            raise ParameterError(f"TrackProgress: max_laps must be None or an integer >= 1, got {max_laps!r}")
        self.track = track
        self.path = path
        self.max_laps = max_laps
        self.progress: LapCounter | None = None
        self._s_track: float | None = None

    @property
    def gym_env(self) -> Any:
        """The gym's own ``F110Env``."""
        return self.env.unwrapped

    def _pose(self) -> tuple[float, float, float]:
        gym_env = self.gym_env
        x, y, yaw = (float(v) for v in gym_env.sim.agent_poses[gym_env.ego_idx])
        return x, y, yaw

    def _margin(self, x: float, y: float) -> float:
        self._s_track, _, margin = self.track.boundary_offsets(x, y, self._s_track)
        return float(margin)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        observation, info = self.env.reset(seed=seed, options=options)
        x, y, yaw = self._pose()
        self._s_track = None
        proj = self.path.project(x, y)
        self.progress = LapCounter(self.path, proj.s)
        time = float(self.gym_env.current_time)
        extra = progress_info(time, yaw, self.progress, proj, self._margin(x, y), "running", None)
        return observation, {**info, **extra}

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        if self.progress is None:
            raise gym.error.ResetNeeded("TrackProgress.step called before reset")
        observation, reward, terminated, truncated, info = self.env.step(action)
        gym_env = self.gym_env
        x, y, yaw = self._pose()
        time = float(gym_env.current_time)
        proj, _ = self.progress.update(x, y, time, float(gym_env.timestep))
        laps_done = self.max_laps is not None and len(self.progress.crossings) >= self.max_laps
        collided = bool(gym_env.collisions[gym_env.ego_idx])
        # With max_laps this wrapper counts the laps: the gym's own end after two laps (which it
        # signals some 0.3 m before its start point) is ignored; a collision always ends the episode.
        gym_done = bool(terminated) and not collided and self.max_laps is None
        ended = dict(zip(_OUTCOMES, (collided, laps_done, gym_done), strict=True))
        outcome = next((name for name, happened in ended.items() if happened), "running")
        extra = progress_info(time, yaw, self.progress, proj, self._margin(x, y), outcome, None)
        return observation, reward, collided or gym_done, bool(truncated) or laps_done, {**info, **extra}


def make_gym_env(
    scenario: Scenario,
    map_dir: str | Path,
    *,
    observation: str = "original",
    model: str = "st",
    timestep: float = 0.01,
    max_laps: int | None = None,
    params: Mapping[str, float] | None = None,
    seed: int = 12345,
) -> TrackProgress:
    """The F1TENTH gym on the map folder ``map_dir`` (:func:`gym_map`), one agent, as :class:`TrackProgress`.

    Parameters
    ----------
    scenario : Scenario
        Its track and reference path measure the progress (the map should be written from them).
    map_dir : str or Path
        A map folder written by :func:`gym_map`.
    observation : str
        The gym's observation type, a key of :data:`OBSERVATION_TYPES`.
    model : str
        The gym's dynamic model: ``"st"`` (single track, its default) or ``"ks"`` (kinematic).
    timestep : float
        The gym's physics step (s, > 0); its RK4 integrates one step per call. The adapter holds
        each command for ``control_period / timestep`` steps (five at the default 0.01 s).
    max_laps : int or None
        Laps after which :class:`TrackProgress` truncates the episode, whatever the gym's own lap
        count says; None: the gym ends it, after its two laps.
    params : mapping, optional
        The gym car's parameters to change (its ``params`` keys: ``mu``, ``C_Sf``, ``lf``, ...).
    seed : int
        The gym's seed (its lidar noise).
    """
    if observation not in OBSERVATION_TYPES:
        raise ParameterError(
            f"make_gym_env: observation must be one of {sorted(OBSERVATION_TYPES)}, got {observation!r}"
        )
    if model not in PLACEHOLDER_FIELDS:
        raise ParameterError(
            f"make_gym_env: model must be one of {sorted(PLACEHOLDER_FIELDS)}, got {model!r}"
        )
    if not is_positive_number(timestep):
        raise ParameterError(f"make_gym_env: timestep must be finite and > 0 (s), got {timestep!r}")
    track = load_gym_track(map_dir)
    from f1tenth_gym.envs import F110Env

    known = F110Env.default_config()["params"]
    changed = dict(params or {})
    for key, value in changed.items():
        if key not in known or not (isinstance(value, int | float) and math.isfinite(value)):
            raise ParameterError(
                f"make_gym_env: params[{key!r}] must be a finite number and one of {sorted(known)}, "
                f"got {value!r}"
            )
    config = {
        "map": track,
        "num_agents": 1,
        "ego_idx": 0,
        "timestep": float(timestep),
        "integrator": "rk4",
        "model": model,
        "control_input": ["speed", "steering_angle"],
        "observation_config": {"type": observation},
        "params": {**known, **changed},
        "seed": int(seed),
    }
    env = gym.make(GYM_ENV_ID, config=config)
    return TrackProgress(env, scenario.track, scenario.reference.path, max_laps=max_laps)


def gym_layout(env: gym.Env[Any, Any]) -> ObservationLayout:
    """How the adapter reads the observation of the gym's environment ``env`` (its type and model)."""
    gym_env: Any = env.unwrapped
    config = gym_env.config
    kind = config["observation_config"]["type"] or "original"
    if kind not in OBSERVATION_TYPES:
        raise ParameterError(
            f"gym_layout: the gym's observation type {kind!r} is not one of {sorted(OBSERVATION_TYPES)}"
        )
    return OBSERVATION_TYPES[kind].without(*PLACEHOLDER_FIELDS[config["model"]])


def gym_sensors(observation: str = "original", *, model: str = "st", unmeasured: tuple[str, ...] = ()) -> str:
    """The sensor profile (:data:`rkmpc.vehicle.sensors.SENSOR_PROFILES`) of what the gym observes.

    ``"ideal"`` when the observation type ``observation`` of the gym's dynamic ``model`` gives every
    field (``"dynamic_state"`` of ``"st"``, none of them declared ``unmeasured``), else
    ``"no-steer"``: the true pose and speed, and a field it does not give is NaN, which the state
    estimator of a controller built for that profile fills.
    """
    if observation not in OBSERVATION_TYPES:
        raise ParameterError(
            f"gym_sensors: observation must be one of {sorted(OBSERVATION_TYPES)}, got {observation!r}"
        )
    if model not in PLACEHOLDER_FIELDS:
        raise ParameterError(f"gym_sensors: model must be one of {sorted(PLACEHOLDER_FIELDS)}, got {model!r}")
    layout = OBSERVATION_TYPES[observation].without(*PLACEHOLDER_FIELDS[model], *unmeasured)
    return "no-steer" if layout.never_measured else "ideal"


def gym_car(
    car: CarConfig | None = None,
    *,
    observation: str = "original",
    model: str = "st",
    unmeasured: tuple[str, ...] = (),
    estimator: EstimatorConfig | None = GYM_ESTIMATOR,
) -> CarConfig:
    """The car whose controllers drive in the gym: ``car`` with the gym's sensors and the gym's plant.

    ``car`` (the ``f1tenth`` preset when None: its nominal model and controller settings) gets the
    sensor profile :func:`gym_sensors` of the observation, so that
    :func:`rkmpc.sim.build.build_controller` wraps its controllers in the state estimator where the
    gym does not measure a field; that estimator's tuning ``estimator`` (:data:`GYM_ESTIMATOR` for
    the gym's exact measurements; None keeps ``car``'s), which smooths the data learned from too
    (:func:`rkmpc.experiments.training.estimated_for`); and the zoo car ``"gym"`` (the gym's vehicle
    parameters) as its plant, which the contract of a data set recorded in the gym and of a model
    trained on it names. Put it on a track with :meth:`rkmpc.sim.scenario.Scenario.from_car`.
    """
    base = load_preset("f1tenth") if car is None else car
    sensors = gym_sensors(observation, model=model, unmeasured=unmeasured)
    tuned = base if estimator is None else replace(base, estimator=estimator)
    return tuned.with_sensors(sensors).with_zoo_car("gym")


def gym_policy(
    controller: Controller,
    env: gym.Env[Any, Any],
    *,
    control_period: float | None = None,
    unmeasured: tuple[str, ...] = (),
) -> ControllerPolicy:
    """The :class:`ControllerPolicy` of ``controller`` in the gym's ``env``.

    Parameters
    ----------
    controller : Controller
        Any controller, a wrapped one (a state estimator) too.
    env : gymnasium.Env
        The gym's environment (:func:`make_gym_env`).
    control_period : float or None
        See :class:`ControllerPolicy`.
    unmeasured : tuple of str
        Observation fields to read as NaN though the gym gives them (``"steer_angle"``: the
        ``"dynamic_state"`` wheel angle a real car does not measure).
    """
    layout = gym_layout(env).without(*unmeasured)
    gym_env: Any = env.unwrapped
    return ControllerPolicy(controller, float(gym_env.timestep), control_period=control_period, layout=layout)
