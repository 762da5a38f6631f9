"""Plots made from step logs (never inside the numerics)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rkmpc.core.io import atomic_write
from rkmpc.sim.log import StepLog
from rkmpc.track.track import Track

#: Fixed colour and line width per controller, so every figure of a study reads alike.
CONTROLLER_STYLE: dict[str, tuple[str, float]] = {
    "pp": ("tab:blue", 0.9),
    "lmpc": ("tab:orange", 1.0),
    "lmpc-id": ("tab:olive", 0.9),
    "nmpc": ("tab:red", 0.9),
    "nmpc-dynamic": ("tab:purple", 0.9),
    "nmpc-acados": ("tab:pink", 0.9),
    "nmpc-acados-dynamic": ("tab:cyan", 0.9),
    "kmpc": ("tab:brown", 0.9),
    "rkmpc-paper": ("tab:gray", 0.9),
    "rkmpc": ("tab:green", 1.6),
}


def controller_style(label: str) -> dict[str, object]:
    """Matplotlib ``color`` and ``lw`` of a controller label (``name`` or ``name+fault``)."""
    color, width = CONTROLLER_STYLE.get(label.split("+")[0], (None, 0.9))
    style: dict[str, object] = {"lw": width}
    if color is not None:
        style["color"] = color
    return style


def plot_runs(logs: Mapping[str, StepLog], track: Track, title: str = "") -> Figure:
    """Paths on the track, and lateral error, heading error and wheel angle over distance.

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
    """
    fig = plt.figure(figsize=(13, 8.5), layout="constrained")
    grid = fig.add_gridspec(3, 2, width_ratios=[1.1, 1.0])
    ax_map = fig.add_subplot(grid[:, 0])
    ax_lat = fig.add_subplot(grid[0, 1])
    ax_head = fig.add_subplot(grid[1, 1], sharex=ax_lat)
    ax_wheel = fig.add_subplot(grid[2, 1], sharex=ax_lat)

    spacing = max(track.centerline.length / 4000.0, 0.01)
    left, right = track.boundaries(spacing)
    for edge in (left, right):
        closed = np.vstack([edge, edge[:1]])
        ax_map.plot(closed[:, 0], closed[:, 1], color="0.3", lw=0.8)
    ref = track.reference_path.sample(spacing)
    ax_map.plot(ref.x, ref.y, color="0.6", lw=0.8, ls="--", label="reference")
    for label, log in logs.items():
        style = controller_style(label)
        line = ax_map.plot(log["x"], log["y"], label=label, **style)[0]  # type: ignore[arg-type]
        color = line.get_color()
        width = float(style["lw"])  # type: ignore[arg-type]
        if log.metadata.get("outcome") == "off_track" and len(log):
            ax_map.plot(log["x"][-1], log["y"][-1], "x", color=color, ms=10, mew=2)
        dist = log["progress"]
        ax_lat.plot(dist, log["lateral_error"], lw=width, color=color, label=label)
        ax_head.plot(dist, log["heading_error"], lw=width, color=color)
        ax_wheel.plot(dist, log["wheel_angle"], lw=width, color=color)
    ax_map.plot(*ref_start(track), "k>", ms=8, label="start")
    ax_map.set_aspect("equal")
    ax_map.set_xlabel("x (m)")
    ax_map.set_ylabel("y (m)")
    ax_map.legend(loc="best", fontsize=8)
    ax_lat.set_ylabel("lateral error (m)")
    ax_head.set_ylabel("heading error (rad)")
    ax_wheel.set_ylabel("front wheel angle (rad)")
    ax_wheel.set_xlabel("distance along the reference (m)")
    for ax in (ax_lat, ax_head, ax_wheel):
        ax.grid(True, lw=0.3)
        ax.axhline(0.0, color="0.5", lw=0.5)
    ax_lat.legend(loc="best", fontsize=8)
    if title:
        fig.suptitle(title)
    return fig


def plot_solve_times(logs: Mapping[str, StepLog], period_s: float | None = None, title: str = "") -> Figure:
    """Distribution of each controller's step time (box plot on a log scale, with mean and max).

    Parameters
    ----------
    logs : mapping of str to StepLog
        One log per controller; its ``solve_time_s`` column is used (s).
    period_s : float, optional
        Control period (s), drawn as a vertical line for scale.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    names = list(logs)
    samples = []
    for name in names:
        ms = 1e3 * np.asarray(logs[name]["solve_time_s"], dtype=float)
        ms = ms[np.isfinite(ms) & (ms > 0)]
        samples.append(ms if ms.size else np.array([np.nan]))
    fig, ax = plt.subplots(figsize=(9, 0.55 * len(names) + 1.8), layout="constrained")
    positions = np.arange(len(names))[::-1]
    ax.boxplot(samples, positions=positions, orientation="horizontal", whis=(1, 99), showfliers=False)
    for pos, ms in zip(positions, samples, strict=True):
        if np.isfinite(ms).any():
            ax.plot(np.nanmean(ms), pos, "o", color="tab:blue", ms=4)
            ax.plot(np.nanmax(ms), pos, "x", color="tab:red", ms=6)
            ax.text(
                np.nanmax(ms) * 1.15,
                pos,
                f"{np.nanmedian(ms):.3f} / {np.nanmax(ms):.2f} ms",
                va="center",
                fontsize=8,
            )
    ax.plot([], [], "o", color="tab:blue", ms=4, label="mean")
    ax.plot([], [], "x", color="tab:red", ms=6, label="max")
    if period_s is not None:
        ax.axvline(
            1e3 * period_s, color="0.4", ls="--", lw=0.8, label=f"control period {1e3 * period_s:g} ms"
        )
    ax.set_xscale("log")
    ax.set_yticks(positions, names)
    ax.set_xlabel(
        "controller step time (ms), log scale; box: quartiles, whiskers: p1-p99; text: median / max"
    )
    ax.grid(True, axis="x", which="both", lw=0.3)
    lo = min((np.nanmin(ms) for ms in samples if np.isfinite(ms).any()), default=0.01)
    hi = max((np.nanmax(ms) for ms in samples if np.isfinite(ms).any()), default=1.0)
    right = max(hi * 8, 1e3 * period_s * 1.5) if period_s is not None else hi * 8
    ax.set_xlim(lo / 2, right)
    ax.legend(loc="lower right", fontsize=8)
    if title:
        ax.set_title(title)
    return fig


def ref_start(track: Track) -> tuple[float, float]:
    """Position (m) of the start of the reference path."""
    p = track.reference_path.position(0.0)
    return float(p[0]), float(p[1])


def save_figure(fig: Figure, path: str | Path, dpi: int = 130) -> None:
    """Save a figure as PNG through a temporary file, then close it."""
    try:
        with atomic_write(path, "wb", suffix=".png") as handle:
            fig.savefig(handle, dpi=dpi, format="png")
    finally:
        plt.close(fig)
