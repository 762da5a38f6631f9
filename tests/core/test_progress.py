"""Training progress in words: about ten lines, each with an estimate of the time left."""

from __future__ import annotations

import pytest

from rkmpc.core.progress import EpochProgress, format_duration


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_about_ten_lines_with_a_shrinking_estimate() -> None:
    clock = FakeClock()
    lines: list[str] = []
    told = EpochProgress(lines.append, "training the residual model of rkmpc", 100, clock=clock)
    told(0, 1.0)  # the untrained network: starts the clock, says nothing
    assert lines == []
    for epoch in range(1, 101):
        clock.t += 2.0  # two seconds an epoch
        told(epoch, 1.0 / epoch)
    assert 10 <= len(lines) <= 12
    assert lines[0] == "training the residual model of rkmpc: epoch 1/100, loss 1, about 3 min left"
    assert "epoch 50/100" in lines[5] and "about 2 min left" in lines[5]
    assert lines[-1].endswith("epoch 100/100, loss 0.01, done")


def test_without_epoch_zero_the_clock_starts_at_the_first_epoch() -> None:
    clock = FakeClock()
    lines: list[str] = []
    told = EpochProgress(lines.append, "training", 3, clock=clock)
    for epoch in (1, 2, 3):
        clock.t += 10.0
        told(epoch, 0.5)
    assert [line.split(": ")[1] for line in lines] == [
        "epoch 1/3, loss 0.5, estimating the time left",
        "epoch 2/3, loss 0.5, about 10 s left",
        "epoch 3/3, loss 0.5, done",
    ]


@pytest.mark.parametrize(
    ("seconds", "text"),
    [(0.2, "1 s"), (40.4, "40 s"), (89, "89 s"), (150, "2 min"), (3600, "60 min"), (5400, "1 h 30 min")],
)
def test_durations_are_rounded_for_reading(seconds: float, text: str) -> None:
    assert format_duration(seconds) == text
