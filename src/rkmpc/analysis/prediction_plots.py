"""The plot of ``rkmpc evaluate``: each model's open-loop prediction error against the horizon."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from matplotlib.figure import Figure

__all__ = ["plot_prediction_errors"]


#: Lines drawn apart from the models': the nominal kinematic model and the exact inputs.
_STYLES: dict[str, dict[str, str]] = {
    "kinematic": {"color": "black"},
    "exact inputs": {"color": "grey", "linestyle": ":"},
}


def plot_prediction_errors(
    horizons_s: Sequence[float],
    position_mean: Mapping[str, Sequence[float]],
    position_p95: Mapping[str, Sequence[float]],
    heading_mean: Mapping[str, Sequence[float]],
    title: str,
) -> Figure:
    """Position error (mean, and 95th percentile dashed) and heading error against the horizon (s).

    One line per model, the nominal kinematic model (``kinematic``) in black, the exact inputs
    (``exact inputs``: what a perfect model of the residual's form predicts) dotted grey.
    """
    fig = Figure(figsize=(10.0, 4.2), constrained_layout=True)
    left, right = fig.subplots(1, 2)
    for name in position_mean:
        style = _STYLES[name] if name in _STYLES else {}
        (line,) = left.plot(horizons_s, position_mean[name], marker="o", label=name, **style)
        left.plot(horizons_s, position_p95[name], linestyle="--", color=line.get_color())
        right.plot(horizons_s, heading_mean[name], marker="o", color=line.get_color(), label=name)
    left.set_xlabel("horizon (s)")
    left.set_ylabel("position error (m): mean, p95 dashed")
    right.set_xlabel("horizon (s)")
    right.set_ylabel("heading error, mean (rad)")
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
        ax.set_xlim(left=0.0)
        ax.set_ylim(bottom=0.0)
    left.legend(loc="upper left", fontsize="small")
    fig.suptitle(title)
    return fig
