import json

import pytest

from rkmpc.analysis.metrics import METRIC_KEYS
from rkmpc.cli import main


def test_run_writes_log_metrics_and_plot(tmp_path):
    out = tmp_path / "run"
    assert main(["run", "--controller", "lmpc", "--track", "builtin", "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(METRIC_KEYS) <= set(metrics)
    assert metrics["completed"] is True
    assert isinstance(metrics["lap_time_s"], float)
    cfg = metrics["config"]
    assert cfg["scenario"]["track"] == "builtin"
    assert cfg["scenario"]["vehicle"] == "f1tenth"
    assert cfg["runs"][0]["seed"] == 0
    assert "numpy" in cfg["versions"]
    header = (out / "log.csv").read_text().splitlines()[0].split(",")
    assert {"t", "x", "cmd_steer", "wheel_angle", "lateral_error", "solve_time_s"} <= set(header)
    assert (out / "plot.png").stat().st_size > 10_000
    # No temporary files are left behind.
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_compare_writes_results_and_table(tmp_path, capsys):
    out = tmp_path / "cmp"
    code = main(
        [
            "compare",
            "--controllers",
            "pp,lmpc",
            "--track",
            "oval",
            "--noise",
            "--seed",
            "3",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    results = json.loads((out / "results.json").read_text())
    assert set(results["controllers"]) == {"pp", "lmpc"}
    assert results["config"]["runs"][0]["noise"]["position"] > 0
    assert results["config"]["runs"][1]["seed"] == 3
    table = (out / "table.md").read_text()
    assert "| lmpc |" in table and "| pp |" in table
    assert "lmpc" in capsys.readouterr().out


def test_bad_track_file_is_a_clear_error(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("# x_m,y_m,w_tr_right_m\n0,0,1\n1,0,1\n1,1,1\n0,1,1\n")
    code = main(["run", "--controller", "pp", "--track", str(bad), "--out", str(tmp_path / "o")])
    assert code == 2
    err = capsys.readouterr().err
    assert "bad.csv" in err and "w_tr_left_m" in err


def test_unknown_controller_in_compare(tmp_path, capsys):
    assert main(["compare", "--controllers", "pp,xyz", "--out", str(tmp_path)]) == 2
    assert "xyz" in capsys.readouterr().err


def test_tracks_lists_builtin(capsys):
    assert main(["tracks"]) == 0
    assert "builtin" in capsys.readouterr().out


def test_missing_track_file(tmp_path, capsys):
    code = main(
        ["run", "--controller", "pp", "--track", str(tmp_path / "nope.csv"), "--out", str(tmp_path / "o")]
    )
    assert code == 2
    assert "nope.csv" in capsys.readouterr().err


@pytest.mark.parametrize("track", ["Monza", "Silverstone"])
def test_run_on_shared_track(tmp_path, shared_tracks, track):
    out = tmp_path / track
    path = shared_tracks / "centerlines" / f"{track}.csv"
    assert main(["run", "--controller", "lmpc", "--track", str(path), "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["completed"], metrics
    assert metrics["config"]["scenario"]["scale"] == 0.1
    # The default speed profile puts the car in the dynamic regime.
    assert metrics["lateral_accel_max_m_s2"] >= 4.0


def test_collect_train_run_learned(tmp_path):
    data = tmp_path / "data.npz"
    assert main(["collect", "--track", "oval", "--laps", "1", "--out", str(data)]) == 0
    model = tmp_path / "res.rkm"
    assert (
        main(["train", "--data", str(data), "--kind", "residual", "--epochs", "3", "--out", str(model)]) == 0
    )
    ident = tmp_path / "id.json"
    assert main(["train", "--data", str(data), "--kind", "identified", "--out", str(ident)]) == 0
    out = tmp_path / "cmp"
    code = main(
        [
            "compare",
            "--track",
            "oval",
            "--controllers",
            "lmpc,lmpc-id,rkmpc",
            "--model",
            f"rkmpc={model}",
            "--model",
            f"lmpc-id={ident}",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    results = json.loads((out / "results.json").read_text())
    assert set(results["controllers"]) == {"lmpc", "lmpc-id", "rkmpc"}


def test_model_of_the_wrong_kind_is_refused(tmp_path, capsys):
    data = tmp_path / "data.npz"
    assert main(["collect", "--track", "oval", "--laps", "1", "--out", str(data)]) == 0
    model = tmp_path / "paper.rkm"
    assert main(["train", "--data", str(data), "--kind", "paper", "--epochs", "2", "--out", str(model)]) == 0
    code = main(["run", "--controller", "rkmpc", "--model", str(model), "--out", str(tmp_path / "o")])
    assert code == 2
    assert "paper" in capsys.readouterr().err


def test_learned_controller_without_model(tmp_path, capsys):
    assert main(["run", "--controller", "rkmpc", "--out", str(tmp_path / "o")]) == 2
    assert "--model" in capsys.readouterr().err


def test_collect_from_a_run_log(tmp_path):
    run = tmp_path / "run"
    assert main(["run", "--controller", "pp", "--track", "oval", "--out", str(run)]) == 0
    data = tmp_path / "from_log.npz"
    assert main(["collect", "--from-log", str(run / "log.csv"), "--out", str(data)]) == 0
    from rkmpc.learning.dataset import TransitionDataset

    loaded = TransitionDataset.load(data)
    assert len(loaded) > 100
    assert loaded.metadata["controller"] == "pp"
