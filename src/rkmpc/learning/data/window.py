"""A time window of a recording: which stretch of a log or a bag an import keeps (laps held out).

A window is written ``START:END`` in seconds from the recording's start (the earliest stamp of the
signals the import reads), either end left out for "from the start" or "to the end": ``10:60``,
``:45``, ``90:``. Prefixed with ``@`` both ends are absolute stamps (s since the epoch of the
recording's clock, as ``date -d @SECONDS`` reads them): ``@1650776500:@1650776560``. Samples at
``START <= t <= END`` are kept; the transitions of the import lie inside the window, both ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rkmpc.core.errors import ParameterError

__all__ = ["TimeWindow"]

_NS = 1_000_000_000


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


@dataclass(frozen=True)
class TimeWindow:
    """The stretch ``[start, end]`` of a recording an import keeps.

    Parameters
    ----------
    start, end : float or None
        Bounds (s); None: the recording's start or end. ``start < end`` when both are given.
    absolute : bool
        False: seconds from the recording's start (>= 0); True: stamps of the recording's clock.
    """

    start: float | None = None
    end: float | None = None
    absolute: bool = False

    def __post_init__(self) -> None:
        for name in ("start", "end"):
            value = getattr(self, name)
            if value is not None and not _finite(value):
                raise ParameterError(f"TimeWindow.{name} must be None or a finite number, got {value!r}")
            if value is not None and not self.absolute and value < 0:
                raise ParameterError(f"TimeWindow.{name} must be >= 0 (s from the start), got {value!r}")
        if self.start is not None and self.end is not None and not self.start < self.end:
            raise ParameterError(f"TimeWindow: start must be before end, got {self.start!r}:{self.end!r}")

    @classmethod
    def parse(cls, text: str) -> TimeWindow:
        """A window from ``START:END`` (module docstring), e.g. ``"10:60"`` or ``"@1650776500:"``.

        Raises
        ------
        ParameterError
            Naming the text and the problem.
        """
        parts = text.strip().split(":")
        if len(parts) != 2:
            raise ParameterError(f"window {text!r}: expected START:END (seconds), e.g. 10:60 or :45")
        marked = [part.strip().startswith("@") for part in parts if part.strip()]
        if any(marked) and not all(marked):
            raise ParameterError(f"window {text!r}: mark both ends absolute with @, or neither")
        bounds: list[float | None] = []
        for part in parts:
            value = part.strip().removeprefix("@")
            if not value:
                bounds.append(None)
                continue
            try:
                bounds.append(float(value))
            except ValueError:
                raise ParameterError(
                    f"window {text!r}: {part.strip()!r} is not a number of seconds"
                ) from None
        if bounds == [None, None]:
            raise ParameterError(f"window {text!r}: give a start, an end or both")
        return cls(start=bounds[0], end=bounds[1], absolute=any(marked))

    def bounds_ns(self, origin_ns: int) -> tuple[int, int]:
        """``(first, last)`` stamp (ns) kept, for a recording whose start is ``origin_ns`` (ns)."""
        base = 0 if self.absolute else origin_ns
        lo = -(2**62) if self.start is None else base + round(self.start * _NS)
        hi = 2**62 if self.end is None else base + round(self.end * _NS)
        return lo, hi

    def mask(self, stamps: np.ndarray, origin_ns: int) -> np.ndarray:
        """Which of ``stamps`` (ns) lie in the window."""
        lo, hi = self.bounds_ns(origin_ns)
        return (stamps >= lo) & (stamps <= hi)

    def text(self) -> str:
        """The window as ``START:END`` (the form :meth:`parse` reads)."""
        mark = "@" if self.absolute else ""
        ends = ["" if v is None else f"{mark}{v:.15g}" for v in (self.start, self.end)]
        return ":".join(ends)

    def describe(self) -> dict[str, Any]:
        """JSON-able record (for a data set's metadata)."""
        return {"start": self.start, "end": self.end, "absolute": self.absolute, "text": self.text()}
