"""Read the files of a CSV log into time-stamped signals in SI units, checked.

Every problem is an :class:`~rkmpc.core.errors.InputFileError` naming the file, the column and
the problem (with the row, counted from 1 after the header): a missing file or column (listing
the columns the file has), a row of the wrong length, a value that is no number or not finite,
stamps that go backwards or repeat.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rkmpc.core.errors import InputFileError
from rkmpc.learning.data.bags.read import Stream
from rkmpc.learning.data.logs.spec import CsvLogSpec, TimeColumns, ValueSource
from rkmpc.learning.data.units import UNITS

__all__ = ["CsvTable", "LogSignals", "column_notes", "read_signals", "read_table"]

_NS = 1_000_000_000


@dataclass(frozen=True, eq=False)
class CsvTable:
    """One CSV file: its header and its rows as text."""

    path: Path
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]

    def column(self, name: str) -> np.ndarray:
        """The column ``name`` as floats; InputFileError for a missing column or a bad value."""
        if name not in self.header:
            named = [h for h in self.header if h]
            raise InputFileError(self.path, f"no such column; the file has {named}", field=name)
        j = self.header.index(name)
        text = [row[j] for row in self.rows]
        try:
            values = np.array(text, dtype=float)
        except ValueError:
            k = next(k for k, v in enumerate(text) if not _is_number(v))
            raise InputFileError(self.path, f"row {k + 1}: {text[k]!r} is not a number", field=name) from None
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise InputFileError(self.path, f"row {bad[0] + 1}: {text[bad[0]]!r} is not finite", field=name)
        return values

    def stamps(self, time: TimeColumns) -> np.ndarray:
        """Stamps (ns, int64) of the rows, strictly increasing; InputFileError naming the column."""
        per_unit = round(UNITS["time"][time.unit] * _NS)  # ns per unit of the seconds column
        seconds = self.column(time.seconds)
        whole = np.floor(seconds)  # whole units exactly, the fraction in float (no loss at 1e9 s)
        stamps = whole.astype(np.int64) * per_unit + np.round((seconds - whole) * per_unit).astype(np.int64)
        if time.nanoseconds is not None:
            stamps = stamps + np.round(self.column(time.nanoseconds)).astype(np.int64)
        step = np.diff(stamps)
        if np.any(step <= 0):
            k = int(np.flatnonzero(step <= 0)[0]) + 1
            how = "goes backwards" if step[k - 1] < 0 else "repeats the one before"
            where = time.seconds if time.nanoseconds is None else f"{time.seconds}+{time.nanoseconds}"
            raise InputFileError(
                self.path, f"row {k + 1}: the stamp {how} (stamps must increase)", field=where
            )
        return stamps


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_table(path: Path) -> CsvTable:
    """The header and rows of a CSV file; InputFileError for a missing, empty or ragged file."""
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            rows = [tuple(cell.strip() for cell in row) for row in csv.reader(handle) if row]
    except FileNotFoundError:
        raise InputFileError(path, "no such file in the log's folder") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputFileError(path, f"cannot read the CSV file: {exc}") from None
    if len(rows) < 3:
        raise InputFileError(path, f"needs a header row and at least 2 rows of data, got {len(rows)} rows")
    header = rows[0]
    for k, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputFileError(path, f"row {k + 1} has {len(row)} values, the header {len(header)} columns")
    return CsvTable(path=path, header=header, rows=tuple(rows[1:]))


@dataclass(frozen=True, eq=False)
class LogSignals:
    """The signals of a log in SI units, each on its own stamps (ns).

    Parameters
    ----------
    folder : Path
        The log's folder.
    pose : Stream
        Columns ``x, y`` (m) and ``yaw`` (rad, unwrapped: continuous over the log).
    speed : Stream
        Column ``speed`` (m/s, signed).
    yaw_rate : Stream or None
        Column ``yaw_rate`` (rad/s); None when the spec has none.
    command : Stream
        Columns ``speed`` (m/s), ``steer`` (rad).
    tables : dict of str to CsvTable
        The files read, by name.
    origin : int
        The log's start (ns): the earliest stamp of any signal as read (before a window).
    """

    folder: Path
    pose: Stream
    speed: Stream
    yaw_rate: Stream | None
    command: Stream
    tables: dict[str, CsvTable]
    origin: int

    def streams(self) -> dict[str, Stream]:
        """The signals by name (``pose``, ``speed``, ``yaw_rate`` when measured, ``command``)."""
        named = {"pose": self.pose, "speed": self.speed, "yaw_rate": self.yaw_rate, "command": self.command}
        return {name: stream for name, stream in named.items() if stream is not None}


def read_signals(folder: str | Path, spec: CsvLogSpec) -> LogSignals:
    """Read the files of ``spec`` in ``folder`` and convert every signal to SI (module docstring)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise InputFileError(folder, "no such folder (a CSV log is a folder of CSV files)")
    tables = {name: read_table(folder / name) for name in spec.files}
    pose = spec.pose
    table = tables[pose.file]
    length = UNITS["length"][pose.unit]
    if pose.yaw is not None:
        yaw = table.column(pose.yaw) * UNITS["angle"][pose.yaw_unit]
    else:
        qx, qy, qz, qw = (table.column(c) for c in pose.quaternion or ())
        yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    values = np.stack([table.column(pose.x) * length, table.column(pose.y) * length, np.unwrap(yaw)], 1)
    pose_stream = Stream(pose.file, table.stamps(pose.time), values, ("x", "y", "yaw"))
    command = spec.command
    table = tables[command.file]
    speed = table.column(command.speed) * UNITS["speed"][command.speed_unit]
    steer = table.column(command.steer) * UNITS["angle"][command.steer_unit]
    command_stream = Stream(
        command.file, table.stamps(command.time), np.stack([speed, steer], 1), ("speed", "steer")
    )
    speed_stream = _value(tables, spec.speed, "speed", "speed")
    rate_stream = None if spec.yaw_rate is None else _value(tables, spec.yaw_rate, "rate", "yaw_rate")
    streams = [s for s in (pose_stream, speed_stream, rate_stream, command_stream) if s is not None]
    return LogSignals(
        folder=folder,
        pose=pose_stream,
        speed=speed_stream,
        yaw_rate=rate_stream,
        command=command_stream,
        tables=tables,
        origin=min(int(s.stamps[0]) for s in streams),
    )


def _value(tables: dict[str, CsvTable], source: ValueSource, quantity: str, name: str) -> Stream:
    table = tables[source.file]
    factor = UNITS[quantity][source.unit] * source.scale
    values = (table.column(source.column) * factor)[:, None]
    return Stream(source.file, table.stamps(source.time), values, (name,))


def column_notes(tables: dict[str, CsvTable], spec: CsvLogSpec) -> tuple[tuple[str, str], ...]:
    """``(file, note)`` for columns that carry nothing: constant in every row, or repeating another.

    Time columns and columns that are not numbers are left out.
    """
    time_columns = {
        c for s in (spec.pose, spec.speed, spec.yaw_rate, spec.command) if s for c in s.time.columns
    }
    notes: list[tuple[str, str]] = []
    for name, table in tables.items():
        columns: dict[str, np.ndarray] = {}
        for column in table.header:
            if column and column not in time_columns:
                try:
                    columns[column] = table.column(column)
                except InputFileError:
                    continue
        constant: dict[float, list[str]] = {}
        for column, values in columns.items():
            if np.all(values == values[0]):
                constant.setdefault(float(values[0]), []).append(column)
        for value, names in constant.items():
            verb = "is" if len(names) == 1 else "are"
            notes.append((name, f"{', '.join(names)} {verb} {_plain(value)} in every row"))
        varying = [c for c in columns if not any(c in names for names in constant.values())]
        for k, column in enumerate(varying):
            for other in varying[:k]:
                if np.array_equal(columns[column], columns[other]):
                    notes.append((name, f"{column} repeats {other} in every row"))
                    break
    return tuple(notes)


def _plain(value: float) -> str:
    return str(int(value)) if math.isfinite(value) and value == int(value) else f"{value:g}"
