"""Time-blocked cross-validation: candidates scored on data they were not fitted on.

A data set of driving is a time series: neighbouring samples are nearly equal,
so a random split would score a model on copies of its training data. Here the
transitions are cut into a few contiguous blocks (:func:`time_blocks`); each
block is predicted by a fit on the others, with a gap of :data:`GAP_SECONDS`
left out on either side of it so that the fit does not see its immediate
neighbours. A candidate's score (:class:`Score`) is its squared prediction error
summed over the held-out blocks, and :func:`choose` picks among candidates by
that score alone: a candidate must beat the car's nominal model by
:data:`HELDOUT_MARGIN`, and one with more fitted parameters must beat every
simpler one by as much.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "DEFAULT_FOLDS",
    "GAP_SECONDS",
    "HELDOUT_MARGIN",
    "MIN_BLOCK",
    "Folds",
    "Score",
    "choose",
    "heldout_r2",
    "time_blocks",
]

#: Blocks of the cross-validation, unless the data are too few for that many.
DEFAULT_FOLDS = 5
#: Seconds of data left out of a fit on either side of the block it predicts.
GAP_SECONDS = 0.5
#: Usable samples a block needs at least; fewer blocks are made when the data are short.
MIN_BLOCK = 10
#: Relative margin (of the mean squared error) by which a candidate must beat the nominal model,
#: and a candidate with more fitted parameters every simpler one, to be chosen.
HELDOUT_MARGIN = 0.05


@dataclass(frozen=True)
class Folds:
    """Which samples each fit uses and which block it predicts.

    Parameters
    ----------
    train : numpy.ndarray
        Shape (F + 1, N) bool: the samples of the fit that predicts block ``f``; the last row
        is every usable sample (the final fit).
    test : numpy.ndarray
        Shape (F, N) bool: the samples of block ``f``.
    """

    train: np.ndarray
    test: np.ndarray

    @property
    def count(self) -> int:
        """F, the number of held-out blocks."""
        return int(self.test.shape[0])

    def restricted(self, usable: np.ndarray) -> Folds:
        """The same blocks, keeping only the samples where ``usable`` (shape (N,) bool)."""
        return Folds(self.train & usable, self.test & usable)


def time_blocks(usable: np.ndarray, folds: int, gap: int) -> Folds | None:
    """``folds`` contiguous blocks of the usable samples, in time order, and the fits that predict them.

    Parameters
    ----------
    usable : numpy.ndarray
        Shape (N,) bool: the samples a fit may use, in time order (episode after episode).
    folds : int
        Blocks wanted; fewer when there are less than :data:`MIN_BLOCK` usable samples per block.
    gap : int
        Samples left out of a fit on either side of the block it predicts.

    Returns
    -------
    Folds or None
        None when fewer than two blocks can be made, or a fit would have fewer than
        :data:`MIN_BLOCK` samples left.
    """
    index = np.flatnonzero(usable)
    count = min(folds, len(index) // MIN_BLOCK)
    if count < 2:
        return None
    n = len(usable)
    train = np.zeros((count + 1, n), dtype=bool)
    test = np.zeros((count, n), dtype=bool)
    for f, block in enumerate(np.array_split(index, count)):
        test[f, block] = True
        train[f] = usable
        train[f, max(int(block[0]) - gap, 0) : int(block[-1]) + gap + 1] = False
    train[-1] = usable
    if train.sum(axis=1).min() < MIN_BLOCK:
        return None
    return Folds(train, test)


@dataclass(frozen=True)
class Score:
    """A candidate's held-out prediction error.

    Parameters
    ----------
    name : str
        The candidate (``nominal``, ``delay-lag + K``, ...).
    parameters : int
        Parameters it fits (0 for the nominal model).
    sse : numpy.ndarray
        Squared prediction error summed over each held-out block, shape (F,).
    count : numpy.ndarray
        Samples of each held-out block, shape (F,).
    nonlinear : bool
        Whether it fits a nonlinearity (a rate limit): of two candidates with as many parameters
        that predict alike, the linear one is kept.
    """

    name: str
    parameters: int
    sse: np.ndarray
    count: np.ndarray
    nonlinear: bool = False

    @property
    def mse(self) -> float:
        """Mean squared error over every held-out sample."""
        total = float(np.sum(self.count))
        return float(np.sum(self.sse)) / total if total > 0 else math.nan

    @property
    def rmse(self) -> float:
        """Root of :attr:`mse`."""
        return math.sqrt(self.mse)


def choose(scores: Sequence[Score], nominal: Score, margin: float = HELDOUT_MARGIN) -> Score:
    """The candidate to keep: ``nominal`` unless some candidate predicts clearly better.

    A candidate is eligible when its held-out mean squared error is below ``(1 - margin)`` times
    the nominal model's; among the eligible ones within ``(1 + margin)`` of the best, the one
    with the fewest parameters, then without a nonlinearity, then of the lowest error is kept.
    """
    eligible = [s for s in scores if s is not nominal and s.mse < (1.0 - margin) * nominal.mse]
    if not eligible:
        return nominal
    best = min(s.mse for s in eligible)
    close = [s for s in eligible if s.mse <= (1.0 + margin) * best]
    return min(close, key=lambda s: (s.parameters, s.nonlinear, s.mse))


def heldout_r2(score: Score, target: np.ndarray, folds: Folds) -> float:
    """Share of the variance of ``target`` (shape (N,)) about each block's mean that ``score`` predicts."""
    total = 0.0
    for f in range(folds.count):
        y = target[folds.test[f]]
        total += float(np.sum((y - y.mean()) ** 2)) if len(y) else 0.0
    return 1.0 - float(np.sum(score.sse)) / total if total > 0 else math.nan
