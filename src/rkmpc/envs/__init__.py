"""The project's simulator for reinforcement-learning tools, with the F1TENTH gym's conventions.

* :mod:`rkmpc.envs.f1tenth`: :class:`~rkmpc.envs.f1tenth.F1TenthTrackEnv`, a Gymnasium
  environment (needs ``pip install rkmpc[gym]``; importing it registers
  ``"rkmpc/F1TenthTrack-v0"``).
* :mod:`rkmpc.envs.adapter`: :class:`~rkmpc.envs.adapter.ControllerPolicy`, any rkmpc controller
  driving an F1TENTH-style environment (this one or the F1TENTH gym), and
  :func:`~rkmpc.envs.adapter.run_episode`, which records a data set while it drives. It does not
  need ``gymnasium``.
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
