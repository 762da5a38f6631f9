"""A pace beyond what the car can do: a top speed beyond its drive is refused, a lateral limit beyond
its tyres' grip is said (issue 27: such runs left the track with nothing said)."""

from __future__ import annotations

import warnings

import pytest

from rkmpc.cli import _one_line_warnings, main
from rkmpc.cli.common import PaceWarning
from rkmpc.config.car import tyre_grip
from rkmpc.config.loader import load_car_config, load_preset
from rkmpc.core.errors import InputFileError, ParameterError


def test_the_tyres_grip_is_the_weaker_axles_peak_force_per_load():
    f1tenth, fullsize = load_preset("f1tenth"), load_preset("fullsize")
    assert tyre_grip(f1tenth.vehicle) == pytest.approx(11.16, abs=0.01)  # front: D sin(C pi/2), C < 1
    assert tyre_grip(fullsize.vehicle) == pytest.approx(9.81 * 1.0489)  # C > 1: D
    assert f1tenth.check_limits() == [] and fullsize.check_limits() == []  # the presets' own pace


def test_a_top_speed_beyond_the_cars_drive_is_refused_naming_both():
    car = load_preset("f1tenth")
    assert car.at_pace(max_speed=8.0).limits.max_speed == 8.0  # the drive's own top speed is fine
    with pytest.raises(ParameterError, match=r"--max-speed: 20 m/s.*\[vehicle.drive\] max_speed: 8 m/s"):
        car.at_pace(max_speed=20.0)


def test_a_drive_slower_than_the_pace_in_a_car_file_is_refused_naming_the_file(tmp_path):
    path = tmp_path / "slow.toml"
    path.write_text('[vehicle]\npreset = "f1tenth"\n\n[vehicle.drive]\nmax_speed = 0.5\n')
    with pytest.raises(InputFileError, match=r"slow.toml.*--max-speed: 3.5 m/s.*max_speed: 0.5 m/s"):
        load_car_config(path)
    slow = '[vehicle]\npreset = "f1tenth"\n\n[vehicle.drive]\nmax_speed = 0.5\n\n'
    path.write_text(slow + "[limits]\nmax_speed = 0.5\n")
    with pytest.raises(InputFileError, match="min_speed"):  # the floor of 0.5 m/s must go too
        load_car_config(path)
    path.write_text(
        '[vehicle]\npreset = "f1tenth"\n\n[vehicle.drive]\nmax_speed = 0.5\n\n'
        "[limits]\nmax_speed = 0.5\nmin_speed = 0.2\n"
    )
    assert load_car_config(path).limits.max_speed == 0.5


def test_a_lateral_limit_beyond_the_grip_is_said_in_one_line(tmp_path, capsys):
    car = load_preset("f1tenth").at_pace(lateral_accel=30.0)  # allowed: the pace study climbs past it
    (doubt,) = car.check_limits()
    assert "30 m/s^2" in doubt and "grip, about 11.2 m/s^2" in doubt
    out = tmp_path / "o"
    args = ["run", "--controller", "pp", "--track", "oval", "--lateral-accel", "30", "--out", str(out)]
    with pytest.warns(PaceWarning) as seen:
        assert main(args) == 0
    assert [str(w.message) for w in seen if w.category is PaceWarning] == [doubt]
    with _one_line_warnings():  # how the command line shows a warning: one line, no source
        assert warnings.formatwarning(doubt, PaceWarning, "common.py", 1) == f"rkmpc: warning: {doubt}\n"
    assert main([*args[:5], "--max-speed", "20", "--out", str(tmp_path / "o2")]) == 2
    assert "[vehicle.drive] max_speed: 8 m/s" in capsys.readouterr().err
