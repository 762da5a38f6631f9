"""One episode driven through :mod:`rkmpc.envs.adapter`: its log, how its controller fared, its data set.

:class:`Episode` keeps, per control period, what the controller saw and sent and the status of its
step (:data:`rkmpc.control.base.STATUSES`). A controller that fell back (a learned controller
without the wheel angle its model reads keeps its baseline: status ``"guard"``) is counted here,
never hidden: :attr:`Episode.status_counts`, :attr:`Episode.fallback_count` and, past
:data:`DEGRADED_SHARE` of the steps, :meth:`Episode.degraded`, which names the fall-backs and the
observation fields that were never measured.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from rkmpc.core.observation import OBSERVATION_FIELDS
from rkmpc.learning.contract import CONTRACT_KEY, Provenance
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.sim.log import StepLog

__all__ = ["DEGRADED_SHARE", "Episode"]

#: Share of the control steps that may fall back before an episode is :meth:`Episode.degraded`
#: (and :func:`rkmpc.envs.adapter.run_episode` warns).
DEGRADED_SHARE = 0.02


@dataclass
class Episode:
    """One episode driven by :func:`rkmpc.envs.adapter.run_episode`.

    Parameters
    ----------
    log : StepLog
        One row per control period (:data:`rkmpc.envs.adapter.LOG_COLUMNS`: time, observation,
        command, status code), the last one the final observation (no command, status NaN).
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
    controller : str
        Name of the controller that drove.
    status_counts : dict
        Control steps by status; every step not ``"ok"`` was a fall-back.
    """

    log: StepLog
    control_period: float
    steps: int
    total_reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any] = field(default_factory=dict)
    controller: str = "controller"
    status_counts: dict[str, int] = field(default_factory=dict)

    @property
    def control_steps(self) -> int:
        """Control steps driven (rows of the log with a command)."""
        return sum(self.status_counts.values())

    @property
    def fallback_count(self) -> int:
        """Control steps whose status was not ``"ok"``."""
        return self.control_steps - self.status_counts.get("ok", 0)

    @property
    def unmeasured(self) -> tuple[str, ...]:
        """Observation fields that were NaN at every control step: the environment does not measure them."""
        stepped = np.isfinite(np.asarray(self.log["status"], dtype=float))
        if not np.any(stepped):
            return ()
        return tuple(name for name in OBSERVATION_FIELDS if np.all(np.isnan(self.log[name][stepped])))

    def degraded(self) -> str | None:
        """What fell back, when more than :data:`DEGRADED_SHARE` of the control steps did; else None."""
        steps, fallbacks = self.control_steps, self.fallback_count
        if steps == 0 or fallbacks <= DEGRADED_SHARE * steps:
            return None
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(self.status_counts.items()) if k != "ok")
        missing = f"; not measured: {', '.join(self.unmeasured)}" if self.unmeasured else ""
        return (
            f"{self.controller}: {fallbacks} of {steps} control steps ({100.0 * fallbacks / steps:.1f} %) "
            f"fell back ({reasons}){missing}"
        )

    def dataset(
        self, metadata: Mapping[str, Any] | None = None, made_with: Provenance | None = None
    ) -> TransitionDataset:
        """The episode's transitions at the control period (:meth:`TransitionDataset.from_log`).

        Fields the environment does not measure stay NaN (a wheel angle is never made up here).

        Parameters
        ----------
        metadata : mapping, optional
            Added to the data set's metadata (``source`` is ``"gym"`` unless given). The episode's
            own: ``controller``, ``steps``, ``terminated``, ``truncated``, ``status_counts``,
            ``fallback_count`` and ``unmeasured`` (the fields NaN in every row).
        made_with : Provenance, optional
            The car and track scale the data were recorded with (for the environments of
            :mod:`rkmpc.envs.f1tenth`, ``env.unwrapped.provenance()``); its period becomes the
            control period and the data set records it as its contract.
        """
        meta: dict[str, Any] = {
            "source": "gym",
            "controller": self.controller,
            "steps": self.steps,
            "terminated": self.terminated,
            "truncated": self.truncated,
            "status_counts": dict(self.status_counts),
            "fallback_count": self.fallback_count,
            "unmeasured": list(self.unmeasured),
        }
        meta.update(metadata or {})
        if made_with is not None:
            meta[CONTRACT_KEY] = replace(made_with, dt=self.control_period).to_json()
        return TransitionDataset.from_log(self.log, metadata=meta, dt=self.control_period)
