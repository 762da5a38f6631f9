"""The track map of a comparison: edges, reference, driven paths; on a long track, errors made visible.

On a track many times longer than it is wide, a lateral error of a few
centimetres is far below a pixel of the whole map and every path lies on the
reference. There the main controller's path is coloured by its lateral error
(with a colour bar), and a second axis zooms on the section where that error is
largest, with every controller's path.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from rkmpc.analysis.styles import LEARNED, controller_style
from rkmpc.sim.log import StepLog
from rkmpc.track.track import Track

__all__ = [
    "LONG_TRACK_RATIO",
    "draw_map",
    "draw_zoom",
    "is_long_track",
    "main_controller",
    "track_width",
]

#: A track longer than this many times its mean width is "long": its map needs help.
LONG_TRACK_RATIO = 150.0

_EDGE = {"color": "0.35", "lw": 0.7}
_REFERENCE = {"color": "0.65", "lw": 0.8, "ls": (0, (4, 3))}
_ERROR_CMAP = "viridis"


def track_width(track: Track, samples: int = 400) -> float:
    """Mean width (m) of the track, left plus right."""
    s = np.linspace(0.0, track.centerline.length, samples, endpoint=False)
    return float(np.mean(np.asarray(track.width_left(s)) + np.asarray(track.width_right(s))))


def is_long_track(track: Track) -> bool:
    """Whether the track is more than :data:`LONG_TRACK_RATIO` times longer than it is wide."""
    return track.centerline.length > LONG_TRACK_RATIO * track_width(track)


def main_controller(labels: list[str]) -> str | None:
    """The label the map details: ``rkmpc``, else the first learned controller, else the first."""
    bases = [label.split("+")[0] for label in labels]
    for wanted in ("rkmpc",):
        if wanted in bases:
            return labels[bases.index(wanted)]
    for label, base in zip(labels, bases, strict=True):
        if base in LEARNED:
            return label
    return labels[0] if labels else None


def _spacing(track: Track) -> float:
    return max(track.centerline.length / 4000.0, 0.01)


def _draw_track(ax: Axes, track: Track, spacing: float) -> None:
    left, right = track.boundaries(spacing)
    for edge in (left, right):
        closed = np.vstack([edge, edge[:1]])
        ax.plot(closed[:, 0], closed[:, 1], **_EDGE)  # type: ignore[arg-type]
    ref = track.reference_path.sample(spacing)
    ax.plot(ref.x, ref.y, label="reference", **_REFERENCE)  # type: ignore[arg-type]


def _draw_paths(ax: Axes, logs: Mapping[str, StepLog]) -> None:
    for label, log in logs.items():
        style = controller_style(label)
        line = ax.plot(log["x"], log["y"], label=label, **style)[0]  # type: ignore[arg-type]
        if log.metadata.get("outcome") == "off_track" and len(log):
            ax.plot(log["x"][-1], log["y"][-1], "x", color=line.get_color(), ms=10, mew=2)


def draw_map(fig: Figure, ax: Axes, logs: Mapping[str, StepLog], track: Track, *, detail: bool) -> None:
    """Track edges, reference, each controller's path and where a car left the track.

    Parameters
    ----------
    fig : Figure
        The figure (for the colour bar).
    ax : Axes
        The map's axes.
    logs : mapping of str to StepLog
        One log per controller.
    track : Track
        The track.
    detail : bool
        Colour the main controller's path by its lateral error, with a colour bar.
    """
    spacing = _spacing(track)
    _draw_track(ax, track, spacing)
    _draw_paths(ax, logs)
    start = track.reference_path.position(0.0)
    ax.plot(float(start[0]), float(start[1]), "k>", ms=8, label="start")
    main = main_controller(list(logs))
    if detail and main is not None and len(logs[main]) > 1:
        log = logs[main]
        points = np.column_stack([log["x"], log["y"]])
        segments = np.stack([points[:-1], points[1:]], axis=1)
        error = np.abs(np.asarray(log["lateral_error"], dtype=float))
        finite = error[np.isfinite(error)]
        top = float(np.percentile(finite, 99)) if finite.size else 1.0
        paths = LineCollection(list(segments), cmap=_ERROR_CMAP, linewidths=2.4, zorder=3)
        paths.set_array(0.5 * (error[:-1] + error[1:]))
        paths.set_clim(0.0, top if top > 0 else 1.0)
        ax.add_collection(paths)
        bar = fig.colorbar(paths, ax=ax, location="bottom", shrink=0.8, pad=0.02, extend="max")
        bar.set_label(f"{main}: |lateral error| (m), path coloured by it")
    # The map shows the track: a car that left it far behind must not shrink it to a dot.
    edges = np.vstack(track.boundaries(spacing))
    lo, hi = edges.min(axis=0), edges.max(axis=0)
    margin = 0.04 * float(np.max(hi - lo))
    ax.set_xlim(lo[0] - margin, hi[0] + margin)
    ax.set_ylim(lo[1] - margin, hi[1] + margin)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def draw_zoom(ax: Axes, ax_map: Axes, logs: Mapping[str, StepLog], track: Track) -> str | None:
    """Zoom on the main controller's largest lateral error, with every controller's path.

    The section is outlined on the map. Returns the main controller's label, or
    None when there is nothing to zoom on (the axes are then hidden).
    """
    main = main_controller(list(logs))
    error = np.abs(np.asarray(logs[main]["lateral_error"], dtype=float)) if main is not None else np.array([])
    if main is None or not np.isfinite(error).any():
        ax.set_axis_off()
        return None
    k = int(np.nanargmax(error))
    centre = np.array([logs[main]["x"][k], logs[main]["y"][k]], dtype=float)
    width = track_width(track)
    extent = np.ptp(np.vstack(track.boundaries(_spacing(track))), axis=0).max()
    # Wide enough for the track's edges, narrow enough that the errors are several pixels.
    half = float(min(max(1.2 * width, 6.0 * error[k]), 0.15 * extent))
    spacing = min(_spacing(track), half / 50.0)
    _draw_track(ax, track, spacing)
    _draw_paths(ax, logs)
    ax.plot(*centre, "o", ms=9, mfc="none", mec="k", mew=1.2)
    # Twice as wide as high, the shape of the axes under the map.
    ax.set_xlim(centre[0] - 2 * half, centre[0] + 2 * half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal", adjustable="box")
    ax.set_title(
        f"zoom: largest |lateral error| of {main}, {error[k]:.3g} m at {logs[main]['progress'][k]:.0f} m",
        fontsize=9,
    )
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.tick_params(labelsize=7)
    corner = (centre[0] - 2 * half, centre[1] - half)
    ax_map.add_patch(Rectangle(corner, 4 * half, 2 * half, fill=False, ec="k", lw=1.2, zorder=4))
    ax_map.annotate(
        "zoom",
        (centre[0] + 2 * half, centre[1] + half),
        xytext=(6, 6),
        textcoords="offset points",
        fontsize=8,
    )
    return main
