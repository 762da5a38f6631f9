"""A CSV log of a car (a folder of CSV files) as a transition data set, with its data-quality report.

:func:`import_csv_log` reads the signals a :class:`~rkmpc.learning.data.logs.spec.CsvLogSpec`
names, keeps a time window of them (the grid and the commands held are those of the whole log, so a
window's transitions are the whole import's over that span), finds what is wrong with them
(:mod:`rkmpc.learning.data.quality.measures`) and resamples them onto the control period
(:mod:`rkmpc.learning.data.logs.stretches`):

1. the speed sensor's scale against the pose, over the stretches without gaps (first pass);
2. pose jumps, with that scale; they are outliers, never labels: each cuts its stretch, so the
   transitions across it are left out and an episode ends there;
3. the speed scale and the unit checks again, over the stretches without gaps and jumps;
4. the transitions, and the report of all of it.

The data set keeps the raw measurements (no smoothing); ``steer_angle`` and ``slip_angle`` are NaN
(the car measures neither), ``yaw_rate`` too when the spec has no yaw rate.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from rkmpc.core.errors import InputFileError
from rkmpc.learning.data.bags.imported import imported_dataset
from rkmpc.learning.data.bags.read import Stream
from rkmpc.learning.data.bags.resample import Transitions
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.data.logs.read import LogSignals, column_notes, read_signals
from rkmpc.learning.data.logs.spec import CsvLogSpec, ValueSource
from rkmpc.learning.data.logs.stretches import Resampled, cut, resample_stretches, sensor_stretches
from rkmpc.learning.data.quality import measures as m
from rkmpc.learning.data.quality.pose_point import pose_point
from rkmpc.learning.data.quality.records import PoseJump, ScaleFit, UnitCheck
from rkmpc.learning.data.quality.report import QualityReport
from rkmpc.learning.data.quality.speed_command import speed_command_check, with_measured_speed_commands
from rkmpc.learning.data.quality.warnings import findings
from rkmpc.learning.data.units import UNITS
from rkmpc.learning.data.window import TimeWindow
from rkmpc.vehicle.params import VehicleParams

__all__ = ["LogImport", "import_csv_log"]

_NS = 1_000_000_000


@dataclass(frozen=True, eq=False)
class LogImport:
    """What :func:`import_csv_log` made: the data set and the report of the log."""

    data: TransitionDataset
    report: QualityReport


def import_csv_log(
    folder: str | Path,
    vehicle: VehicleParams,
    spec: CsvLogSpec,
    *,
    window: TimeWindow | None = None,
    scale: float | None = None,
) -> LogImport:
    """Read a CSV log as transitions on ``spec.dt``, and report its quality (module docstring).

    Parameters
    ----------
    folder : str or Path
        The log's folder (the spec's files in it).
    vehicle : VehicleParams
        The car: its name and wheelbase go into the contract, its ``lr`` (m) moves a rear-axle
        pose to the centre of gravity.
    spec : CsvLogSpec
        Where each signal is, its units, and the resampling settings.
    window : TimeWindow, optional
        The stretch of the log to keep (seconds from its start: the earliest stamp of the signals
        read); None: all of it.
    scale : float or None
        Scale of the track the car drove (for the contract); None when not known.

    Returns
    -------
    LogImport
        The data set (metadata ``source = "csv"``, the folder, the spec, the window, the row
        counts, the first stamp (s), the contract) and its :class:`QualityReport`.

    Raises
    ------
    InputFileError
        Naming the file and the column: a missing file or column, a bad value, stamps that do not
        increase; naming the folder: a window without data, too few transitions.
    """
    signals = read_signals(folder, spec)
    origin = signals.origin
    span = (max(int(s.stamps[-1]) for s in signals.streams().values()) - origin) / _NS
    commands = signals.command  # all of them: the grid starts at the first, as without a window
    if window is not None:
        signals = _windowed(signals, window, origin, span)
    gap_ns = round(spec.gap * _NS)
    sensors = [s for s in (signals.pose, signals.speed, signals.yaw_rate) if s is not None]
    covered = sensor_stretches(sensors, gap_ns)

    first_fit, (first_rate, _, _) = _fits(signals, _series(signals.pose, covered, origin), origin)
    jump_at, jumps = _jumps(signals, spec, (first_fit.factor if first_fit else 1.0, first_rate), origin)
    kept = cut(covered, jump_at)
    fit, rate = _fits(signals, _series(signals.pose, kept, origin), origin)
    lr = vehicle.lr if spec.pose.frame == "rear-axle" else 0.0

    def run(intervals: list[tuple[int, int]]) -> Resampled:
        return resample_stretches(
            intervals, signals.pose, signals.speed, signals.yaw_rate, commands,
            dt=spec.dt, hold=spec.command_hold, tolerance=spec.tolerance, lr=lr,
        )  # fmt: skip

    result = run(kept)
    if len(result.found) < spec.min_samples:
        raise InputFileError(signals.folder, _too_little(len(result.found), spec, window, span))
    dropped = len(run(covered).found) - len(result.found)
    report = _report(signals, spec, window, fit=fit, rate=rate, jumps=jumps, result=result, dropped=dropped)
    data = _dataset(result.found, signals, spec, window, vehicle, scale)
    check = speed_command_check(data)
    if spec.speed_command == "measured" or (spec.speed_command == "auto" and not check.tracks):
        check = replace(check, replaced=True)
        data = with_measured_speed_commands(data, vehicle.drive.time_constant)
    data = replace(data, metadata={**data.metadata, "speed_command": asdict(check)})
    warning = check.message()
    report = replace(report, speed_command=check, pose_point=pose_point(data, vehicle.lr))
    warnings = findings(report, _dead_columns(signals, spec)) + ((warning,) if warning else ())
    report = replace(report, warnings=warnings)
    return LogImport(data=data, report=report)


def _report(
    signals: LogSignals,
    spec: CsvLogSpec,
    window: TimeWindow | None,
    *,
    fit: ScaleFit | None,
    rate: tuple[float, float, int],
    jumps: tuple[PoseJump, ...],
    result: Resampled,
    dropped: int,
) -> QualityReport:
    """The quality report of an import (:class:`QualityReport` says what each part is)."""
    origin = signals.origin
    found = result.found
    nan = float("nan")
    units = [
        _unit("speed", spec.speed, *((fit.factor, fit.correlation, fit.windows) if fit else (nan, nan, 0)))
    ]
    if spec.yaw_rate is not None:
        units.append(_unit("yaw_rate", spec.yaw_rate, *rate))
    gaps = {"command": spec.command_hold}  # a command holds longer than a sensor's gap is bridged
    report = QualityReport(
        source=str(signals.folder),
        raw=True,
        spec=f"CSV log, spec {spec.name}",
        span_s=_window_span(signals),
        window=None if window is None else window.text(),
        dt=spec.dt,
        transitions=len(found),
        episodes=m.episode_spans((found.stamps - origin) / _NS, found.episode, spec.dt),
        rates=tuple(
            m.signal_rate(name, stream.topic, _t(stream, origin), gaps[name] if name in gaps else spec.gap)
            for name, stream in signals.streams().items()
        ),
        max_gap_s=spec.gap,
        jump_rule=_jump_rule(spec),
        jumps=jumps,
        jump_transitions=dropped,
        speed_scale=fit,
        units=tuple(units),
        reversing=m.reversing(_t(signals.speed, origin), signals.speed.values[:, 0], result.reversing),
        stale_command_samples=result.stale,
        columns=column_notes(signals.tables, spec),
        coverage=m.coverage(found.obs[:, 3], found.obs[:, 4]),
        warnings=(),  # filled in by import_csv_log once the data set is made
    )
    return report


def _t(stream: Stream, origin: int) -> np.ndarray:
    return (stream.stamps - origin) / _NS


def _windowed(signals: LogSignals, window: TimeWindow, origin: int, span: float) -> LogSignals:
    """The signals inside the window; InputFileError when one has fewer than 2 samples there."""
    kept: dict[str, Stream] = {}
    for name, stream in signals.streams().items():
        inside = window.mask(stream.stamps, origin)
        if int(inside.sum()) < 2:
            raise InputFileError(
                signals.folder,
                f"the window {window.text()} holds {int(inside.sum())} sample(s) of {name} "
                f"({stream.topic}); the log spans 0 to {span:.2f} s from its start "
                f"(stamp {origin / _NS:.3f} s)",
                field=stream.topic,
            )
        kept[name] = Stream(stream.topic, stream.stamps[inside], stream.values[inside], stream.fields)
    return LogSignals(
        folder=signals.folder,
        pose=kept["pose"],
        speed=kept["speed"],
        yaw_rate=kept["yaw_rate"] if "yaw_rate" in kept else None,
        command=kept["command"],
        tables=signals.tables,
        origin=signals.origin,
    )


def _window_span(signals: LogSignals) -> float:
    streams = signals.streams().values()
    return (max(int(s.stamps[-1]) for s in streams) - min(int(s.stamps[0]) for s in streams)) / _NS


def _series(pose: Stream, intervals: list[tuple[int, int]], origin: int) -> m.PoseSeries:
    """The poses inside ``intervals`` (ns), numbered by interval."""
    which = np.full(len(pose), -1)
    for k, (lo, hi) in enumerate(intervals):
        which[(pose.stamps >= lo) & (pose.stamps <= hi)] = k
    keep = which >= 0
    return m.PoseSeries(
        t=_t(pose, origin)[keep], xy=pose.values[keep, :2], yaw=pose.values[keep, 2], stretch=which[keep]
    )


def _fits(
    signals: LogSignals, series: m.PoseSeries, origin: int
) -> tuple[ScaleFit | None, tuple[float, float, int]]:
    """The speed scale, and the yaw rate's ``(factor, correlation, windows)``, over ``series``."""
    fit = m.speed_scale(series, _t(signals.speed, origin), signals.speed.values[:, 0])
    rate = signals.yaw_rate
    if rate is None:
        return fit, (float("nan"), float("nan"), 0)
    return fit, m.rate_fit(series, _t(rate, origin), rate.values[:, 0])


def _jumps(
    signals: LogSignals, spec: CsvLogSpec, scales: tuple[float, float], origin: int
) -> tuple[list[tuple[int, int]], tuple[PoseJump, ...]]:
    """Jumps between consecutive poses at most ``max_gap`` apart: their stamps (ns) and records."""
    pose = signals.pose
    interval = np.diff(pose.stamps) / _NS
    close = interval <= spec.gap
    mid = pose.stamps[:-1] + np.diff(pose.stamps) // 2
    speed = np.interp(mid, signals.speed.stamps, signals.speed.values[:, 0])
    rate = signals.yaw_rate
    yaw_rate = (
        np.interp(mid, rate.stamps, rate.values[:, 0]) if rate is not None else np.full(len(mid), np.nan)
    )
    moved = np.hypot(*np.diff(pose.values[:, :2], axis=0).T)
    jump, allowed, excess = m.jump_test(
        interval, moved, np.diff(pose.values[:, 2]), speed, yaw_rate,
        scales=scales, distance=spec.jump_distance, turn=spec.jump_yaw,
    )  # fmt: skip
    rows = np.flatnonzero(jump & close)
    at = [(int(pose.stamps[k]), int(pose.stamps[k + 1])) for k in rows]
    t = _t(pose, origin)[rows + 1]
    return at, m.jumps_of(t, interval[rows], moved[rows], allowed[rows], excess[rows])


def _jump_rule(spec: CsvLogSpec) -> str:
    return (
        f"Between two poses at most {spec.gap:g} s apart, a pose that moved more than "
        f"{spec.jump_distance:g} m farther than the speed sensor allows (|v| dt, the sensor divided "
        f"by its scale of a first pass), or turned more than {spec.jump_yaw:g} rad farther than the "
        "yaw rate allows (divided by its factor likewise), jumped. A jump is an outlier, never a "
        "label: the episode ends at it and the transitions across it are left out."
    )


def _unit(name: str, source: ValueSource, factor: float, correlation: float, windows: int) -> UnitCheck:
    return m.unit_check(
        signal=name,
        column=f"{source.file}:{source.column}",
        declared=source.unit,
        factor=factor,
        correlation=correlation,
        windows=windows,
        units=UNITS["speed" if name == "speed" else "rate"],
        column_scale=source.scale,
    )


def _dead_columns(signals: LogSignals, spec: CsvLogSpec) -> tuple[str, ...]:
    """The spec's value columns that are constant in every row (nothing measured)."""
    used = [(spec.speed.file, spec.speed.column, signals.speed)]
    if spec.yaw_rate is not None and signals.yaw_rate is not None:
        used.append((spec.yaw_rate.file, spec.yaw_rate.column, signals.yaw_rate))
    return tuple(
        f"{file}:{column}" for file, column, stream in used if np.all(stream.values == stream.values[0])
    )


def _too_little(count: int, spec: CsvLogSpec, window: TimeWindow | None, span: float) -> str:
    where = f" in the window {window.text()}" if window is not None else ""
    return (
        f"too little data: {count} transitions{where} at dt = {spec.dt:g} s, need at least "
        f"{spec.min_samples} (the log spans {span:.2f} s; its quality report says where the data went)"
    )


def _dataset(
    found: Transitions,
    signals: LogSignals,
    spec: CsvLogSpec,
    window: TimeWindow | None,
    vehicle: VehicleParams,
    scale: float | None,
) -> TransitionDataset:
    source = {
        "source": "csv",
        "log": str(signals.folder),
        "csv_spec": spec.describe(),
        "window": None if window is None else window.describe(),
        "rows": {name: len(stream) for name, stream in signals.streams().items()},
        "start_stamp": signals.origin / _NS,
        "dt": spec.dt,
    }
    return imported_dataset(found, source, dt=spec.dt, vehicle=vehicle, scale=scale)
