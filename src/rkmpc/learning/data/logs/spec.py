"""What a CSV log holds and where: the column mapping of :func:`~rkmpc.learning.data.logs.import_csv_log`.

A log is a folder of CSV files with a header row. A :class:`CsvLogSpec` says, per signal, the file,
the time columns, the value columns and their units:

* **pose** (required): ``x, y`` and a heading, either a yaw column or a quaternion
  ``(qx, qy, qz, qw)`` (the yaw about the vertical axis is taken from it);
* **speed** (required): the speed along the heading, signed (negative: reversing);
* **yaw rate** (optional; NaN in the data set when not given);
* **commands** (required): the speed and steering commands sent to the car.

Every value is converted to SI by its unit (:data:`~rkmpc.learning.data.units.UNITS`) and an
extra ``scale`` (a gain or a sign). The car measures no wheel angle and no side slip here: both
are NaN in the data set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rkmpc.core.errors import ParameterError
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.core.validation import is_integer, require_choice
from rkmpc.learning.data.quality.speed_command import SPEED_COMMAND_RULES
from rkmpc.learning.data.resampling import GapAndTolerance
from rkmpc.learning.data.units import unit_factor

__all__ = [
    "POSE_FRAMES",
    "CommandSource",
    "CsvLogSpec",
    "PoseSource",
    "TimeColumns",
    "ValueSource",
]

#: Where the pose's frame sits on the car: the centre of gravity or the rear axle's centre.
POSE_FRAMES = ("cog", "rear-axle")


def _name(value: Any, where: str) -> None:
    if not (isinstance(value, str) and value.strip() and value == value.strip()):
        raise ParameterError(f"{where} must be a column or file name, got {value!r}")


def _scale(value: Any, where: str) -> None:
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not math.isfinite(value)
        or value == 0
    ):
        raise ParameterError(f"{where} must be a finite number other than 0, got {value!r}")


@dataclass(frozen=True)
class TimeColumns:
    """How a file's rows are stamped: ``seconds * unit`` plus ``nanoseconds`` (ns), when given.

    Parameters
    ----------
    seconds : str
        Column of the time (a float, or the whole seconds of a ROS stamp).
    nanoseconds : str or None
        Column of the stamp's nanoseconds (ROS ``sec`` + ``nanosec``); None: ``seconds`` alone.
    unit : str
        Unit of the ``seconds`` column: ``"s"``, ``"ms"``, ``"us"`` or ``"ns"``.
    """

    seconds: str
    nanoseconds: str | None = None
    unit: str = "s"

    def __post_init__(self) -> None:
        _name(self.seconds, "TimeColumns.seconds")
        if self.nanoseconds is not None:
            _name(self.nanoseconds, "TimeColumns.nanoseconds")
            if self.nanoseconds == self.seconds:
                raise ParameterError("TimeColumns: seconds and nanoseconds must be different columns")
        unit_factor("time", self.unit, "TimeColumns.unit")

    @property
    def columns(self) -> tuple[str, ...]:
        return (self.seconds,) if self.nanoseconds is None else (self.seconds, self.nanoseconds)


@dataclass(frozen=True, kw_only=True)
class PoseSource:
    """The pose: position of the car's frame in the map and its heading.

    Parameters
    ----------
    file : str
        CSV file (in the log's folder).
    time : TimeColumns
        Its time columns.
    x, y : str
        Position columns.
    yaw : str or None
        Heading column; exactly one of ``yaw`` and ``quaternion``.
    quaternion : tuple of 4 str or None
        Orientation columns ``(qx, qy, qz, qw)``; the yaw is ``atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))``.
    unit : str
        Unit of ``x, y`` (``"m"``, ``"cm"``, ``"mm"``).
    yaw_unit : str
        Unit of the ``yaw`` column (``"rad"``, ``"deg"``).
    frame : str
        Where the frame sits: ``"cog"`` (taken as is) or ``"rear-axle"`` (moved ``lr`` ahead).
    """

    file: str
    time: TimeColumns
    x: str
    y: str
    yaw: str | None = None
    quaternion: tuple[str, str, str, str] | None = None
    unit: str = "m"
    yaw_unit: str = "rad"
    frame: str = "cog"

    def __post_init__(self) -> None:
        _name(self.file, "PoseSource.file")
        for field in ("x", "y"):
            _name(getattr(self, field), f"PoseSource.{field}")
        if (self.yaw is None) == (self.quaternion is None):
            raise ParameterError("PoseSource: give the heading as yaw or as quaternion (one of them)")
        if self.yaw is not None:
            _name(self.yaw, "PoseSource.yaw")
        if self.quaternion is not None:
            if not (isinstance(self.quaternion, tuple) and len(self.quaternion) == 4):
                raise ParameterError(f"PoseSource.quaternion must be 4 columns, got {self.quaternion!r}")
            for column in self.quaternion:
                _name(column, "PoseSource.quaternion")
        unit_factor("length", self.unit, "PoseSource.unit")
        unit_factor("angle", self.yaw_unit, "PoseSource.yaw_unit")
        require_choice(self, "frame", POSE_FRAMES)

    @property
    def columns(self) -> tuple[str, ...]:
        heading = (self.yaw,) if self.yaw is not None else self.quaternion
        return (self.x, self.y, *(heading or ()))


@dataclass(frozen=True, kw_only=True)
class ValueSource:
    """One measured value (a speed or a yaw rate): ``SI = raw * unit factor * scale``.

    Parameters
    ----------
    file : str
        CSV file.
    time : TimeColumns
        Its time columns.
    column : str
        The value's column.
    unit : str
        Its unit (:data:`~rkmpc.learning.data.units.UNITS`, of the quantity the spec uses it for).
    scale : float
        Extra factor (a gain, or -1 for a sign), not 0.
    """

    file: str
    time: TimeColumns
    column: str
    unit: str
    scale: float = 1.0

    def __post_init__(self) -> None:
        _name(self.file, "ValueSource.file")
        _name(self.column, "ValueSource.column")
        _scale(self.scale, "ValueSource.scale")


@dataclass(frozen=True, kw_only=True)
class CommandSource:
    """The commands sent to the car: speed and steering angle.

    Parameters
    ----------
    file : str
        CSV file.
    time : TimeColumns
        Its time columns.
    speed, steer : str
        Columns of the speed and steering commands.
    speed_unit : str
        Unit of the speed command (:data:`~rkmpc.learning.data.units.UNITS` ``"speed"``).
    steer_unit : str
        Unit of the steering command (``"rad"``, ``"deg"``).
    """

    file: str
    time: TimeColumns
    speed: str
    steer: str
    speed_unit: str = "m/s"
    steer_unit: str = "rad"

    def __post_init__(self) -> None:
        _name(self.file, "CommandSource.file")
        _name(self.speed, "CommandSource.speed")
        _name(self.steer, "CommandSource.steer")
        unit_factor("speed", self.speed_unit, "CommandSource.speed_unit")
        unit_factor("angle", self.steer_unit, "CommandSource.steer_unit")


@dataclass(frozen=True, kw_only=True)
class CsvLogSpec(GapAndTolerance):
    """Where a CSV log keeps each signal, and how the import resamples it.

    Parameters
    ----------
    name : str
        Name of the layout (a preset's name, or the spec file's).
    pose : PoseSource
        The pose.
    speed : ValueSource
        The speed along the heading (a ``"speed"`` unit), signed.
    yaw_rate : ValueSource or None
        The yaw rate (a ``"rate"`` unit); None: not measured (NaN).
    command : CommandSource
        The commands.
    description : str
        What the layout is and why its signals come from where they do.
    dt : float
        Control period (s) the log is resampled onto, > 0.
    max_gap : float or None
        A gap (s) of any signal longer than this ends an episode; None: three periods.
    command_hold : float
        How long (s) a command holds after its stamp (a joystick's teleop publishes irregularly);
        a sample with an older command is not used. > 0.
    command_tolerance : float or None
        A command stamped up to this long (s) after a sample counts for it; in ``[0, dt)``;
        None: a quarter period.
    jump_distance : float
        A pose that moved farther (m) than the speed sensor allows, by more than this, is a jump.
    jump_yaw : float
        A heading that turned farther (rad) than the yaw rate allows, by more than this, is a jump.
    min_samples : int
        Fewer transitions than this are an error.
    speed_command : str
        ``"auto"`` (default): replace the recorded speed command by the measured speed where it did
        not set the car's speed (a remote-controlled log:
        :mod:`rkmpc.learning.data.quality.speed_command`); ``"recorded"``: keep it; ``"measured"``:
        always replace it.
    """

    name: str
    pose: PoseSource
    speed: ValueSource
    yaw_rate: ValueSource | None
    command: CommandSource
    description: str = ""
    dt: float = 0.05
    max_gap: float | None = None
    command_hold: float = 0.5
    command_tolerance: float | None = None
    jump_distance: float = 0.3
    jump_yaw: float = 0.3
    min_samples: int = 20
    speed_command: str = "auto"

    def __post_init__(self) -> None:
        _name(self.name, "CsvLogSpec.name")
        unit_factor("speed", self.speed.unit, "CsvLogSpec.speed.unit")
        if self.yaw_rate is not None:
            unit_factor("rate", self.yaw_rate.unit, "CsvLogSpec.yaw_rate.unit")
        positive = ("dt", "command_hold", "jump_distance", "jump_yaw")
        for field in positive:
            value = getattr(self, field)
            if not (_real(value) and value > 0):
                raise ParameterError(f"CsvLogSpec.{field} must be finite and > 0, got {value!r}")
        if self.max_gap is not None and not (_real(self.max_gap) and self.max_gap > 0):
            raise ParameterError(f"CsvLogSpec.max_gap must be None or finite and > 0, got {self.max_gap!r}")
        tol = self.command_tolerance
        if tol is not None and not (_real(tol) and 0 <= tol < self.dt):
            raise ParameterError(f"CsvLogSpec.command_tolerance must be None or in [0, dt), got {tol!r}")
        require_choice(self, "speed_command", SPEED_COMMAND_RULES)
        if not is_integer(self.min_samples, 1):
            raise ParameterError(f"CsvLogSpec.min_samples must be an integer >= 1, got {self.min_samples!r}")

    @property
    def files(self) -> tuple[str, ...]:
        """The files the spec reads, each once, in the order of the signals."""
        names = [self.pose.file, self.speed.file, self.command.file]
        if self.yaw_rate is not None:
            names.insert(2, self.yaw_rate.file)
        return tuple(dict.fromkeys(names))

    def describe(self) -> dict[str, Any]:
        """JSON-able record of the mapping and the settings (for a data set's metadata)."""
        record = to_json_ready(self)
        return {**record, "max_gap": self.gap, "command_tolerance": self.tolerance}


def _real(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, int | float) and math.isfinite(value)
