"""Plots of study results: lateral error and completion against training-data volume."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

from rkmpc.analysis.statistics import Stats
from rkmpc.analysis.styles import CONTROLLER_STYLE, controller_style

__all__ = ["VolumeSeries", "plot_data_study"]

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
    for i, name in enumerate(controllers):
        offset = x + (i - (len(controllers) - 1) / 2) * width
        stats_ = [lateral[car][name] for car in cars]
        mean = np.array([np.nan if s.mean is None else s.mean for s in stats_])
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
    ax_lat.set_yscale("log")
    ax_lat.set_ylabel("mean lateral error (m), completed laps")
    ax_done.set_ylabel("laps completed (-)")
    ax_done.set_ylim(0, 1.05)
    ax_lat.legend(fontsize="small", ncols=2)
    figure.suptitle("controllers on cars they were not built for")
    return figure
