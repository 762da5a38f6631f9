"""Legibility of the comparison figures: legends off the data, distinct styles, robust axes,
long-track maps, fall-backs on the solve-time plot."""

from __future__ import annotations

import math
from itertools import combinations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.collections import LineCollection

from rkmpc.analysis.maps import is_long_track, main_controller
from rkmpc.analysis.plots import fallback_steps, plot_runs, plot_solve_times, robust_limit
from rkmpc.analysis.styles import CONTROLLER_STYLE, LEARNED
from rkmpc.sim.closed_loop import log_columns
from rkmpc.sim.log import StepLog
from rkmpc.track import Path, Track

COLUMNS = log_columns(("x", "y", "yaw", "v", "beta", "yaw_rate", "delta"))
COMPARED = ("pp", "lmpc", "lmpc-id", "nmpc", "nmpc-dynamic", "kmpc", "rkmpc-paper", "rkmpc")


def _log(track: Track, offset: float, n: int = 60, ds: float = 0.1, outcome: str = "completed") -> StepLog:
    """A car ``offset`` m left of the reference path for ``n`` steps of ``ds`` m; a bump at step n/2."""
    path = track.reference_path
    log = StepLog(COLUMNS)
    for k in range(n):
        s = ds * k
        pos, heading = path.position(s), float(path.heading(s))
        lateral = offset * (1.0 + 0.2 * math.sin(0.5 * k) + (0.5 if k == n // 2 else 0.0))
        row = dict.fromkeys(COLUMNS, 0.0)
        row.update(
            t=0.05 * k,
            s=s,
            progress=s,
            x=float(pos[0]) - lateral * math.sin(heading),
            y=float(pos[1]) + lateral * math.cos(heading),
            lateral_error=lateral,
            heading_error=0.02 * math.cos(k),
            wheel_angle=0.05 * math.sin(0.3 * k),
            solve_time_s=1e-3 * (1.0 + 0.5 * math.sin(k)),
        )
        log.append(np.array([row[c] for c in COLUMNS]))
    log.metadata["outcome"] = outcome
    return log


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def track(builtin_scenario):
    return builtin_scenario.track


@pytest.fixture(scope="module")
def long_track() -> Track:
    """A ring 3.1 km long and 2 m wide."""
    th = np.linspace(0.0, 2 * np.pi, 120, endpoint=False)
    return Track("ring", Path.from_points(500.0 * np.column_stack([np.cos(th), np.sin(th)])), 1.0, 1.0)


def _assert_legend_off_the_axes(fig) -> None:
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    assert fig.legends, "the figure has no legend"
    for legend in fig.legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            assert ax.get_legend() is None
            assert not box.overlaps(ax.get_window_extent(renderer)), ax.get_label() or ax.get_ylabel()


def _figure_text(fig) -> str:
    texts = [t.get_text() for ax in fig.axes for t in (*ax.texts, ax.title, ax._left_title, ax._right_title)]
    return " ".join(texts)


def test_styles_are_pairwise_distinct():
    colours = [CONTROLLER_STYLE[name].color.lower() for name in COMPARED]
    assert len(set(colours)) == len(COMPARED)
    pairs = [(s.color.lower(), s.linestyle) for s in CONTROLLER_STYLE.values()]
    assert len(set(pairs)) == len(pairs)
    for a, b in combinations(COMPARED, 2):
        assert CONTROLLER_STYLE[a] != CONTROLLER_STYLE[b]
    # Learned controllers solid, baselines broken; the RKMPC the widest.
    for name, style in CONTROLLER_STYLE.items():
        assert (style.linestyle == "-") == (name in LEARNED), name
    assert max(CONTROLLER_STYLE.values(), key=lambda s: s.linewidth) is CONTROLLER_STYLE["rkmpc"]


def test_legends_are_off_the_data(track):
    logs = {name: _log(track, 0.02 * (i + 1)) for i, name in enumerate(COMPARED)}
    logs["pp"] = _log(track, 0.3, n=20, outcome="off_track")
    _assert_legend_off_the_axes(plot_runs(logs, track, title="t"))
    _assert_legend_off_the_axes(plot_solve_times(logs, period_s=0.05, title="t"))


def test_error_axis_ignores_a_controller_twenty_times_worse(track):
    logs = {"lmpc": _log(track, 0.1), "rkmpc": _log(track, 0.05), "kmpc": _log(track, 2.0)}
    fig = plot_runs(logs, track)
    ax_lat = fig.axes[1]
    others = max(np.abs(logs[n]["lateral_error"]).max() for n in ("lmpc", "rkmpc"))
    low, high = ax_lat.get_ylim()
    assert others <= high <= 2.0 * others
    assert low == pytest.approx(-high)
    text = _figure_text(fig)
    assert "beyond the axis" in text and "kmpc" in text
    assert "lmpc (" not in text and "rkmpc (" not in text  # only the cut-off one is named
    # A marker at the axis edge, in the KMPC's colour, where it first goes beyond.
    edge = [line for line in ax_lat.get_lines() if line.get_marker() == "^"]
    assert len(edge) == 1 and edge[0].get_color() == CONTROLLER_STYLE["kmpc"].color
    # The heading errors are alike: that axis is left alone.
    assert "beyond" not in fig.axes[2].get_title(loc="right")


def test_robust_limit():
    rng = np.random.default_rng(1)
    base = {"lmpc": 0.1 * rng.standard_normal(500), "rkmpc": 0.05 * rng.standard_normal(500)}
    assert robust_limit(base) == (None, [])  # nothing far out: the automatic axis
    limit, clipped = robust_limit({**base, "kmpc": 20 * base["lmpc"]})
    assert clipped == ["kmpc"]
    assert limit is not None and limit < 2.0 * np.abs(base["lmpc"]).max()
    # A controller that left the track never sets the limit, even with errors like the others'.
    failing = np.concatenate([0.1 * rng.standard_normal(400), np.linspace(0.3, 3.0, 100)])
    limit, clipped = robust_limit({**base, "pp": failing}, failed=["pp"])
    assert clipped == ["pp"] and limit is not None and limit < 1.0
    # Without the LMPC the median controller is the reference; all failed: all count.
    assert robust_limit({"a": failing}, failed=["a"]) == (None, [])
    assert robust_limit({}) == (None, [])


def test_long_track_map_colours_the_path_by_error_and_zooms(long_track):
    assert is_long_track(long_track)
    logs = {"lmpc": _log(long_track, 0.3, n=300, ds=2.0), "rkmpc": _log(long_track, 0.1, n=300, ds=2.0)}
    fig = plot_runs(logs, long_track, title="ring")
    ax_map, ax_zoom = fig.axes[0], fig.axes[4]
    paths = [c for c in ax_map.collections if isinstance(c, LineCollection)]
    assert len(paths) == 1 and paths[0].get_array() is not None
    assert len(paths[0].get_segments()) == len(logs["rkmpc"]) - 1
    colourbar = fig.axes[5]
    assert "rkmpc" in colourbar.get_xlabel() and "lateral error" in colourbar.get_xlabel()
    # The zoom shows the RKMPC's worst step (the bump at step 150) and every controller.
    assert "rkmpc" in ax_zoom.get_title()
    worst = 150
    x0, x1 = ax_zoom.get_xlim()
    assert x0 < logs["rkmpc"]["x"][worst] < x1 and x1 - x0 < 20.0
    assert {"lmpc", "rkmpc"} <= {line.get_label() for line in ax_zoom.get_lines()}
    # The map shows the whole track, and the legend stays off the data.
    assert ax_map.get_xlim()[1] - ax_map.get_xlim()[0] > 1000.0
    _assert_legend_off_the_axes(fig)


def test_short_track_map_has_no_detail(track):
    assert not is_long_track(track)
    fig = plot_runs({"rkmpc": _log(track, 0.1)}, track)
    assert len(fig.axes) == 4
    assert not [c for c in fig.axes[0].collections if isinstance(c, LineCollection)]


def test_main_controller():
    assert main_controller(["lmpc", "rkmpc", "kmpc"]) == "rkmpc"
    assert main_controller(["lmpc+delay", "kmpc+delay"]) == "kmpc+delay"
    assert main_controller(["pp", "lmpc"]) == "pp"
    assert main_controller([]) is None


def test_solve_times_mark_the_fall_backs(track):
    logs = {"lmpc": _log(track, 0.1), "nmpc-dynamic": _log(track, 0.1), "rkmpc": _log(track, 0.1)}
    status = logs["nmpc-dynamic"]["status"]
    status[::5] = 3.0  # 12 of 60 steps hit the iteration limit
    logs["nmpc-dynamic"]["solve_time_s"][0] = math.nan  # one without a time
    assert len(fallback_steps(logs["nmpc-dynamic"])) == 12
    fig = plot_solve_times(logs, period_s=0.05)
    ax = fig.axes[0]
    marks = [line for line in ax.get_lines() if line.get_marker() == "v"]
    assert sum(len(line.get_xdata()) for line in marks) == 12
    assert all(np.isfinite(line.get_xdata()).all() for line in marks)
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "12 fall-backs" in legend
    ticks = [t.get_text() for t in ax.get_yticklabels()]
    assert ticks == ["lmpc", "nmpc-dynamic\n12 fall-backs", "rkmpc"]


def test_no_fall_backs_no_marks(track):
    log = _log(track, 0.1)
    old = StepLog([c for c in COLUMNS if c != "status"])  # a log from before the status column
    for row in log.as_array():
        old.append(np.delete(row, COLUMNS.index("status")))
    assert len(fallback_steps(old)) == 0
    fig = plot_solve_times({"lmpc": log, "old": old})
    assert not [line for line in fig.axes[0].get_lines() if line.get_marker() == "v"]
    assert not any("fall-back" in t.get_text() for t in fig.legends[0].get_texts())


def test_solve_times_flag_a_maximum_beyond_the_control_period(track):
    logs = {"lmpc": _log(track, 0.1), "nmpc-dynamic": _log(track, 0.1)}
    logs["nmpc-dynamic"]["solve_time_s"][7] = 0.063  # one step of 63 ms at a 50 ms period
    ax = plot_solve_times(logs, period_s=0.05).axes[0]
    texts = {t.get_text(): t for t in ax.texts}
    (late,) = [text for text in texts if "beyond" in text]
    assert late.endswith("/ 63.00 ms: max beyond the 50 ms period!")
    assert texts[late].get_color() == "#D55E00" and texts[late].get_fontweight() == "bold"
    assert [t.get_text() for t in ax.get_yticklabels()] == ["lmpc", "nmpc-dynamic\nLATE"]
    assert ax.get_xlim()[1] > 63.0 * 10  # the flagged text has room on the axes
    ax = plot_solve_times({"lmpc": logs["lmpc"]}, period_s=0.05).axes[0]
    assert not [t for t in ax.texts if "beyond" in t.get_text()]


def test_the_lmpc_is_drawn_over_the_nonlinear_mpcs_and_lmpc_id_stands_out(track):
    """The demo plot: lmpc's path was hidden under nmpc's, lmpc-id's hard to find."""
    order = ["pp", "nmpc", "nmpc-dynamic", "lmpc", "kmpc", "rkmpc-paper", "lmpc-id", "rkmpc"]
    z = {name: CONTROLLER_STYLE[name].zorder for name in order}
    assert [z[name] for name in order] == sorted(z.values()) and len({z["nmpc"], z["lmpc"]}) == 2
    assert CONTROLLER_STYLE["lmpc-id"].linewidth > CONTROLLER_STYLE["kmpc"].linewidth
    logs = {name: _log(track, 0.1) for name in ("nmpc", "lmpc", "lmpc-id", "rkmpc")}  # one path for all
    fig = plot_runs(logs, track)
    paths = {line.get_label(): line.get_zorder() for line in fig.axes[0].get_lines()}
    assert paths["nmpc"] < paths["lmpc"] < paths["lmpc-id"] < paths["rkmpc"]
