"""``rkmpc collect --from-csv DIR --csv-spec ...`` and ``--window`` (for bags too): data set, report, errors.

``rkmpc.cli._cmd_collect`` hands ``--from-bag`` to :func:`rkmpc.cli.bags.cmd_collect_from_bag`;
``--from-csv`` is parsed by :func:`rkmpc.cli.bags.add_bag_args` and run here through
:func:`rkmpc.cli.bags.cmd_collect_from_csv` (the dispatch in ``_cmd_collect`` is the lead's).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from csv_logs import Drive, write_drive
from rkmpc.cli import build_parser, main
from rkmpc.cli.bags import cmd_collect_from_csv, quality_path
from rkmpc.learning.data.dataset import TransitionDataset


def _collect_csv(*argv: str) -> int:
    return cmd_collect_from_csv(build_parser().parse_args(["collect", *argv]))


def test_collect_from_csv_writes_the_data_set_and_its_quality_report(tmp_path, capsys):
    log = write_drive(tmp_path / "log", Drive(jump=(10.0, 0.8)))
    out = tmp_path / "d.npz"
    args = ["--from-csv", str(log), "--csv-spec", "friction-maps", "--window", "2:15", "--out", str(out)]
    assert _collect_csv(*args) == 0
    text = capsys.readouterr().out
    data = TransitionDataset.load(out)
    report = json.loads(quality_path(out).read_text())
    assert quality_path(out) == tmp_path / "d.quality.json"
    assert report["transitions"] == len(data) and report["window"] == "2:15" and len(report["jumps"]) == 1
    assert f"{len(data)} transitions in 2 episode(s) from {log} -> {out}" in text
    assert "## Data quality" in text and "### Pose jumps" in text
    assert max(len(line) for line in text.splitlines()[:-1]) <= 100
    assert np.isnan(data.obs[:, 6]).all() and data.metadata["window"]["text"] == "2:15"


def test_a_spec_file_is_read_and_its_errors_name_the_key(tmp_path):
    from rkmpc.learning.data.logs import FRICTION_MAPS, spec_toml

    log = write_drive(tmp_path / "log")
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_toml(FRICTION_MAPS).replace('unit = "deg/s"', 'unit = "rad/s"'))
    out = tmp_path / "d.npz"
    assert _collect_csv("--from-csv", str(log), "--csv-spec", str(spec), "--out", str(out)) == 0
    (check,) = [u for u in json.loads(quality_path(out).read_text())["units"] if u["signal"] == "yaw_rate"]
    assert check["suspicious"] and check["match"] == "deg/s"
    spec.write_text(spec_toml(FRICTION_MAPS).replace('unit = "deg/s"', 'unit = "rpm"'))
    with pytest.raises(ValueError, match=r"spec\.toml \[yaw_rate\.unit\]: .*must be a rate unit"):
        _collect_csv("--from-csv", str(log), "--csv-spec", str(spec), "--out", str(tmp_path / "e.npz"))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ([], "--from-csv needs --csv-spec"),
        (["--csv-spec", "friction-maps", "--from-log", "x.csv"], "exclude each other"),
        (["--csv-spec", "friction-maps", "--window", "5"], "expected START:END"),
    ],
)
def test_collect_from_csv_refuses_bad_options(tmp_path, extra, message):
    log = write_drive(tmp_path / "log")
    with pytest.raises(ValueError, match=message):
        _collect_csv("--from-csv", str(log), "--out", str(tmp_path / "d.npz"), *extra)
    assert not (tmp_path / "d.npz").exists()


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """10 s of a circle at 2 m/s as a ROS 1 bag, odometry every 50 ms."""
    pytest.importorskip("rosbags")
    from rkmpc.learning.data.bags import BagWriteConfig, write_bag

    t = 0.05 * np.arange(201)
    yaw = 0.5 * t
    obs = np.stack([4 * np.sin(yaw), 4 * (1 - np.cos(yaw)), np.angle(np.exp(1j * yaw)), 2 + 0 * t,
                    0.5 + 0 * t, 0 * t, math.nan + 0 * t], axis=1)  # fmt: skip
    path = tmp_path_factory.mktemp("bags") / "circle.bag"
    command = np.tile([2.0, 0.08], (len(t), 1))
    write_bag(path, t, obs, command, BagWriteConfig(storage="ros1", start_time=100.0))
    return path


def test_a_window_keeps_that_stretch_of_a_bag(tmp_path, bag, capsys):
    full, part = tmp_path / "full.npz", tmp_path / "part.npz"
    assert main(["collect", "--from-bag", str(bag), "--out", str(full)]) == 0
    assert main(["collect", "--from-bag", str(bag), "--out", str(part), "--window", "2:5"]) == 0
    assert "60 transitions in 1 episode(s)" in capsys.readouterr().out
    whole, kept = TransitionDataset.load(full), TransitionDataset.load(part)
    np.testing.assert_allclose(kept.obs, whole.obs[40:100], atol=1e-9)
    assert kept.metadata["window"]["text"] == "2:5"
    assert main(["collect", "--from-bag", str(bag), "--out", str(part), "--window", "@102:@105"]) == 0
    np.testing.assert_allclose(TransitionDataset.load(part).obs, kept.obs, atol=1e-12)


def test_a_window_outside_a_bag_is_an_error(tmp_path, bag, capsys):
    out = tmp_path / "d.npz"
    assert main(["collect", "--from-bag", str(bag), "--out", str(out), "--window", "20:30"]) == 2
    err = capsys.readouterr().err
    assert "the window 20:30 holds no message" in err and "0 to 10.00 s" in err
