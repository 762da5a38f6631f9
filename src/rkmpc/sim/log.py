"""Step log of a closed-loop run: one row per control step, columns of floats."""

from __future__ import annotations

import csv
import json
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rkmpc.errors import InputFileError


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
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "w", newline="") as handle:
                handle.write(",".join(self.columns) + "\n")
                np.savetxt(handle, self.as_array(), delimiter=",", fmt="%.9g")
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
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


def write_json_atomic(path: str | Path, payload: Any) -> None:
    """Write JSON to a temporary file in the same folder, then rename it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as handle:
            json.dump(payload, handle, indent=2, sort_keys=False, default=json_default)
            handle.write("\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def json_default(value: Any) -> Any:
    """``default=`` hook of :func:`json.dump` for numpy values, paths and tuples."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, tuple):
        return list(value)
    raise TypeError(f"cannot write {type(value).__name__} as JSON")
