"""Progress of a long loop told in words, with an estimate of the time left.

The estimate is for the person waiting only: nothing computed depends on it (training stops
after a fixed number of epochs, never after a time).
"""

from __future__ import annotations

import time
from collections.abc import Callable

__all__ = ["EpochProgress", "format_duration"]


def format_duration(seconds: float) -> str:
    """``"40 s"``, ``"3 min"``, ``"1 h 05 min"``: a duration rounded for a progress line."""
    if seconds < 90:
        return f"{max(seconds, 1.0):.0f} s"
    minutes = round(seconds / 60)
    if minutes < 90:
        return f"{minutes} min"
    return f"{minutes // 60} h {minutes % 60:02d} min"


class EpochProgress:
    """An ``on_epoch(epoch, loss)`` callback that tells ``say`` how far training is and how long is left.

    It speaks after the first epoch (the first estimate) and then each time another tenth of the
    epochs is done, so a run of any length prints about ten lines.

    Parameters
    ----------
    say : callable
        Receives each progress line.
    what : str
        What is trained, the start of each line (``"training the residual model of rkmpc"``).
    epochs : int
        Epochs the training will run (epoch 0 is the untrained network, reported before training).
    clock : callable
        Seconds of a monotonic clock (``time.perf_counter``; replaceable in tests).
    """

    def __init__(
        self,
        say: Callable[[str], None],
        what: str,
        epochs: int,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        self.say = say
        self.what = what
        self.epochs = max(int(epochs), 1)
        self.clock = clock
        self._start: float | None = None
        self._start_epoch = 0
        self._next = 1

    def __call__(self, epoch: int, loss: float) -> None:
        now = self.clock()
        if self._start is None:  # normally epoch 0, the untrained network, before any training
            self._start, self._start_epoch = now, epoch
        if epoch <= 0 or (epoch < self._next and epoch < self.epochs):
            return
        done = epoch - self._start_epoch
        if epoch >= self.epochs:
            tail = "done"
        elif done <= 0:
            tail = "estimating the time left"
        else:
            tail = f"about {format_duration((now - self._start) / done * (self.epochs - epoch))} left"
        self.say(f"{self.what}: epoch {epoch}/{self.epochs}, loss {loss:.3g}, {tail}")
        step = max(self.epochs // 10, 1)
        self._next = (epoch // step + 1) * step
