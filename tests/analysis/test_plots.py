"""Figures from step logs and study series: axes, one line per controller, atomic PNG files."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

from rkmpc.analysis.plots import controller_style, plot_runs, plot_solve_times, save_figure
from rkmpc.analysis.statistics import Stats
from rkmpc.analysis.study_plots import VolumeSeries, plot_data_study
from rkmpc.sim.closed_loop import log_columns
from rkmpc.sim.log import StepLog

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
COLUMNS = log_columns(("x", "y", "yaw", "v", "beta", "yaw_rate", "delta"))


def _log(track, offset: float, n: int = 40, solve_s=None, outcome: str = "completed") -> StepLog:
    """A car driving the first ``n`` dm of the reference path ``offset`` m to its left."""
    path = track.reference_path
    log = StepLog(COLUMNS)
    rng = np.random.default_rng(abs(round(1000 * offset)) + n)
    for k in range(n):
        s = 0.1 * k
        pos = path.position(s)
        heading = float(path.heading(s))
        row = dict.fromkeys(COLUMNS, 0.0)
        row.update(
            t=0.05 * k,
            s=s,
            progress=s,
            x=float(pos[0]) - offset * math.sin(heading),
            y=float(pos[1]) + offset * math.cos(heading),
            lateral_error=offset + 0.01 * math.sin(k),
            heading_error=0.02 * math.cos(k),
            wheel_angle=0.05 * math.sin(0.3 * k),
            solve_time_s=rng.uniform(1e-4, 2e-3) if solve_s is None else solve_s[k],
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


def _labels(ax) -> list[str]:
    return [line.get_label() for line in ax.get_lines() if not line.get_label().startswith("_")]


def test_controller_style():
    assert controller_style("rkmpc") == {"color": "#D55E00", "ls": "-", "lw": 1.8, "zorder": 3.0}
    assert controller_style("lmpc+delay") == {"color": "#0072B2", "ls": "--", "lw": 1.4, "zorder": 2.4}
    assert controller_style("unknown") == {"lw": 1.1, "ls": "-"}


def test_plot_runs_axes_and_lines(track):
    logs = {"lmpc": _log(track, 0.1), "rkmpc": _log(track, -0.05), "mine": _log(track, 0.2, n=20)}
    fig = plot_runs(logs, track, title="builtin")
    assert isinstance(fig, Figure)
    assert fig.get_suptitle() == "builtin"
    assert len(fig.axes) == 4
    ax_map, ax_lat, ax_head, ax_wheel = fig.axes
    assert (ax_map.get_xlabel(), ax_map.get_ylabel()) == ("x (m)", "y (m)")
    assert ax_lat.get_ylabel() == "lateral error (m)"
    assert ax_head.get_ylabel() == "heading error (rad)"
    assert ax_wheel.get_ylabel() == "front wheel angle (rad)"
    assert ax_wheel.get_xlabel() == "distance along the reference (m)"
    # Map: the two track edges, the reference, one path per controller and the start marker.
    assert _labels(ax_map) == ["reference", "lmpc", "rkmpc", "mine", "start"]
    assert len(ax_map.get_lines()) == 2 + 1 + len(logs) + 1
    # Each trace: one line per controller plus the zero level.
    for ax in (ax_lat, ax_head, ax_wheel):
        assert len(ax.get_lines()) == len(logs) + 1
    assert _labels(ax_lat) == list(logs)
    # The traces are the logged columns against the distance, in the controller's colour.
    lat_lines = {line.get_label(): line for line in ax_lat.get_lines()}
    np.testing.assert_array_equal(lat_lines["mine"].get_xdata(), logs["mine"]["progress"])
    np.testing.assert_array_equal(lat_lines["mine"].get_ydata(), logs["mine"]["lateral_error"])
    np.testing.assert_array_equal(ax_wheel.get_lines()[1].get_ydata(), logs["rkmpc"]["wheel_angle"])
    map_lines = {line.get_label(): line for line in ax_map.get_lines()}
    np.testing.assert_array_equal(map_lines["lmpc"].get_xdata(), logs["lmpc"]["x"])
    assert map_lines["rkmpc"].get_color() == "#D55E00"
    assert lat_lines["rkmpc"].get_color() == "#D55E00"
    assert lat_lines["rkmpc"].get_linewidth() == pytest.approx(1.8)
    # One legend, for the whole figure: the controllers, the reference and the start.
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [*logs, "reference", "start"]
    assert all(ax.get_legend() is None for ax in fig.axes)


def test_plot_runs_marks_where_a_car_left_the_track(track):
    logs = {"pp": _log(track, 0.3, n=15, outcome="off_track"), "lmpc": _log(track, 0.0)}
    fig = plot_runs(logs, track)
    ax_map = fig.axes[0]
    assert fig.get_suptitle() == ""
    crosses = [line for line in ax_map.get_lines() if line.get_marker() == "x"]
    assert len(crosses) == 1
    assert crosses[0].get_xdata()[0] == pytest.approx(logs["pp"]["x"][-1])
    assert crosses[0].get_ydata()[0] == pytest.approx(logs["pp"]["y"][-1])
    assert crosses[0].get_color() == "#7F7F7F"
    assert "left the track" in [t.get_text() for t in fig.legends[0].get_texts()]


def test_plot_solve_times(track):
    solve = {
        "lmpc": np.full(40, 0.002),
        "rkmpc": np.linspace(0.001, 0.005, 40),
        "broken": np.full(40, math.nan),  # no finite step time: a box without marks
    }
    logs = {name: _log(track, 0.0, solve_s=s) for name, s in solve.items()}
    fig = plot_solve_times(logs, period_s=0.05, title="step times")
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert ax.get_title() == "step times"
    assert ax.get_xscale() == "log"
    assert ax.get_xlabel().startswith("controller step time (ms)")
    # One row per controller, the first at the top.
    ticks = dict(zip([t.get_text() for t in ax.get_yticklabels()], ax.get_yticks(), strict=True))
    assert set(ticks) == set(logs)
    assert ticks["lmpc"] > ticks["rkmpc"] > ticks["broken"]
    # Mean and max markers and the median / max text for the controllers with step times.
    texts = sorted(t.get_text() for t in ax.texts)
    assert texts == ["2.000 / 2.00 ms", "3.000 / 5.00 ms"]
    means = [line for line in ax.get_lines() if line.get_marker() == "o" and len(line.get_xdata())]
    assert sorted(float(line.get_xdata()[0]) for line in means) == pytest.approx([2.0, 3.0])
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == ["mean", "max", "control period 50 ms"]
    assert ax.get_xlim()[1] >= 75.0  # the control period fits on the axis


def test_plot_solve_times_without_period(track):
    logs = {"pp": _log(track, 0.0, solve_s=np.full(40, 1e-4))}
    fig = plot_solve_times(logs)
    ax = fig.axes[0]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == ["mean", "max"]
    assert ax.get_title() == ""
    assert ax.get_xlim()[1] == pytest.approx(0.1 * 8)


def _series() -> list[VolumeSeries]:
    return [
        VolumeSeries(
            controller="rkmpc",
            samples=[100.0, 1000.0, 10000.0],
            lateral=[
                Stats(3, 0.05, 0.01, 0.04, 0.06),
                Stats(3, 0.03, 0.005, 0.025, 0.035),
                Stats(1, 0.02, None, 0.02, 0.02),
            ],
            completion_rate=[0.33, 1.0, 1.0],
        ),
        VolumeSeries(
            controller="kmpc",
            samples=[100.0, 1000.0, 10000.0],
            lateral=[
                Stats(0, None, None, None, None),
                Stats(2, 0.08, 0.02, 0.06, 0.1),
                Stats(3, 0.06, 0.01, 0.05, 0.07),
            ],
            completion_rate=[0.0, 0.67, 1.0],
        ),
    ]


def test_plot_data_study():
    fig = plot_data_study(_series(), baseline_lateral=0.04, title="data study")
    assert isinstance(fig, Figure)
    assert fig.get_suptitle() == "data study"
    assert len(fig.axes) == 2
    ax_err, ax_done = fig.axes
    for ax in (ax_err, ax_done):
        assert ax.get_xscale() == "log"
        assert ax.get_xlabel() == "training samples (local-frame transitions)"
    assert ax_err.get_ylabel() == "mean lateral error (m), completed laps"
    assert ax_done.get_ylabel() == "laps completed (fraction of seeds)"
    assert ax_done.get_ylim() == pytest.approx((-0.05, 1.05))
    # One line per controller on each side (the left one with error bars and a band), plus the LMPC level.
    assert len(ax_done.get_lines()) == 2
    assert [line.get_label() for line in ax_done.get_lines()] == ["RKMPC", "KMPC"]
    np.testing.assert_array_equal(ax_done.get_lines()[1].get_ydata(), [0.0, 0.67, 1.0])
    assert len(ax_err.containers) == 2
    assert len(ax_err.collections) >= 2
    err_lines = [c.lines[0] for c in ax_err.containers]
    np.testing.assert_array_equal(err_lines[0].get_ydata(), [0.05, 0.03, 0.02])
    kmpc_mean = np.asarray(err_lines[1].get_ydata(), dtype=float)
    assert math.isnan(kmpc_mean[0]) and kmpc_mean[1:].tolist() == [0.08, 0.06]
    legend = [t.get_text() for t in ax_err.get_legend().get_texts()]
    assert sorted(legend) == ["KMPC", "LMPC (no data)", "RKMPC"]
    level = [line for line in ax_err.get_lines() if line.get_label() == "LMPC (no data)"]
    assert len(level) == 1 and level[0].get_ydata()[0] == pytest.approx(0.04)


def test_plot_data_study_without_baseline():
    fig = plot_data_study(_series()[:1], baseline_lateral=None, title="")
    ax_err = fig.axes[0]
    assert [t.get_text() for t in ax_err.get_legend().get_texts()] == ["RKMPC"]
    assert len(ax_err.containers) == 1


def test_save_figure_writes_a_png_and_closes_the_figure(tmp_path, track):
    fig = plot_runs({"lmpc": _log(track, 0.1)}, track)
    number = fig.number
    assert plt.fignum_exists(number)
    path = tmp_path / "out" / "plot.png"
    save_figure(fig, path, dpi=40)
    assert path.read_bytes().startswith(PNG_SIGNATURE)
    assert not plt.fignum_exists(number)
    assert [p.name for p in path.parent.iterdir()] == ["plot.png"]


def test_save_figure_of_a_study_plot(tmp_path):
    path = tmp_path / "study.png"
    path.write_bytes(b"old")
    save_figure(plot_data_study(_series(), 0.04, "t"), path, dpi=40)
    assert path.read_bytes().startswith(PNG_SIGNATURE)
    assert [p.name for p in tmp_path.iterdir()] == ["study.png"]


def test_save_figure_failure_keeps_the_old_file_and_closes_the_figure(tmp_path, monkeypatch):
    fig, _ = plt.subplots()
    path = tmp_path / "plot.png"
    path.write_bytes(b"old content")

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(fig, "savefig", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        save_figure(fig, path)
    assert path.read_bytes() == b"old content"
    assert [p.name for p in tmp_path.iterdir()] == ["plot.png"]
    assert not plt.fignum_exists(fig.number)
