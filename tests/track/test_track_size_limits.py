"""Tracks in the wrong unit or at an absurd scale are refused, not driven for days of simulated time."""

from __future__ import annotations

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.sim.closed_loop import MAX_STEPS, SimConfig
from rkmpc.track.loaders import load_centerline
from rkmpc.track.track import MAX_TRACK_LENGTH, track_length_problem


def _write(path, factor: float) -> None:
    t = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    rows = [f"{factor * 10 * np.cos(a):.6f},{factor * 6 * np.sin(a):.6f},1.0,1.0" for a in t]
    path.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n" + "\n".join(rows) + "\n")


def test_a_normal_track_loads(tmp_path):
    _write(tmp_path / "oval.csv", 1.0)
    assert load_centerline(tmp_path / "oval.csv").length < 100.0


@pytest.mark.parametrize(("factor", "scale"), [(1e9, 1.0), (1.0, 1e6)])
def test_a_huge_track_is_refused_naming_the_file(tmp_path, factor, scale):
    path = tmp_path / "oval.csv"
    _write(path, factor)
    with pytest.raises(
        InputFileError, match=r"oval\.csv \[x_m,y_m\]: the line is .* m long, more than 100 km"
    ):
        load_centerline(path, scale=scale)


def test_the_length_bound():
    assert track_length_problem(21_000.0) is None
    assert track_length_problem(float("inf")) is not None
    assert "wrong scale" in str(track_length_problem(2 * MAX_TRACK_LENGTH))


def test_an_endless_time_limit_is_refused():
    with pytest.raises(ParameterError, match="max_time must be finite"):
        SimConfig(max_time=float("inf"))
    assert MAX_STEPS * SimConfig().dt > 24 * 3600


def test_latitude_and_longitude_read_as_metres_are_refused(tmp_path):
    """A lap of a real circuit in degrees is a few hundredths of a 'metre' long."""
    th = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    lat, lon = 48.26 + 0.004 * np.sin(th), 11.55 + 0.006 * np.cos(th)
    path = tmp_path / "gps.csv"
    rows = "\n".join(f"{x},{y},5.0,5.0" for x, y in zip(lon, lat, strict=True))
    path.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n" + rows + "\n")
    with pytest.raises(InputFileError, match=r"degrees \(latitude, longitude\)"):
        load_centerline(path)
