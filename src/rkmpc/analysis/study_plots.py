"""Plots of study results: training-data volume, cars, pace (lap time and error against the pace)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

from rkmpc.analysis.statistics import Stats
from rkmpc.analysis.styles import CONTROLLER_STYLE, controller_style

__all__ = [
    "PaceSeries",
    "VolumeSeries",
    "plot_cars_study",
    "plot_data_study",
    "plot_learn_pace",
    "plot_pace_study",
]

#: Line styles of the data study, by controller (distinct where lines overlap), in the project's colours.
_STYLES = {
    "rkmpc": {"color": CONTROLLER_STYLE["rkmpc"].color, "marker": "o", "linestyle": "-"},
    "kmpc": {"color": CONTROLLER_STYLE["kmpc"].color, "marker": "s", "linestyle": "--"},
}


@dataclass(frozen=True)
class VolumeSeries:
    """One controller of the data study: one point per training-set size.

    Parameters
    ----------
    controller : str
        Controller name (the legend and line style).
    samples : sequence of float
        Mean number of local-frame training samples of each size (the x axis).
    lateral : sequence of Stats
        Mean lateral error (m) over the completed laps of each size.
    completion_rate : sequence of float
        Fraction of laps completed at each size.
    """

    controller: str
    samples: Sequence[float]
    lateral: Sequence[Stats]
    completion_rate: Sequence[float]


def plot_data_study(series: Sequence[VolumeSeries], baseline_lateral: float | None, title: str) -> Figure:
    """Lateral error and completion rate against the number of training samples.

    Left: mean lateral error over the completed laps (line) with its range
    over seeds (band, min to max) and standard deviation (error bars);
    right: the fraction of laps completed. One line per controller; the x axis
    (logarithmic) is the mean number of local-frame training samples.

    Parameters
    ----------
    series : sequence of VolumeSeries
        One per controller.
    baseline_lateral : float or None
        The LMPC's lateral error on the same track (drawn as a level), or None.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes: lateral error (m) and completion rate, both against samples.
    """
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    ax_err, ax_done = fig.subplots(1, 2)
    for s in series:
        x = np.asarray(s.samples, dtype=float)
        mean = np.array([np.nan if v.mean is None else v.mean for v in s.lateral])
        std = np.array([0.0 if v.std is None else v.std for v in s.lateral])
        lo = np.array([np.nan if v.min is None else v.min for v in s.lateral])
        hi = np.array([np.nan if v.max is None else v.max for v in s.lateral])
        style = _STYLES.get(s.controller, {"marker": "^"})
        ax_err.errorbar(x, mean, yerr=std, capsize=3, label=s.controller.upper(), **style)
        ax_err.fill_between(x, lo, hi, color=style.get("color"), alpha=0.2, linewidth=0)
        rate = np.asarray(s.completion_rate, dtype=float)
        ax_done.plot(x, rate, label=s.controller.upper(), fillstyle="none", markersize=8, **style)
    if baseline_lateral is not None:
        ax_err.axhline(
            baseline_lateral, color=CONTROLLER_STYLE["lmpc"].color, ls=":", lw=1.5, label="LMPC (no data)"
        )
    for ax in (ax_err, ax_done):
        ax.set_xscale("log")
        ax.set_xlabel("training samples (local-frame transitions)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    ax_err.set_ylabel("mean lateral error (m), completed laps")
    ax_done.set_ylabel("laps completed (fraction of seeds)")
    ax_done.set_ylim(-0.05, 1.05)
    fig.suptitle(title)
    return fig


def plot_cars_study(
    cars: Sequence[str],
    controllers: Sequence[str],
    lateral: Mapping[str, Mapping[str, Stats]],
    completion: Mapping[str, Mapping[str, float]],
) -> Figure:
    """Mean lateral error and completion rate per car of the zoo, one bar per controller.

    Left: mean over tracks and seeds of the mean lateral error of the
    completed laps (bar) with its range (error bar, min to max), logarithmic;
    right: the fraction of laps completed.

    Parameters
    ----------
    cars, controllers : sequence of str
        The groups (x axis) and the bars in each group.
    lateral : mapping
        ``lateral[car][controller]``: statistics of the mean lateral error (m).
    completion : mapping
        ``completion[car][controller]``: completed laps / runs (-).
    """
    figure = Figure(figsize=(max(8.0, 1.3 * len(cars) * 2), 4.5), layout="constrained")
    ax_lat, ax_done = figure.subplots(1, 2, width_ratios=(3, 2))
    x = np.arange(len(cars))
    width = 0.8 / max(len(controllers), 1)
    drawn = False
    for i, name in enumerate(controllers):
        offset = x + (i - (len(controllers) - 1) / 2) * width
        stats_ = [lateral[car][name] for car in cars]
        mean = np.array([np.nan if s.mean is None else s.mean for s in stats_])
        drawn = drawn or bool(np.any(mean > 0))
        low = np.array([np.nan if s.min is None else s.min for s in stats_])
        high = np.array([np.nan if s.max is None else s.max for s in stats_])
        color = controller_style(name).get("color")
        ax_lat.bar(offset, mean, width, label=name, color=color)
        # Rounding can put the mean a hair outside [min, max] when all values are equal.
        spread = [np.maximum(mean - low, 0.0), np.maximum(high - mean, 0.0)]
        ax_lat.errorbar(offset, mean, yerr=spread, fmt="none", ecolor="k", lw=0.8)
        ax_done.bar(offset, [completion[car][name] for car in cars], width, label=name, color=color)
    for ax in (ax_lat, ax_done):
        ax.set_xticks(x, list(cars), rotation=30, ha="right")
    if drawn:
        ax_lat.set_yscale("log")
    else:  # no completed lap at all: nothing to put on a logarithmic axis
        ax_lat.text(0.5, 0.5, "no completed lap", ha="center", va="center", transform=ax_lat.transAxes)
        ax_lat.set_yticks([])
    ax_lat.set_ylabel("mean lateral error (m), completed laps")
    ax_done.set_ylabel("laps completed (-)")
    ax_done.set_ylim(0, 1.05)
    ax_lat.legend(fontsize="small", ncols=2)
    figure.suptitle("controllers on cars they were not built for")
    return figure


@dataclass(frozen=True)
class PaceSeries:
    """One controller on one track of the pace study: one point per pace it drove.

    Parameters
    ----------
    controller, track : str
        Names (colour and label).
    paces : sequence of (float, float)
        ``(lateral_accel, max_speed)`` of each step (the x axis is the lateral limit).
    lap_time, lateral : sequence of float or None
        Lap time (s) and mean lateral error (m) of each step; None where the lap was not clean.
    reference_lap_time : float
        The track's reference lap time at the first pace (s), to compare tracks.
    best_index : int or None
        The step of the fastest clean lap (marked).
    """

    controller: str
    track: str
    paces: Sequence[tuple[float, float]]
    lap_time: Sequence[float | None]
    lateral: Sequence[float | None]
    reference_lap_time: float
    best_index: int | None


def _values(values: Sequence[float | None]) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=float)


#: Most tick labels on a pace axis: a ladder of 20 paces, each named by two numbers, overprints.
MAX_PACE_TICKS = 10


def _thinned(values: Sequence[float], most: int) -> list[float]:
    """Every k-th of ``values`` (k the least that leaves at most ``most``), always the last."""
    step = max(1, -(-len(values) // most))
    kept = list(values[::step])
    if values and kept[-1] != values[-1]:
        kept[-1] = values[-1]
    return kept


def plot_pace_study(series: Sequence[PaceSeries], title: str) -> Figure:
    """Lap time and mean lateral error of the clean laps against the pace, one line per controller and track.

    With one track the lap time is in seconds; with several it is relative to each track's
    reference lap time at the first pace (so that tracks share an axis). The fastest clean lap of
    each line is marked with a star. The x axis is the lateral-acceleration limit, its ticks also
    name the top speed.
    """
    fig = Figure(figsize=(11, 4.4), layout="constrained")
    ax_time, ax_lat = fig.subplots(1, 2, sharex=True)
    tracks = list(dict.fromkeys(s.track for s in series))
    relative = len(tracks) > 1
    labelled: set[str] = set()
    ticks: dict[float, str] = {}
    for s in series:
        x = np.array([p[0] for p in s.paces], dtype=float)
        ticks.update({p[0]: f"{p[0]:g}\n{p[1]:g}" for p in s.paces})
        times = _values(s.lap_time) / (s.reference_lap_time if relative else 1.0)
        style = controller_style(s.controller)
        label = None if s.controller in labelled else s.controller
        labelled.add(s.controller)
        alpha = 0.6 if relative else 1.0
        ax_time.plot(x, times, marker="o", markersize=3, label=label, alpha=alpha, **style)
        ax_lat.plot(x, _values(s.lateral), marker="o", markersize=3, alpha=alpha, **style)
        if s.best_index is not None:
            color = style.get("color")
            ax_time.plot(x[s.best_index], times[s.best_index], marker="*", markersize=11, color=color)
            ax_lat.plot(
                x[s.best_index], _values(s.lateral)[s.best_index], marker="*", markersize=11, color=color
            )
    shown = _thinned(sorted(ticks), MAX_PACE_TICKS)
    for ax in (ax_time, ax_lat):
        ax.set_xticks(shown, [ticks[k] for k in shown])
        ax.set_xlabel("pace: lateral limit (m/s$^2$) / top speed (m/s)")
        ax.grid(True, alpha=0.3)
    ax_time.set_ylabel("lap time / reference lap time at the first pace" if relative else "lap time (s)")
    ax_lat.set_ylabel("mean lateral error (m), clean laps")
    ax_time.legend(fontsize="small")
    fig.suptitle(title)
    return fig


def plot_learn_pace(
    labels: Sequence[str],
    lap_time: Sequence[float | None],
    clean: Sequence[bool],
    lmpc_lap_time: Sequence[float | None],
    lateral: Sequence[float | None],
    title: str,
) -> Figure:
    """The learning-to-race curve: lap time and lateral error over iterations.

    ``labels`` name each iteration's pace; an unclean iteration is drawn as a cross. The LMPC's
    lap at the same pace (not learned) is drawn dashed for comparison.
    """
    fig = Figure(figsize=(10, 4.2), layout="constrained")
    ax_time, ax_lat = fig.subplots(1, 2, sharex=True)
    x = np.arange(len(labels))
    ok = np.asarray(clean, dtype=bool)
    times, lat = _values(lap_time), _values(lateral)
    rk = controller_style("rkmpc")
    ax_time.plot(x[ok], times[ok], marker="o", label="learned (clean laps)", **rk)
    ax_time.plot(x[~ok], times[~ok], "x", color=rk["color"], markersize=10, label="not clean")
    ax_time.plot(
        x, _values(lmpc_lap_time), marker="s", label="LMPC at the same pace", **controller_style("lmpc")
    )
    ax_lat.plot(x[ok], lat[ok], marker="o", **rk)
    ax_lat.plot(x[~ok], lat[~ok], "x", color=rk["color"], markersize=10)
    shown = [int(i) for i in _thinned(range(len(labels)), MAX_PACE_TICKS)]
    for ax in (ax_time, ax_lat):
        ax.set_xticks(shown, [f"{i}\n{labels[i]}" for i in shown])
        ax.set_xlabel("iteration / pace (m/s$^2$ / m/s)")
        ax.grid(True, alpha=0.3)
    ax_time.set_ylabel("lap time (s)")
    ax_lat.set_ylabel("mean lateral error (m)")
    ax_time.legend(fontsize="small")
    fig.suptitle(title)
    return fig
