"""Bad CSV logs, bad spec files and bad windows: clear errors naming the file and the column or key."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.learning.data.logs import (
    FRICTION_MAPS,
    CsvLogSpec,
    PoseSource,
    TimeColumns,
    csv_spec,
    import_csv_log,
    load_csv_spec,
    spec_toml,
)
from rkmpc.learning.data.window import TimeWindow
from rkmpc.vehicle.params import f1tenth


def _edit(path: Path, old: str, new: str, count: int = 1) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, count))


def _import(folder: Path, spec: CsvLogSpec = FRICTION_MAPS) -> None:
    import_csv_log(folder, f1tenth(), spec)


def test_a_missing_column_names_the_file_the_column_and_what_is_there(drive_log):
    folder = drive_log()
    _edit(folder / "odomData.csv", ",s,ns,vx,", ",s,ns,speed,")
    with pytest.raises(InputFileError, match=r"odomData\.csv \[vx\]: no such column; the file has") as err:
        _import(folder)
    assert err.value.field == "vx" and err.value.path == folder / "odomData.csv"
    assert "'speed'" in str(err.value)


def test_a_missing_file_and_a_missing_folder_are_named(drive_log, tmp_path):
    folder = drive_log()
    (folder / "imuData.csv").unlink()
    with pytest.raises(InputFileError, match=r"imuData\.csv: no such file"):
        _import(folder)
    with pytest.raises(InputFileError, match="no such folder"):
        _import(tmp_path / "nowhere")


def test_stamps_that_go_backwards_name_the_file_the_columns_and_the_row(drive_log):
    folder = drive_log()
    lines = (folder / "imuData.csv").read_text().splitlines()
    lines[5], lines[6] = lines[6], lines[5]
    (folder / "imuData.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputFileError, match=r"imuData\.csv \[s\+ns\]: row 6: the stamp goes backwards"):
        _import(folder)
    lines[6] = lines[5]
    (folder / "imuData.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputFileError, match="row 6: the stamp repeats the one before"):
        _import(folder)


def test_a_value_that_is_no_number_or_not_finite_names_its_row(drive_log):
    folder = drive_log()
    lines = (folder / "commandData.csv").read_text().splitlines()
    lines[3] = lines[3].rsplit(",", 1)[0] + ",left"
    (folder / "commandData.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputFileError, match=r"commandData\.csv \[delta\]: row 3: 'left' is not a number"):
        _import(folder)
    lines[3] = lines[3].rsplit(",", 1)[0] + ",nan"
    (folder / "commandData.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputFileError, match=r"\[delta\]: row 3: 'nan' is not finite"):
        _import(folder)


def test_a_ragged_row_is_refused(drive_log):
    folder = drive_log()
    _edit(folder / "pfPoseData.csv", "\n0,", "\n0,1,", 1)
    with pytest.raises(InputFileError, match=r"pfPoseData\.csv: row 1 has 10 values, the header 9 columns"):
        _import(folder)


def test_an_empty_window_names_the_window_and_the_span(drive_log):
    with pytest.raises(InputFileError, match=r"window 40:50 holds 0 sample\(s\) of pose .* 0 to 19\.\d+ s"):
        import_csv_log(drive_log(), f1tenth(), FRICTION_MAPS, window=TimeWindow(40.0, 50.0))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("10", "expected START:END"),
        ("a:5", "'a' is not a number"),
        ("@5:9", "mark both ends absolute"),
        (":", "give a start, an end or both"),
        ("9:5", "start must be before end"),
        ("-1:5", "must be >= 0"),
    ],
)
def test_bad_windows_are_refused(text, message):
    with pytest.raises(ParameterError, match=message):
        TimeWindow.parse(text)


def test_windows_parse_and_print_back():
    assert TimeWindow.parse("10:60") == TimeWindow(10.0, 60.0)
    assert TimeWindow.parse(" :45") == TimeWindow(None, 45.0)
    window = TimeWindow.parse("@1650776500.25:@1650776560")
    assert window.absolute and window.start == 1650776500.25
    assert TimeWindow.parse(window.text()) == window


def test_a_spec_file_reads_back_to_the_preset(tmp_path):
    path = tmp_path / "friction.toml"
    path.write_text(spec_toml(FRICTION_MAPS))
    assert load_csv_spec(path) == FRICTION_MAPS
    assert csv_spec(path) == FRICTION_MAPS and csv_spec("friction-maps") is FRICTION_MAPS


_MINIMAL = """
[time]
seconds = "t"

[pose]
file = "pose.csv"
x = "x"
y = "y"
yaw = "heading"
yaw_unit = "deg"

[speed]
file = "odom.csv"
column = "v"
unit = "km/h"

[command]
file = "cmd.csv"
speed = "v"
steer = "steer"
time = { seconds = "stamp", unit = "ms" }

[import]
dt = 0.1
"""


def test_a_spec_file_fills_every_signal_s_time_columns_from_time(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(_MINIMAL)
    spec = load_csv_spec(path)
    assert spec.name == "mine" and spec.dt == 0.1 and spec.yaw_rate is None
    assert spec.pose.time == TimeColumns(seconds="t") and spec.pose.yaw == "heading"
    assert spec.command.time == TimeColumns(seconds="stamp", unit="ms")
    assert spec.files == ("pose.csv", "odom.csv", "cmd.csv")


@pytest.mark.parametrize(
    ("old", "new", "key", "message"),
    [
        ('unit = "km/h"', 'unit = "furlong/s"', "speed.unit", "must be a speed unit"),
        ('yaw_unit = "deg"', 'yaw_unit = "grad"', "pose.yaw_unit", "must be a angle unit"),
        ('x = "x"\n', "", "pose.x", "missing key"),
        ('yaw = "heading"', 'yaw = "h"\nquaternion = ["a", "b", "c", "d"]', "pose.quaternion", "one of"),
        ('column = "v"', 'column = "v"\ncolour = "red"', "speed.colour", "unknown key"),
        ("dt = 0.1", "dt = -0.1", "import.dt", "must be finite and > 0"),
        ("dt = 0.1", 'dt = "fast"', "import.dt", "expected a number"),
        ('seconds = "t"', 'second = "t"', "time.second", "unknown key"),
        ("[command]", "[commands]", "commands", "unknown key"),
    ],
)
def test_a_bad_spec_file_names_the_file_and_the_key(tmp_path, old, new, key, message):
    path = tmp_path / "bad.toml"
    assert old in _MINIMAL
    path.write_text(_MINIMAL.replace(old, new, 1))
    with pytest.raises(InputFileError, match=message) as err:
        load_csv_spec(path)
    assert err.value.path == path and err.value.field == key


def test_a_quaternion_needs_four_columns_and_no_time_is_an_error(tmp_path):
    path = tmp_path / "q.toml"
    path.write_text(_MINIMAL.replace('yaw = "heading"', 'quaternion = ["qz", "qw"]'))
    with pytest.raises(InputFileError, match="a list of 4 column names") as err:
        load_csv_spec(path)
    assert err.value.field == "pose.quaternion"
    path.write_text(_MINIMAL.replace('[time]\nseconds = "t"\n', ""))
    with pytest.raises(InputFileError, match="no time columns") as err:
        load_csv_spec(path)
    assert err.value.field == "pose.time"


def test_a_name_that_is_neither_a_preset_nor_a_file_lists_the_presets(tmp_path):
    with pytest.raises(InputFileError, match=r"nor a preset \(\['friction-maps'\]\)"):
        csv_spec(tmp_path / "missing.toml")
    (tmp_path / "broken.toml").write_text("[pose\n")
    with pytest.raises(InputFileError, match="not a valid TOML file"):
        csv_spec(tmp_path / "broken.toml")


def test_the_spec_classes_refuse_bad_values():
    with pytest.raises(ParameterError, match="yaw or as quaternion"):
        PoseSource(file="p.csv", time=TimeColumns(seconds="t"), x="x", y="y")
    with pytest.raises(ParameterError, match=r"CsvLogSpec\.yaw_rate\.unit must be a rate unit"):
        replace(FRICTION_MAPS, yaw_rate=replace(FRICTION_MAPS.yaw_rate, unit="m/s"))
    with pytest.raises(ParameterError, match="command_tolerance must be None or in"):
        replace(FRICTION_MAPS, command_tolerance=0.05)
    with pytest.raises(ParameterError, match="scale must be a finite number other than 0"):
        replace(FRICTION_MAPS.speed, scale=0.0)
    with pytest.raises(ParameterError, match="different columns"):
        TimeColumns(seconds="s", nanoseconds="s")
