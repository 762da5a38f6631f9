"""Random-excitation data from the plant, for the pure Koopman MPC (KMPC).

Following the paper's KMPC set-up, the car is driven in open space (no track)
by random smooth speed and steering sequences within its limits, from random
initial states, and every transition is recorded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rkmpc.core.errors import ParameterError
from rkmpc.core.observation import Command
from rkmpc.vehicle.plants.base import Plant

_MAX_EMPTY_EPISODES = 100


@dataclass(frozen=True)
class ExcitationConfig:
    """Random excitation settings.

    Parameters
    ----------
    n_samples : int
        Transitions to record.
    episode_steps : int
        Steps per episode before a new random initial state.
    speed_range : tuple of float
        Range of commanded speeds (m/s).
    steer_fraction : float
        Commanded wheel angles stay within this fraction of the car's limit.
    hold_range : tuple of float
        Each random target is held for a duration drawn from this range (s);
        commands move smoothly (first-order filter) towards the targets.
    smoothing : float
        Time constant of the command filter (s).
    max_lateral_accel : float
        Targets ask for at most this lateral acceleration in the kinematic
        model, ``v^2 tan(delta) / L`` (m/s^2): steering is limited at speed.
    max_slip : float
        An episode ends when the side-slip angle exceeds this (rad): the car has
        spun, and what follows is not driving data. The simulator's true state
        decides (the supervisor of the experiment), so the episode ends the
        same way whatever the sensors measure.
    seed : int
        Seed of every random choice.
    """

    n_samples: int = 50_000
    episode_steps: int = 200
    speed_range: tuple[float, float] = (0.5, 3.5)
    steer_fraction: float = 0.9
    hold_range: tuple[float, float] = (0.3, 1.5)
    smoothing: float = 0.2
    max_lateral_accel: float = 8.0
    max_slip: float = 0.35
    seed: int = 0

    def __post_init__(self) -> None:
        if self.n_samples < 1 or self.episode_steps < 2:
            raise ParameterError("ExcitationConfig: n_samples >= 1 and episode_steps >= 2 required")
        lo, hi = self.speed_range
        if not 0.0 <= lo < hi:
            raise ParameterError(
                f"ExcitationConfig.speed_range must satisfy 0 <= low < high, got {self.speed_range}"
            )
        if not 0.0 < self.steer_fraction <= 1.0:
            raise ParameterError("ExcitationConfig.steer_fraction must be in (0, 1]")
        if not 0.0 < self.hold_range[0] <= self.hold_range[1]:
            raise ParameterError("ExcitationConfig.hold_range must satisfy 0 < low <= high")
        if not self.smoothing > 0.0:
            raise ParameterError("ExcitationConfig.smoothing must be > 0")


def random_excitation(
    plant: Plant, config: ExcitationConfig, dt: float = 0.05
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Drive ``plant`` with random smooth commands and record the transitions.

    Parameters
    ----------
    plant : Plant
        The simulated car (reset at every episode).
    config : ExcitationConfig
        Amounts, ranges and seed.
    dt : float
        Control period (s).

    Returns
    -------
    obs : numpy.ndarray
        Observations before each transition, shape (N, 7).
    command : numpy.ndarray
        Applied commands, shape (N, 2).
    next_obs : numpy.ndarray
        Observations after each transition, shape (N, 7).
    episode : numpy.ndarray
        Episode index of each transition, shape (N,).
    """
    rng = np.random.default_rng(config.seed)
    steer_max = config.steer_fraction * plant.params.steering.max_angle
    wheelbase = plant.params.wheelbase
    lo, hi = config.speed_range
    alpha = 1.0 - math.exp(-dt / config.smoothing)
    obs_rows: list[np.ndarray] = []
    cmd_rows: list[tuple[float, float]] = []
    next_rows: list[np.ndarray] = []
    episodes: list[int] = []
    episode = 0
    empty_in_a_row = 0
    while len(cmd_rows) < config.n_samples:
        recorded = len(cmd_rows)
        speed = rng.uniform(lo, hi)
        steer = rng.uniform(-steer_max, steer_max) * 0.5
        plant.reset(0.0, 0.0, rng.uniform(-math.pi, math.pi), speed, steer)
        target_v, target_d = speed, steer
        hold = 0.0
        obs = plant.observe()
        for _ in range(config.episode_steps):
            if hold <= 0.0:
                target_v = rng.uniform(lo, hi)
                grip = math.atan(wheelbase * config.max_lateral_accel / max(target_v, 0.1) ** 2)
                limit = min(steer_max, grip)
                target_d = rng.uniform(-limit, limit)
                hold = rng.uniform(*config.hold_range)
            hold -= dt
            speed += alpha * (target_v - speed)
            steer += alpha * (target_d - steer)
            plant.step(Command(speed=speed, steer=steer), dt)
            nxt = plant.observe()
            truth = plant.unwrapped.observe()
            if not (
                np.all(np.isfinite(truth.as_array()))
                and np.all(np.isfinite([nxt.x, nxt.y, nxt.yaw, nxt.speed]))
                and abs(truth.slip_angle) <= config.max_slip
                and truth.speed >= 0
            ):
                break
            obs_rows.append(obs.as_array())
            cmd_rows.append((speed, steer))
            next_rows.append(nxt.as_array())
            episodes.append(episode)
            obs = nxt
            if len(cmd_rows) >= config.n_samples:
                break
        episode += 1
        empty_in_a_row = empty_in_a_row + 1 if len(cmd_rows) == recorded else 0
        if empty_in_a_row >= _MAX_EMPTY_EPISODES:
            raise ParameterError(
                f"random_excitation: {_MAX_EMPTY_EPISODES} episodes in a row ended at their first step "
                "(the car spun at once, or its sensors gave no finite pose or speed); nothing to record"
            )
    return np.array(obs_rows), np.array(cmd_rows), np.array(next_rows), np.array(episodes, dtype=np.int64)
