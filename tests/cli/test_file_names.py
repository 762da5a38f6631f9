"""A track file whose name is not valid UTF-8 (bytes from another system's encoding): the run
completes and shows the name safely (issue 27: the plot title raised TypeError after the lap)."""

from __future__ import annotations

import json
import os

import numpy as np

from rkmpc.cli import main
from rkmpc.core.io import display_name


def test_undecodable_bytes_of_a_name_are_shown_as_escapes():
    name = os.fsdecode(b"ov\xe9al")  # how Python receives it from the command line or a folder
    assert name != "ov\xe9al" and display_name(name) == "ov\\xe9al"
    assert display_name("Nürburgring") == "Nürburgring"  # valid UTF-8 stays as it is


def test_a_run_on_a_track_file_whose_name_is_not_utf8_completes(tmp_path, capsys):
    t = np.linspace(0.0, 2 * np.pi, 80, endpoint=False)
    rows = "\n".join(f"{20 * np.cos(a):.6f},{12 * np.sin(a):.6f},2,2" for a in t)
    track = tmp_path / os.fsdecode(b"ov\xe9al.csv")
    track.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n" + rows + "\n")
    out = tmp_path / "o"
    args = ["run", "--controller", "pp", "--track", str(track), "--scale", "1", "--out", str(out)]
    assert main(args) == 0, capsys.readouterr().err
    assert "ov\\xe9al (scale 1, f1tenth)" in capsys.readouterr().out
    scenario = json.loads((out / "metrics.json").read_text())["config"]["scenario"]
    assert scenario["track"] == "ov\\xe9al" and scenario["track_source"].endswith("ov\\xe9al.csv")
    assert (out / "plot.png").stat().st_size > 0
