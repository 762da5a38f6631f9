"""Step log of a closed-loop run: one row per control step, columns of floats."""

from __future__ import annotations

import csv
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.core.errors import InputFileError
from rkmpc.core.io import atomic_write, write_json_atomic


class StepLog:
    """Preallocated table of per-step records, shape (time, column).

    Parameters
    ----------
    columns : sequence of str
        Column names.
    capacity : int
        Initial number of rows; grows by doubling when full.
    """

    def __init__(self, columns: Sequence[str], capacity: int = 1024) -> None:
        if len(set(columns)) != len(columns):
            raise ValueError("StepLog: duplicate column names")
        self.columns: tuple[str, ...] = tuple(columns)
        self._index = {name: i for i, name in enumerate(self.columns)}
        self._data = np.full((max(capacity, 1), len(self.columns)), np.nan)
        self._rows = 0
        self.metadata: dict[str, Any] = {}

    def __len__(self) -> int:
        return self._rows

    def append(self, row: np.ndarray) -> None:
        """Append one row (shape (n_columns,))."""
        if self._rows == self._data.shape[0]:
            grown = np.full((2 * self._data.shape[0], self._data.shape[1]), np.nan)
            grown[: self._rows] = self._data[: self._rows]
            self._data = grown
        self._data[self._rows] = row
        self._rows += 1

    def column(self, name: str) -> np.ndarray:
        """One column as a view, shape (time,)."""
        try:
            return self._data[: self._rows, self._index[name]]
        except KeyError:
            raise KeyError(f"no column {name!r} in the log; columns: {self.columns}") from None

    def __getitem__(self, name: str) -> np.ndarray:
        return self.column(name)

    def as_array(self) -> np.ndarray:
        """All rows, shape (time, column)."""
        return self._data[: self._rows]

    def to_csv(self, path: str | Path) -> None:
        """Write the log as CSV (written to a temporary file, then renamed).

        The metadata, if any, is written beside it as ``<path>.meta.json``.
        """
        path = Path(path)
        with atomic_write(path) as handle:
            handle.write(",".join(self.columns) + "\n")
            np.savetxt(handle, self.as_array(), delimiter=",", fmt="%.9g")
        if self.metadata:
            write_json_atomic(path.with_suffix(path.suffix + ".meta.json"), self.metadata)

    @classmethod
    def from_csv(cls, path: str | Path) -> StepLog:
        """Read a log written by :meth:`to_csv`."""
        path = Path(path)
        try:
            with path.open(newline="") as handle:
                header = next(csv.reader(handle))
                data = np.loadtxt(handle, delimiter=",", ndmin=2)
        except FileNotFoundError:
            raise InputFileError(path, "file not found") from None
        except (StopIteration, ValueError) as exc:
            raise InputFileError(path, f"not a step log: {exc}") from None
        if data.size and data.shape[1] != len(header):
            raise InputFileError(path, f"{data.shape[1]} values per row but {len(header)} columns")
        log = cls(header, capacity=max(len(data), 1))
        for row in data:
            log.append(row)
        meta = path.with_suffix(path.suffix + ".meta.json")
        if meta.exists():
            log.metadata = json.loads(meta.read_text())
        return log
