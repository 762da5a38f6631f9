import json

import pytest

from rkmpc.analysis.metrics import METRIC_KEYS
from rkmpc.cli import main
from rkmpc.cli.compare import FAILED
from rkmpc.core.errors import OutputError, RkmpcError


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


@pytest.mark.parametrize("error", [OutputError("disk full"), RuntimeError("a bug")])
def test_compare_keeps_the_first_sensors_results_when_the_second_fails(tmp_path, capsys, monkeypatch, error):
    import rkmpc.experiments.compare as module

    real_compare = module.compare

    def failing_with_real_sensors(config, **kwargs):
        if config.car.sensors.name == "f1tenth-real":
            raise error
        return real_compare(config, **kwargs)

    monkeypatch.setattr(module, "compare", failing_with_real_sensors)
    out = tmp_path / "cmp"
    args = ["compare", "--controllers", "pp,lmpc", "--track", "oval", "--out", str(out)]
    if isinstance(error, RkmpcError):
        assert main(args) == 2
    else:
        with pytest.raises(RuntimeError, match="a bug"):
            main(args)
    assert set(json.loads((out / "results.json").read_text())["controllers"]) == {"pp", "lmpc"}
    failed = out / "sensors-f1tenth-real" / FAILED
    assert failed.read_text() == f"{type(error).__name__}: {error}\n"
    assert not (out / "sensors-f1tenth-real" / "results.json").exists()
    err = capsys.readouterr().err
    assert "f1tenth-real sensors failed" in err and "is kept" in err
    assert [p.name for p in tmp_path.iterdir()] == ["cmp"]


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
@pytest.mark.slow
def test_run_on_shared_track(tmp_path, shared_tracks, track):
    out = tmp_path / track
    path = shared_tracks / "centerlines" / f"{track}.csv"
    assert main(["run", "--controller", "lmpc", "--track", str(path), "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["completed"], metrics
    assert metrics["config"]["scenario"]["scale"] == 0.1
    # The default speed profile puts the car in the dynamic regime.
    assert metrics["lateral_accel_max_m_s2"] >= 4.0


@pytest.mark.slow
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


@pytest.mark.slow
def test_run_of_a_learned_controller_without_model_trains_it(tmp_path):
    out = tmp_path / "o"
    args = ["run", "--controller", "lmpc-id", "--track", "oval", "--no-cache", "--out", str(out)]
    assert main(args) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["training"]["lmpc-id"]["raw_samples"] > 200
    assert metrics["completed"] is True


def test_collect_from_a_run_log(tmp_path):
    run = tmp_path / "run"
    assert main(["run", "--controller", "pp", "--track", "oval", "--out", str(run)]) == 0
    data = tmp_path / "from_log.npz"
    assert main(["collect", "--from-log", str(run / "log.csv"), "--out", str(data)]) == 0
    from rkmpc.learning.data.dataset import TransitionDataset

    loaded = TransitionDataset.load(data)
    assert len(loaded) > 100
    assert loaded.metadata["controller"] == "pp"


RESULT_KEYS = {
    "completed": bool,
    "progress": float,
    "lap_time_s": (float, type(None)),
    "lateral_error_mean_m": float,
    "lateral_error_max_m": float,
    "heading_error_mean_rad": float,
    "steer_rate_mean_rad_s": float,
    "command_rate_mean_rad_s": float,
    "solve_ms_mean": float,
    "solve_ms_p99": float,
    "solve_ms_max": float,
}


def _learning_compare(out, cache):
    return main(
        [
            "compare",
            "--controllers",
            "pp,lmpc,lmpc-id,kmpc,rkmpc",
            "--track",
            "oval",
            "--epochs",
            "2",
            "--kmpc-samples",
            "1000",
            "--cache-dir",
            str(cache),
            "--out",
            str(out),
        ]
    )


@pytest.mark.slow
def test_compare_learns_and_writes_the_results_schema(tmp_path):
    out, cache = tmp_path / "cmp", tmp_path / "cache"
    assert _learning_compare(out, cache) == 0
    results = json.loads((out / "results.json").read_text())
    assert list(results["controllers"]) == ["pp", "lmpc", "lmpc-id", "kmpc", "rkmpc"]
    for name, metrics in results["controllers"].items():
        for key, kind in RESULT_KEYS.items():
            assert isinstance(metrics[key], kind), (name, key, metrics[key])
        assert 0.0 <= metrics["progress"] <= 1.0
        assert metrics["solve_ms_mean"] <= metrics["solve_ms_p99"] <= metrics["solve_ms_max"]
    training = results["training"]
    assert training["data"]["raw_samples"] > 200
    for name in ("kmpc", "rkmpc"):
        info = training[name]
        assert info["augmented_samples"] > info["raw_samples"] > 0 or name == "kmpc"
        assert info["fit_time_s"] > 0 and info["cached"] is False
        assert all(lo <= hi for lo, hi in zip(info["state_min"], info["state_max"], strict=True))
    assert len(training["rkmpc"]["state_min"]) == 5  # speed, yaw rate, wheel angle, previous command
    assert training["kmpc"]["raw_samples"] == 1000
    assert training["lmpc-id"]["raw_samples"] == training["data"]["raw_samples"]
    assert results["config"]["seed"] == 0 and "numpy" in results["config"]["versions"]
    table = (out / "table.md").read_text()
    assert all(f"| {n} |" in table for n in results["controllers"])
    for plot in ("plot.png", "solve_times.png"):
        assert (out / plot).stat().st_size > 10_000
    # The KMPC (learned from random excitation on the true state, shared by both runs) and one
    # residual model per sensor set: compare also drives the car through the real car's sensors.
    real = json.loads((out / "sensors-f1tenth-real" / "results.json").read_text())
    assert real["training"]["kmpc"]["cache_key"] == training["kmpc"]["cache_key"]
    assert real["training"]["rkmpc"]["cache_key"] != training["rkmpc"]["cache_key"]
    assert len(list(cache.glob("*.rkm"))) == 3


@pytest.mark.slow
def test_second_compare_reuses_the_cached_models(tmp_path):
    cache = tmp_path / "cache"
    assert _learning_compare(tmp_path / "a", cache) == 0
    assert _learning_compare(tmp_path / "b", cache) == 0
    a = json.loads((tmp_path / "a" / "results.json").read_text())
    b = json.loads((tmp_path / "b" / "results.json").read_text())
    assert b["training"]["kmpc"]["cached"] is True and b["training"]["rkmpc"]["cached"] is True
    assert b["training"]["kmpc"]["cache_key"] == a["training"]["kmpc"]["cache_key"]
    for name in ("kmpc", "rkmpc"):
        assert (
            b["controllers"][name]["lateral_error_mean_m"] == a["controllers"][name]["lateral_error_mean_m"]
        )


def test_model_for_a_controller_without_one_is_an_error(tmp_path, capsys):
    code = main(["compare", "--controllers", "lmpc,pp", "--model", "pp=x.rkm", "--out", str(tmp_path)])
    assert code == 2
    assert "takes no model" in capsys.readouterr().err


@pytest.mark.slow
def test_compare_with_a_fault_reports_its_effect(tmp_path, capsys):
    out = tmp_path / "fault"
    args = ["compare", "--controllers", "pp,lmpc", "--track", "oval", "--fault", "delay", "--out", str(out)]
    assert main(args) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["fault"] == "delay"
    assert set(results["faulted"]) == set(results["fault_effect"]) == {"pp", "lmpc"}
    assert set(results["fault_effect"].values()) <= {
        "completes",
        "degrades",
        "leaves the track",
        "does not finish",
    }
    faulted_runs = [r for r in results["config"]["runs"] if r.get("fault")]
    assert len(faulted_runs) == 2 and faulted_runs[0]["fault"]["name"] == "delay"
    assert "with delay" in (out / "table.md").read_text()
    assert (out / "plot_fault.png").stat().st_size > 10_000
    assert (out / "log_lmpc+delay.csv").exists()


def test_unknown_fault_is_a_clear_error(tmp_path, capsys):
    code = main(["compare", "--controllers", "pp", "--fault", "rain", "--out", str(tmp_path)])
    assert code == 2
    assert "rain" in capsys.readouterr().err


def test_study_tracks_in_parallel_writes_json_and_markdown(tmp_path, capsys):
    out = tmp_path / "st"
    args = ["study", "tracks", "--tracks", "builtin,oval", "--controllers", "pp,lmpc", "--jobs", "2"]
    assert main([*args, "--out", str(out)]) == 0
    result = json.loads((out / "study_tracks.json").read_text())
    assert result["summary"]["lmpc"]["completed"] == 2
    assert "| pp |" in (out / "study_tracks.md").read_text()


@pytest.mark.slow
def test_study_data_writes_json_plot_and_markdown(tmp_path):
    out = tmp_path / "sd"
    args = ["study", "data", "--sizes", "1000", "--seeds", "0", "--controllers", "rkmpc", "--epochs", "1"]
    assert main([*args, "--jobs", "1", "--out", str(out)]) == 0
    result = json.loads((out / "study_data.json").read_text())
    assert result["jobs"][0]["controller"] == "rkmpc"
    assert result["baseline"]["controller"] == "lmpc" and result["baseline"]["metrics"]["completed"]
    assert (out / "study_data.png").stat().st_size > 10_000


@pytest.mark.slow
def test_study_cars_writes_json_plot_and_markdown(tmp_path):
    out = tmp_path / "sc"
    args = ["study", "cars", "--cars", "gym,random-4", "--tracks", "oval", "--controllers", "pp,lmpc"]
    assert main([*args, "--jobs", "2", "--out", str(out)]) == 0
    result = json.loads((out / "study_cars.json").read_text())
    assert result["cars"] == ["gym", "random-4"]
    assert result["summary"]["gym"]["lmpc"]["completed"] == 1
    assert "### random-4: random draw" in (out / "study_cars.md").read_text()
    assert (out / "study_cars.png").stat().st_size > 10_000


@pytest.mark.slow  # several seconds: the slow tier (make test-slow, run by CI)
def test_compare_on_a_zoo_car_records_it(tmp_path):
    out = tmp_path / "cmp"
    assert main(["compare", "--controllers", "pp", "--car", "light-short", "--out", str(out)]) == 0
    result = json.loads((out / "results.json").read_text())
    assert result["config"]["scenario"]["car"]["name"] == "light-short"
    assert main(["compare", "--controllers", "pp", "--car", "tank", "--out", str(out)]) == 2


def test_train_identified_reports_identification_warnings_in_its_output(tmp_path, capsys):
    import warnings

    import numpy as np

    from rkmpc.core.errors import IdentificationWarning
    from rkmpc.learning.data.dataset import TransitionDataset
    from rkmpc.learning.io import load_identified

    # A car cornering steadily on a held wheel angle: the servo cannot be identified.
    n = 60
    obs = np.zeros((n + 1, 7))
    obs[:, 3], obs[:, 6], obs[:, 5] = 3.0, 0.1, np.nan
    obs[:, 4] = 3.0 * np.tan(0.1) / 0.4
    obs[:, 2] = obs[:, 4] * 0.05 * np.arange(n + 1)  # on a circle of radius 3 / yaw_rate
    obs[:, 0] = 3.0 / obs[0, 4] * np.sin(obs[:, 2])
    obs[:, 1] = 3.0 / obs[0, 4] * (1.0 - np.cos(obs[:, 2]))
    command = np.column_stack([np.full(n, 3.0), np.full(n, 0.1)])
    data = tmp_path / "data.npz"
    TransitionDataset(obs[:-1], command, obs[1:], 0.05, np.zeros(n, dtype=int)).save(data)
    out = tmp_path / "id.json"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["train", "--data", str(data), "--kind", "identified", "--out", str(out)]) == 0
    assert not [w for w in caught if issubclass(w.category, IdentificationWarning)]
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("identified servo nominal: tau 0.158 s")
    servo = [line for line in lines if line.startswith("warning: servo:")]
    assert servo and servo[0].startswith("warning: servo: the wheel angle barely moves")
    assert load_identified(out).warnings[0] == servo[0].removeprefix("warning: ")
    # A data set written without a contract is said so, too.
    assert any("made before contracts" in line for line in lines)
