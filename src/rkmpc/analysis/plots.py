"""Plots made from step logs (never inside the numerics)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from rkmpc.analysis.maps import draw_map, draw_zoom, is_long_track
from rkmpc.analysis.styles import CONTROLLER_STYLE, controller_style
from rkmpc.core.io import atomic_write
from rkmpc.sim.log import StepLog
from rkmpc.track.track import Track

__all__ = [
    "CONTROLLER_STYLE",
    "controller_style",
    "fallback_steps",
    "plot_runs",
    "plot_solve_times",
    "robust_limit",
    "save_figure",
]

#: A controller whose 99th-percentile error is this many times the reference's is cut off the axis.
OUTLIER_FACTOR = 4.0
#: Head room above the largest 99th percentile of the controllers kept on the axis.
HEAD_ROOM = 1.2


def robust_limit(
    values: Mapping[str, np.ndarray], failed: Sequence[str] = (), reference: str = "lmpc"
) -> tuple[float | None, list[str]]:
    """Symmetric axis limit set by the controllers that matter, and the controllers cut off by it.

    The controllers kept are those that did not fail and whose 99th percentile of
    ``|value|`` is at most :data:`OUTLIER_FACTOR` times the reference controller's
    (``reference`` if present, else the median controller). The limit is
    :data:`HEAD_ROOM` times the largest 99th percentile of those, raised to show
    their largest value whole: only the other controllers are cut off.

    Parameters
    ----------
    values : mapping of str to ndarray
        One series per controller.
    failed : sequence of str
        Controllers that did not finish (left the track, diverged): never set the limit.
    reference : str
        The controller the others are measured against.

    Returns
    -------
    limit : float or None
        The limit, or None when no controller goes beyond what an automatic axis shows.
    clipped : list of str
        The controllers with a value beyond the limit, in the order of ``values``.
    """
    p99: dict[str, float] = {}
    peak: dict[str, float] = {}
    for name, series in values.items():
        magnitude = np.abs(np.asarray(series, dtype=float))
        magnitude = magnitude[np.isfinite(magnitude)]
        if magnitude.size:
            p99[name] = float(np.percentile(magnitude, 99))
            peak[name] = float(magnitude.max())
    candidates = [name for name in p99 if name not in failed] or list(p99)
    if not candidates:
        return None, []
    base = p99[reference] if reference in candidates else float(np.median([p99[n] for n in candidates]))
    kept = [name for name in candidates if p99[name] <= OUTLIER_FACTOR * max(base, 1e-12)] or candidates
    # The kept controllers are shown whole: their peaks are data, not outliers.
    limit = max(HEAD_ROOM * max(p99[name] for name in kept), 1.05 * max(peak[name] for name in kept))
    clipped = [name for name in peak if peak[name] > limit]
    return (limit, clipped) if clipped and limit > 0.0 else (None, [])


def _clip_axis(ax: Axes, column: str, unit: str, logs: Mapping[str, StepLog]) -> None:
    failed = [label for label, log in logs.items() if log.metadata.get("outcome", "completed") != "completed"]
    series = {label: log[column] for label, log in logs.items()}
    limit, clipped = robust_limit(series, failed)
    if limit is None:
        return
    ax.set_ylim(-limit, limit)
    notes = []
    for label in clipped:
        values = np.asarray(series[label], dtype=float)
        beyond = np.flatnonzero(np.abs(values) > limit)
        first = int(beyond[0])
        edge = limit if values[first] > 0 else -limit
        marker = "^" if edge > 0 else "v"
        color = controller_style(label).get("color", "k")
        ax.plot(logs[label]["progress"][first], edge, marker, color=color, ms=8, clip_on=False, zorder=5)
        notes.append(f"{label} (max {np.nanmax(np.abs(values)):.3g} {unit})")
    ax.set_title(
        "beyond the axis (\u25b2/\u25bc: first step beyond): " + ", ".join(notes), loc="right", fontsize=8
    )


def plot_runs(logs: Mapping[str, StepLog], track: Track, title: str = "") -> Figure:
    """Paths on the track, and lateral error, heading error and wheel angle over distance.

    The legend is below the axes (never over data). The error axes are limited
    to the controllers that matter (:func:`robust_limit`); a controller cut off
    is named above the axis. On a long track (:func:`rkmpc.analysis.maps.is_long_track`)
    the main controller's path is coloured by its lateral error and a fifth axis
    zooms on its worst section.

    Parameters
    ----------
    logs : mapping of str to StepLog
        One log per controller, keyed by the label to show.
    track : Track
        The track, for its boundaries and reference path.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        Axes: map, lateral error, heading error, wheel angle (then, on a long
        track, the zoom and the colour bar).
    """
    long_track = is_long_track(track) and bool(logs)
    fig = plt.figure(figsize=(13, 9.5 if long_track else 8.5), layout="constrained")
    columns = fig.add_gridspec(1, 2, width_ratios=[1.1, 1.0])
    maps = (
        columns[0].subgridspec(2, 1, height_ratios=[2.0, 1.0]) if long_track else columns[0].subgridspec(1, 1)
    )
    traces = columns[1].subgridspec(3, 1)
    ax_map = fig.add_subplot(maps[0])
    ax_lat = fig.add_subplot(traces[0])
    ax_head = fig.add_subplot(traces[1], sharex=ax_lat)
    ax_wheel = fig.add_subplot(traces[2], sharex=ax_lat)
    if long_track:
        draw_zoom(fig.add_subplot(maps[1]), ax_map, logs, track)
    draw_map(fig, ax_map, logs, track, detail=long_track)
    for label, log in logs.items():
        style = controller_style(label)
        dist = log["progress"]
        ax_lat.plot(dist, log["lateral_error"], label=label, **style)  # type: ignore[arg-type]
        ax_head.plot(dist, log["heading_error"], **style)  # type: ignore[arg-type]
        ax_wheel.plot(dist, log["wheel_angle"], **style)  # type: ignore[arg-type]
    ax_lat.set_ylabel("lateral error (m)")
    ax_head.set_ylabel("heading error (rad)")
    ax_wheel.set_ylabel("front wheel angle (rad)")
    ax_wheel.set_xlabel("distance along the reference (m)")
    for ax in (ax_lat, ax_head, ax_wheel):
        ax.grid(True, lw=0.3)
        ax.axhline(0.0, color="0.5", lw=0.5)
    _clip_axis(ax_lat, "lateral_error", "m", logs)
    _clip_axis(ax_head, "heading_error", "rad", logs)
    handles = [line for line in ax_lat.get_lines() if not str(line.get_label()).startswith("_")]
    handles += [line for line in ax_map.get_lines() if line.get_label() in ("reference", "start")]
    if any(log.metadata.get("outcome") == "off_track" for log in logs.values()):
        handles.append(Line2D([], [], ls="none", marker="x", color="k", ms=8, mew=2, label="left the track"))
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 6), fontsize=9)
    if title:
        fig.suptitle(title)
    return fig


def fallback_steps(log: StepLog) -> np.ndarray:
    """Indices of the steps whose status is not ``ok`` (none if the log has no status column)."""
    if "status" not in log.columns:
        return np.array([], dtype=int)
    status = np.asarray(log["status"], dtype=float)
    return np.flatnonzero(np.isfinite(status) & (status != 0.0))


def plot_solve_times(logs: Mapping[str, StepLog], period_s: float | None = None, title: str = "") -> Figure:
    """Distribution of each controller's step time (box plot on a log scale, with mean and max).

    Steps that fell back (status not ``ok``) are marked one by one; their number is
    in the controller's row name and in the legend (below the axes).

    Parameters
    ----------
    logs : mapping of str to StepLog
        One log per controller; its ``solve_time_s`` column is used (s), and its
        ``status`` column, if any.
    period_s : float, optional
        Control period (s), drawn as a vertical line for scale; a controller whose slowest step
        took longer is flagged (its numbers in red, ``LATE`` under its name): on a car it would
        have sent that command late.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    names = list(logs)
    samples = []
    fallbacks: dict[str, np.ndarray] = {}
    for name in names:
        all_ms = 1e3 * np.asarray(logs[name]["solve_time_s"], dtype=float)
        fallbacks[name] = all_ms[fallback_steps(logs[name])]
        ms = all_ms[np.isfinite(all_ms) & (all_ms > 0)]
        samples.append(ms if ms.size else np.array([np.nan]))
    fig, ax = plt.subplots(figsize=(9, 0.5 * len(names) + 2.0), layout="constrained")
    positions = np.arange(len(names))[::-1]
    ax.boxplot(samples, positions=positions, orientation="horizontal", whis=(1, 99), showfliers=False)
    period_ms = None if period_s is None else 1e3 * period_s
    late = []  # the controllers whose slowest step took longer than the control period
    for pos, ms, name in zip(positions, samples, names, strict=True):
        if np.isfinite(ms).any():
            ax.plot(np.nanmean(ms), pos, "o", color="tab:blue", ms=4)
            ax.plot(np.nanmax(ms), pos, "x", color="tab:red", ms=6)
            text = f"{np.nanmedian(ms):.3f} / {np.nanmax(ms):.2f} ms"
            beyond = period_ms is not None and np.nanmax(ms) > period_ms
            if beyond:
                late.append(name)
                text += f": max beyond the {period_ms:g} ms period!"
            ax.text(
                np.nanmax(ms) * 1.15,
                pos,
                text,
                va="center",
                fontsize=8,
                color="#D55E00" if beyond else "k",
                fontweight="bold" if beyond else "normal",
            )
    ax.plot([], [], "o", color="tab:blue", ms=4, label="mean")
    ax.plot([], [], "x", color="tab:red", ms=6, label="max")
    ax.set_xscale("log")
    lo = min((np.nanmin(ms) for ms in samples if np.isfinite(ms).any()), default=0.01)
    hi = max((np.nanmax(ms) for ms in samples if np.isfinite(ms).any()), default=1.0)
    right = max(hi * (40 if late else 8), 1e3 * period_s * 1.5) if period_s is not None else hi * 8
    ax.set_xlim(lo / 2, right)
    total = sum(len(steps) for steps in fallbacks.values())
    if total:
        rng = np.random.default_rng(0)
        for pos, name in zip(positions, names, strict=True):
            ms = fallbacks[name]
            # A fall-back without a measured time is drawn at the left edge.
            ms = np.where(np.isfinite(ms) & (ms > 0), ms, lo / 2 * 1.05)
            jitter = rng.uniform(-0.22, 0.22, ms.size)
            ax.plot(ms, pos + jitter, "v", color="#D55E00", ms=5, mec="k", mew=0.4, ls="none", zorder=4)
        ax.plot([], [], "v", color="#D55E00", ms=5, mec="k", mew=0.4, ls="none", label=f"{total} fall-backs")
    if period_s is not None:
        ax.axvline(
            1e3 * period_s, color="0.4", ls="--", lw=0.8, label=f"control period {1e3 * period_s:g} ms"
        )
    counts = [len(fallbacks[name]) for name in names]
    ticks = [f"{n}\n{c} fall-backs" if c else n for n, c in zip(names, counts, strict=True)]
    ax.set_yticks(positions, [f"{t}\nLATE" if n in late else t for t, n in zip(ticks, names, strict=True)])
    ax.set_xlabel(
        "controller step time (ms), log scale; box: quartiles, whiskers: p1-p99; text: median / max"
    )
    ax.grid(True, axis="x", which="both", lw=0.3)
    handles, _ = ax.get_legend_handles_labels()
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=8)
    if title:
        ax.set_title(title)
    return fig


def save_figure(fig: Figure, path: str | Path, dpi: int = 130) -> None:
    """Save a figure as PNG through a temporary file, then close it."""
    try:
        with atomic_write(path, "wb", suffix=".png") as handle:
            fig.savefig(handle, dpi=dpi, format="png")
    finally:
        plt.close(fig)
