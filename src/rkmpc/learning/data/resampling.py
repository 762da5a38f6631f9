"""What the importers' resampling settings share: the gap that ends an episode and the command tolerance."""

from __future__ import annotations

__all__ = ["GapAndTolerance"]


class GapAndTolerance:
    """Mixin of the settings of an import onto a control period: :attr:`gap` and :attr:`tolerance`.

    The class it is mixed into (a frozen dataclass) has ``dt``, the control period (s), and
    ``max_gap`` and ``command_tolerance`` (s), each None for its default.
    """

    dt: float
    max_gap: float | None
    command_tolerance: float | None

    @property
    def gap(self) -> float:
        """The gap (s) that ends an episode: ``max_gap`` or three periods."""
        return 3.0 * self.dt if self.max_gap is None else float(self.max_gap)

    @property
    def tolerance(self) -> float:
        """How late (s) a command may be stamped and still count for a sample."""
        return 0.25 * self.dt if self.command_tolerance is None else float(self.command_tolerance)
