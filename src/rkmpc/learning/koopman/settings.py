"""How a lifting network is trained: :class:`MLPTraining` (no torch needed to read it)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import ClassVar

from rkmpc.core.errors import ParameterError
from rkmpc.core.validation import is_finite_real, is_integer

__all__ = ["TRAINING_THREADS", "MLPTraining"]

#: Torch intra-op threads of every training, whatever the machine: sums in another order give
#: another model, so a fixed count makes models identical everywhere (and one thread is also the
#: fastest for these small batches on a shared machine). Recorded in every model file.
TRAINING_THREADS = 1


@dataclass(frozen=True)
class MLPTraining:
    """Settings of the training of :class:`rkmpc.learning.koopman.lifting.MLPLifting`.

    Every budget is a count: the same data and settings give the same network
    on any machine, however busy (there is no wall-clock limit).

    Parameters
    ----------
    epochs : int
        Passes over the data (>= 1).
    learning_rate : float
        Adam step size (> 0).
    batch_size : int
        Samples per batch; ``A, B`` are solved on each batch, so it should be well above ``nz + nu``.
    huber_delta : float
        ``delta`` of the pseudo-Huber loss (scaled units, > 0).
    rollout_steps : int
        Horizon of the multi-step term of the loss (>= 0).
    rollout_weight : float
        Weight of the multi-step term (>= 0; 0 disables it).
    seed : int
        Seed (>= 0) of the network initialisation and the batch order.
    """

    epochs: int = 100
    learning_rate: float = 1e-3
    batch_size: int = 1024
    huber_delta: float = 1.0
    rollout_steps: int = 10
    rollout_weight: float = 0.1
    seed: int = 0

    _INTS: ClassVar[dict[str, int]] = {"epochs": 1, "batch_size": 1, "rollout_steps": 0, "seed": 0}
    _POSITIVE: ClassVar[tuple[str, ...]] = ("learning_rate", "huber_delta")

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in self._INTS:
                low = self._INTS[f.name]
                if not is_integer(value, low):
                    raise ParameterError(f"MLPTraining.{f.name} must be an integer >= {low}, got {value!r}")
                continue
            ok = is_finite_real(value) and (value > 0 if f.name in self._POSITIVE else value >= 0)
            if not ok:
                bound = "> 0" if f.name in self._POSITIVE else ">= 0"
                raise ParameterError(f"MLPTraining.{f.name} must be a finite number {bound}, got {value!r}")
