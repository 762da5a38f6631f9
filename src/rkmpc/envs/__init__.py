"""The project's simulator for reinforcement-learning tools, and the real F1TENTH gym, with its conventions.

* :mod:`rkmpc.envs.f1tenth`: :class:`~rkmpc.envs.f1tenth.F1TenthTrackEnv`, a Gymnasium
  environment (needs ``pip install rkmpc[gym]``; importing it registers
  ``"rkmpc/F1TenthTrack-v0"``).
* :mod:`rkmpc.envs.f1tenth_gym`: the real F1TENTH gym v1.0.0 on an rkmpc track
  (:func:`~rkmpc.envs.f1tenth_gym.make_gym_env`; needs the gym, ``make f1tenth-gym``), the track
  written in its map format by :func:`~rkmpc.envs.gym_map.gym_map` (which needs no gym).
* :mod:`rkmpc.envs.adapter`: :class:`~rkmpc.envs.adapter.ControllerPolicy`, any rkmpc controller
  driving an F1TENTH-style environment (either of the above), and
  :func:`~rkmpc.envs.adapter.run_episode`, which records an :class:`~rkmpc.envs.episode.Episode`
  (statuses, data set) while it drives; :mod:`rkmpc.envs.layouts` reads the observations, NaN
  for what an environment does not measure. None of these needs ``gymnasium``.
"""

from __future__ import annotations

from rkmpc.envs.adapter import (
    ControllerPolicy,
    Episode,
    action_from_command,
    observation_from_f1tenth,
    run_episode,
)

__all__ = ["ControllerPolicy", "Episode", "action_from_command", "observation_from_f1tenth", "run_episode"]
