"""Load tracks from CSV files in the TUM racetrack-database format.

Centerline files have the columns ``x_m, y_m, w_tr_right_m, w_tr_left_m``
and raceline files ``x_m, y_m``.  The first line is a header naming the
columns (comma separated, optionally starting with ``#``); columns are found
by name, so their order does not matter and extra columns are ignored.  The
points form a closed loop; the first point should not be repeated at the end
(if it is, the copy is dropped).

Validation rules (each failure raises :class:`rkmpc.core.errors.InputFileError`
naming the file, the column where relevant, and the problem):

* the file must exist and be readable text with a header line;
* every required column must be present; every value must parse as a number
  (the error gives the line number) and be finite;
* widths must be > 0;
* consecutive exact duplicate points are dropped silently (this includes a
  repeated closing point); at least 4 distinct points must remain;
* the line must be closable: the closing gap (last point to first point) must
  not exceed ``CLOSING_GAP_FACTOR`` (4) times the median spacing of the other
  points *and* twice the largest other spacing.  A gap failing both tests is
  taken as an open line (e.g. a C shape);
* the closed polyline may cross itself only at a bridge (the track passing over itself, a
  figure-8): the two passes far apart along the lap and crossing at a real angle (the rule is
  :mod:`rkmpc.track.crossings`); a line that folds back on itself locally (a small loop, a
  zig-zag) is refused, naming the lines of the two crossing segments;
* the smoothed line (the periodic spline through the points, sampled about every 2 cm) must
  cross itself nowhere but at the polyline's bridges: the spline of a sharp hairpin between
  sparse points can loop over itself where the points do not; the error names the place (its
  arc length, the nearest lines) and says it is the smoothed line.

The crossings found are recorded in :attr:`rkmpc.track.track.Track.crossings`.
"""

from __future__ import annotations

import math
from pathlib import Path as FilePath

import numpy as np
from numpy.typing import NDArray

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.io import display_name
from rkmpc.track.crossings import (
    Crossing,
    bridge_problem,
    find_self_intersection,
    path_crossings,
    segment_crossings,
)
from rkmpc.track.path import Path
from rkmpc.track.points import dedupe_mask
from rkmpc.track.track import Track, track_length_problem

__all__ = [
    "CLOSING_GAP_FACTOR",
    "find_self_intersection",
    "load_centerline",
    "load_raceline",
    "load_track",
]

FloatArray = NDArray[np.float64]

CLOSING_GAP_FACTOR = 4.0
"""A closing gap larger than this many median spacings (and than twice the largest) is an open line."""

_CENTER_COLUMNS = ("x_m", "y_m", "w_tr_right_m", "w_tr_left_m")
_RACE_COLUMNS = ("x_m", "y_m")


def _check_length(file: FilePath, line: Path) -> None:
    """InputFileError naming ``file`` when ``line`` is too long for a track (:data:`MAX_TRACK_LENGTH`)."""
    problem = track_length_problem(line.length)
    if problem is not None:
        raise InputFileError(file, problem, field="x_m,y_m")


def _check_scale(scale: float) -> float:
    try:
        value = float(scale)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"scale must be a finite number > 0, got {scale!r}") from exc
    if not (math.isfinite(value) and value > 0.0):
        raise ParameterError(f"scale must be a finite number > 0, got {scale!r}")
    return value


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _read_columns(path: FilePath, required: tuple[str, ...]) -> dict[str, FloatArray]:
    """Read the ``required`` columns of a CSV file as float arrays (one value per data row)."""
    if not path.is_file():
        raise InputFileError(path, "file does not exist or is not a regular file")
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark (Excel exports) is not data
    except (OSError, UnicodeDecodeError) as exc:
        raise InputFileError(path, f"cannot read file: {exc}") from exc

    lines = text.splitlines()
    header: list[str] | None = None
    header_line = 0
    for lineno, raw in enumerate(lines, start=1):
        stripped = raw.strip()
        if not stripped:
            continue
        body = stripped.lstrip("#").strip()
        tokens = [t.strip() for t in body.split(",")]
        if stripped.startswith("#") or not all(_is_number(t) for t in tokens):
            header = tokens
            header_line = lineno
        break
    if header is None:
        raise InputFileError(path, f"no header line naming the columns (expected {', '.join(required)})")

    col_index: dict[str, int] = {}
    for name in required:
        if name not in header:
            raise InputFileError(
                path, f"missing column {name!r} (header has: {', '.join(header)})", field=name
            )
        col_index[name] = header.index(name)

    n_cols = len(header)
    rows: list[list[float]] = []
    line_numbers: list[int] = []
    for lineno, raw in enumerate(lines[header_line:], start=header_line + 1):
        stripped = raw.strip()
        if not stripped or stripped.startswith("#"):
            continue
        tokens = [t.strip() for t in stripped.split(",")]
        if len(tokens) != n_cols:
            raise InputFileError(path, f"line {lineno}: expected {n_cols} values, found {len(tokens)}")
        row: list[float] = []
        for name in required:
            token = tokens[col_index[name]]
            try:
                value = float(token)
            except ValueError:
                problem = f"line {lineno}: non-numeric value {token!r}"
                raise InputFileError(path, problem, field=name) from None
            if not math.isfinite(value):
                raise InputFileError(path, f"line {lineno}: value {token!r} is not finite", field=name)
            row.append(value)
        rows.append(row)
        line_numbers.append(lineno)

    data = np.array(rows, dtype=float).reshape(-1, len(required))
    out = {name: data[:, k] for k, name in enumerate(required)}
    out["_line"] = np.array(line_numbers, dtype=float)
    return out


def _validate_loop(
    path: FilePath, cols: dict[str, FloatArray], width_cols: tuple[str, ...]
) -> NDArray[np.bool_]:
    """Check a loop read from ``path``; return the mask of rows kept after de-duplication."""
    xy = np.column_stack([cols["x_m"], cols["y_m"]])
    lines = cols["_line"]
    for name in width_cols:
        bad = np.flatnonzero(cols[name] <= 0.0)
        if bad.size:
            k = int(bad[0])
            raise InputFileError(
                path,
                f"line {int(lines[k])}: width must be > 0, got {cols[name][k]:g}",
                field=name,
            )
    keep = dedupe_mask(xy)
    pts = xy[keep]
    if pts.shape[0] < 4:
        raise InputFileError(path, f"need at least 4 distinct points, found {pts.shape[0]}", field="x_m,y_m")

    spacing = np.hypot(*np.diff(pts, axis=0).T)
    gap = float(np.hypot(*(pts[0] - pts[-1])))
    median = float(np.median(spacing))
    if gap > CLOSING_GAP_FACTOR * median and gap > 2.0 * float(spacing.max()):
        raise InputFileError(
            path,
            f"line is not closable: gap of {gap:.3g} m between the last and the first point is more than "
            f"{CLOSING_GAP_FACTOR:g} x the median spacing ({median:.3g} m); expected a closed loop",
            field="x_m,y_m",
        )
    rows = np.flatnonzero(keep)
    widths = sum((cols[name][keep] for name in width_cols), np.zeros(pts.shape[0]))
    closed = np.vstack([pts, pts[:1]])
    s_pts = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(closed, axis=0).T))])
    for hit in segment_crossings(pts):
        s1 = s_pts[hit.i] + hit.t_i * (s_pts[hit.i + 1] - s_pts[hit.i])
        s2 = s_pts[hit.j] + hit.t_j * (s_pts[hit.j + 1] - s_pts[hit.j])
        length = float(s_pts[-1])
        separation = min(abs(s2 - s1), length - abs(s2 - s1))
        width = float(max(widths[hit.i], widths[hit.j]))
        problem = bridge_problem(separation, math.asin(hit.sin_angle), length, width)
        if problem is not None:
            li = int(lines[rows[hit.i]])
            lj = int(lines[rows[hit.j]])
            raise InputFileError(
                path,
                f"line is self-intersecting: the segment starting at line {li} crosses the one "
                f"starting at line {lj}, and it is no bridge: {problem}",
                field="x_m,y_m",
            )
    return keep


def _check_smoothed(
    file: FilePath, line: Path, pts: FloatArray, file_lines: FloatArray, widths: FloatArray | None
) -> tuple[Crossing, ...]:
    """Check the smoothed line (the spline through ``pts``, sampled densely) for crossings.

    Every crossing of the spline must be one of the polyline's (already checked to be bridges)
    and a bridge itself (with the projection window of ``line``); the spline of a sharp bend
    between sparse points can cross itself where the points do not.  Returns the crossings.
    """
    length = line.length
    knots = np.append(line.knot_s, length)
    width_at = (
        (lambda s: 0.0)
        if widths is None
        else (lambda s: float(np.interp(s, knots, np.append(widths, widths[0]))))
    )
    poly: list[tuple[float, float]] = []
    for hit in segment_crossings(pts):
        s1 = knots[hit.i] + hit.t_i * (knots[hit.i + 1] - knots[hit.i])
        s2 = knots[hit.j] + hit.t_j * (knots[hit.j + 1] - knots[hit.j])
        poly.append((float(s1 % length), float(s2 % length)))
    tol = 3.0 * float(np.max(np.diff(knots)))

    def near(a: float, b: float) -> bool:
        d = abs(a - b) % length
        return min(d, length - d) < tol

    found = path_crossings(line)
    for c in found:
        matched = any(
            (near(c.s_first, a) and near(c.s_second, b)) or (near(c.s_first, b) and near(c.s_second, a))
            for a, b in poly
        )
        width = max(width_at(c.s_first), width_at(c.s_second))
        problem = bridge_problem(c.separation, c.angle, length, width, line.default_window)
        if matched and problem is None:
            continue
        rows = [int(file_lines[int(np.argmin(np.abs(line.knot_s - s)))]) for s in (c.s_first, c.s_second)]
        why = "its points do not cross there" if problem is None else problem
        raise InputFileError(
            file,
            f"the smoothed line (the spline through the points) crosses itself at ({c.x:.3g}, {c.y:.3g}) m, "
            f"at s = {c.s_first:.4g} m and s = {c.s_second:.4g} m along the lap (near lines {rows[0]} "
            f"and {rows[1]}), and {why}: a sharp bend between too few points? add points there",
            field="x_m,y_m",
        )
    return tuple(found)


def _read_loop(
    path: str | FilePath, scale: float, columns: tuple[str, ...], width_cols: tuple[str, ...]
) -> tuple[float, FilePath, dict[str, FloatArray], NDArray[np.bool_], FloatArray]:
    """Read and check the loop of ``path``: ``(scale factor, file, columns, kept rows, scaled xy in m)``."""
    factor = _check_scale(scale)
    file = FilePath(path)
    cols = _read_columns(file, columns)
    keep = _validate_loop(file, cols, width_cols)
    xy = factor * np.column_stack([cols["x_m"][keep], cols["y_m"][keep]])
    return factor, file, cols, keep, xy


def load_centerline(path: str | FilePath, *, scale: float = 1.0, name: str | None = None) -> Track:
    """Load a track centerline with widths.

    Parameters
    ----------
    path : str or pathlib.Path
        CSV file with columns ``x_m, y_m, w_tr_right_m, w_tr_left_m`` (m).
    scale : float, default 1.0
        Factor applied to positions and widths (e.g. 0.1 for a 1:10 car).
    name : str, optional
        Track name; defaults to the file stem.

    Returns
    -------
    Track
        Track without a raceline; widths are interpolated (periodic, linear)
        from the file's points onto a uniform arc-length grid.

    Raises
    ------
    InputFileError
        If the file is missing, unreadable or invalid (see module docstring).
    ParameterError
        If ``scale`` is not finite and positive.
    """
    factor, file, cols, keep, xy = _read_loop(path, scale, _CENTER_COLUMNS, ("w_tr_right_m", "w_tr_left_m"))
    wr = factor * cols["w_tr_right_m"][keep]
    wl = factor * cols["w_tr_left_m"][keep]
    track_name = display_name(file.stem) if name is None else name
    centerline = Path.from_points(xy, name=track_name, source=display_name(str(file)))
    _check_length(file, centerline)
    crossings = _check_smoothed(file, centerline, xy, cols["_line"][keep], wr + wl)
    # Resample the widths onto a uniform arc-length grid (same number of samples as points).
    length = centerline.length
    s_pts = np.append(centerline.knot_s, length)
    m = s_pts.size - 1
    s_grid = np.arange(m) * (length / m)
    wr_grid = np.interp(s_grid, s_pts, np.append(wr, wr[0]))
    wl_grid = np.interp(s_grid, s_pts, np.append(wl, wl[0]))
    return Track(
        track_name,
        centerline,
        wr_grid,
        wl_grid,
        scale=factor,
        source=display_name(str(file)),
        crossings=crossings,
    )


def load_raceline(path: str | FilePath, *, scale: float = 1.0, name: str | None = None) -> Path:
    """Load a racing line.

    Parameters
    ----------
    path : str or pathlib.Path
        CSV file with columns ``x_m, y_m`` (m).
    scale : float, default 1.0
        Factor applied to positions.
    name : str, optional
        Path name; defaults to the file stem.

    Returns
    -------
    Path

    Raises
    ------
    InputFileError, ParameterError
        As :func:`load_centerline`: a missing, unreadable or invalid file, or a bad ``scale``.
    """
    _, file, cols, keep, xy = _read_loop(path, scale, _RACE_COLUMNS, ())
    raceline = Path.from_points(
        xy, name=display_name(file.stem) if name is None else name, source=display_name(str(file))
    )
    _check_length(file, raceline)
    _check_smoothed(file, raceline, xy, cols["_line"][keep], None)
    return raceline


def load_track(
    centerline: str | FilePath,
    raceline: str | FilePath | None = None,
    *,
    scale: float = 1.0,
) -> Track:
    """Load a track (centerline with widths) and optionally its racing line.

    Parameters
    ----------
    centerline : str or pathlib.Path
        Centerline CSV file (see :func:`load_centerline`); its stem names the track.
    raceline : str or pathlib.Path, optional
        Raceline CSV file (see :func:`load_raceline`).
    scale : float, default 1.0
        Factor applied to all positions and widths.

    Returns
    -------
    Track
    """
    track = load_centerline(centerline, scale=scale)
    if raceline is None:
        return track
    return track.with_raceline(load_raceline(raceline, scale=scale))
