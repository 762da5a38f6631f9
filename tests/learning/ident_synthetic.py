"""Synthetic data for the identification tests: a steering actuator behind a delay, a kinematic car.

Each actuator runs at a 1 ms step behind a pure delay, driven by seeded random steps and ramps;
the wheel angle is sampled every control period T = 0.05 s, and the speed and yaw rate follow a
kinematic car with understeer gradient K: ``r = v tan(delta) / (L + K v^2)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.vehicle.params import f1tenth

T = 0.05
STEP = 0.001
WHEELBASE = 0.307
GRADIENT = 0.01
VEHICLE = f1tenth()  # nominal servo: lag 0.158 s, 3.2 rad/s; wheelbase 0.307 m
NOMINAL_RATE = VEHICLE.steering.max_rate

#: One actuator step: (wheel angle, wheel rate, delayed command, step index) -> (angle, rate).
Actuator = Callable[[float, float, float, int], tuple[float, float]]


def commands(n: int, seed: int) -> np.ndarray:
    """Steering commands (rad): random steps and ramps held 1 to 8 periods, within +-0.35 rad."""
    rng = np.random.default_rng(seed)
    out = np.empty(n)
    k, last = 0, 0.0
    while k < n:
        hold = int(rng.integers(1, 9))
        target = float(rng.uniform(-0.35, 0.35))
        stretch = np.full(hold, target) if rng.random() < 0.5 else np.linspace(last, target, hold + 1)[1:]
        out[k : k + hold] = stretch[: n - k]
        k += hold
        last = target
    return out


def lag(tau: float, rate: float = NOMINAL_RATE) -> Actuator:
    """A first-order lag moving at most ``rate`` (rad/s), like the zoo's ``FirstOrderServo``."""
    gain = -math.expm1(-STEP / tau)
    limit = rate * STEP
    return lambda d, r, u, i: (d + min(max((u - d) * gain, -limit), limit), 0.0)


def bang_bang(rate: float, every: int) -> Actuator:
    """Moves ``rate * every`` ms towards the command every ``every`` steps: it never settles."""
    jump = rate * every * STEP
    return lambda d, r, u, i: (d + math.copysign(jump, u - d), 0.0) if i % every == 0 else (d, 0.0)


def second_order(wn: float, zeta: float) -> Actuator:
    def step(d: float, r: float, u: float, i: int) -> tuple[float, float]:
        r += STEP * (wn * wn * (u - d) - 2.0 * zeta * wn * r)
        return d + STEP * r, r

    return step


def wheel_angles(cmd: np.ndarray, actuator: Actuator, delay: float = 0.0) -> np.ndarray:
    """The wheel angle at the start of each period and after the last, shape (n + 1,)."""
    sub = round(T / STEP)
    held = np.repeat(cmd, sub)
    lag_steps = round(delay / STEP)
    delayed = np.concatenate([np.full(lag_steps, cmd[0]), held[: len(held) - lag_steps]])
    d, r = float(cmd[0]), 0.0
    out = np.empty(len(cmd) + 1)
    out[0] = d
    for i, u in enumerate(delayed.tolist()):
        d, r = actuator(d, r, u, i)
        if (i + 1) % sub == 0:
            out[(i + 1) // sub] = d
    return out


def dataset(
    cmd: np.ndarray,
    wheel: np.ndarray,
    *,
    measured: np.ndarray | None = None,
    gradient: float = GRADIENT,
    yaw_rate_noise: float = 0.0,
    speed_scale: float = 1.0,
) -> TransitionDataset:
    """Transitions of a car whose wheel angle is ``wheel`` (measured as ``measured``; NaN: not measured)."""
    n = len(cmd)
    t = T * np.arange(n + 1)
    speed = speed_scale * (3.0 + 1.5 * np.sin(2 * np.pi * t / 17.0))
    yaw_rate = speed * np.tan(wheel) / (WHEELBASE + gradient * speed**2)
    yaw_rate = yaw_rate + yaw_rate_noise * np.random.default_rng(3).standard_normal(n + 1)
    yaw = np.concatenate([[0.0], np.cumsum(yaw_rate[:-1] * T)])
    x = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.cos(yaw[:-1]) * T)])
    y = np.concatenate([[0.0], np.cumsum(speed[:-1] * np.sin(yaw[:-1]) * T)])
    seen = wheel if measured is None else measured
    obs = np.column_stack([x, y, yaw, speed, yaw_rate, np.full(n + 1, np.nan), seen])
    return TransitionDataset(
        obs=obs[:-1],
        command=np.column_stack([speed[:-1], cmd]),
        next_obs=obs[1:],
        dt=T,
        episode=np.zeros(n, dtype=int),
    )


def unmeasured(data: TransitionDataset) -> TransitionDataset:
    """``data`` without its wheel angle (the column NaN), like a car without a steering sensor."""
    obs, nxt = data.obs.copy(), data.next_obs.copy()
    obs[:, 6] = nxt[:, 6] = np.nan
    return TransitionDataset(obs, data.command, nxt, data.dt, data.episode, data.metadata)
