"""Plots of study results (:mod:`rkmpc.experiments.studies`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.figure import Figure

#: Line styles of the data study, by controller (distinct where lines overlap).
_STYLES = {
    "rkmpc": {"color": "tab:green", "marker": "o", "linestyle": "-"},
    "kmpc": {"color": "tab:red", "marker": "s", "linestyle": "--"},
}


def plot_data_study(result: Mapping[str, Any], title: str = "") -> Figure:
    """Lateral error and completion rate against the number of training samples.

    Left: mean lateral error over the completed laps (line) with its range
    over seeds (band, min to max) and standard deviation (error bars);
    right: the fraction of laps completed. One line per controller (RKMPC,
    KMPC); the x axis (logarithmic) is the mean number of local-frame
    training samples (``augmented_count``) of each target size.

    Parameters
    ----------
    result : mapping
        A :func:`rkmpc.experiments.studies.study_data` result (its ``summary``
        and ``track`` are used).
    title : str
        Figure title (default: names the track).

    Returns
    -------
    matplotlib.figure.Figure
        Two axes: lateral error (m) and completion rate, both against samples.
    """
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    ax_err, ax_done = fig.subplots(1, 2)
    summary = list(result["summary"])
    for name in dict.fromkeys(s["controller"] for s in summary):
        rows = sorted((s for s in summary if s["controller"] == name), key=lambda s: s["size"])
        counts = [s["augmented_count"]["mean"] for s in rows]
        x = np.array([s["size"] if c is None else c for s, c in zip(rows, counts, strict=True)], dtype=float)
        lat = [s["lateral_error_mean_m"] for s in rows]
        mean = np.array([np.nan if v["mean"] is None else v["mean"] for v in lat])
        std = np.array([0.0 if v["std"] is None else v["std"] for v in lat])
        lo = np.array([np.nan if v["min"] is None else v["min"] for v in lat])
        hi = np.array([np.nan if v["max"] is None else v["max"] for v in lat])
        style = _STYLES.get(name, {"marker": "^"})
        ax_err.errorbar(x, mean, yerr=std, capsize=3, label=name.upper(), **style)
        ax_err.fill_between(x, lo, hi, color=style.get("color"), alpha=0.2, linewidth=0)
        rate = np.array([s["completion_rate"] for s in rows])
        ax_done.plot(x, rate, label=name.upper(), fillstyle="none", markersize=8, **style)
    base = result.get("baseline")
    if base and base["metrics"].get("lateral_error_mean_m") is not None:
        ax_err.axhline(
            base["metrics"]["lateral_error_mean_m"],
            color="tab:orange",
            ls=":",
            lw=1.5,
            label="LMPC (no data)",
        )
    for ax in (ax_err, ax_done):
        ax.set_xscale("log")
        ax.set_xlabel("training samples (local-frame transitions)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    ax_err.set_ylabel("mean lateral error (m), completed laps")
    ax_done.set_ylabel("laps completed (fraction of seeds)")
    ax_done.set_ylim(-0.05, 1.05)
    fig.suptitle(title or f"Data volume on {result.get('track', '')}")
    return fig
