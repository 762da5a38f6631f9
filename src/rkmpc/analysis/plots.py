"""Plots made from step logs (never inside the numerics)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rkmpc.sim.log import StepLog
from rkmpc.track.track import Track


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
        line = ax_map.plot(log["x"], log["y"], lw=1.0, label=label)[0]
        color = line.get_color()
        if log.metadata.get("outcome") == "off_track" and len(log):
            ax_map.plot(log["x"][-1], log["y"][-1], "x", color=color, ms=10, mew=2)
        dist = log["progress"]
        ax_lat.plot(dist, log["lateral_error"], lw=0.8, color=color, label=label)
        ax_head.plot(dist, log["heading_error"], lw=0.8, color=color)
        ax_wheel.plot(dist, log["wheel_angle"], lw=0.8, color=color)
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


def ref_start(track: Track) -> tuple[float, float]:
    """Position (m) of the start of the reference path."""
    p = track.reference_path.position(0.0)
    return float(p[0]), float(p[1])


def save_figure(fig: Figure, path: str | Path, dpi: int = 130) -> None:
    """Save a figure as PNG through a temporary file, then close it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".png")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=dpi)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    finally:
        plt.close(fig)
