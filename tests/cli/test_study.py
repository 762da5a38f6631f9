"""Car files in ``study pace``, ``learn-pace`` and ``study data`` (``rkmpc.cli.study``,
``rkmpc.cli.learn_pace``): flag > file > preset, recorded.

Nothing trains here: the commands' settings are built from parsed arguments, and the one run of
``study data`` drives fakes (its worker and its LMPC lap).
"""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

import rkmpc.experiments.studies.data as data_mod
from rkmpc.analysis.metrics import LapMetrics
from rkmpc.cli import build_parser, main
from rkmpc.cli.learn_pace import learn_pace_config
from rkmpc.cli.study import StudyProgress, data_study_config, pace_study_config
from rkmpc.config.loader import load_car_config, load_preset
from rkmpc.experiments.parallel import JobOutcome
from rkmpc.experiments.studies.data_job import DataRun
from rkmpc.experiments.studies.pace_rules import car_ladder, pace_ladder
from rkmpc.sim.scenario import load_scenario

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
RACE = CONFIGS / "f1tenth-race.toml"

#: The three commands, each with the function that turns its arguments into its settings.
COMMANDS = {
    "study pace": (["study", "pace", "--tracks", "builtin"], pace_study_config),
    "learn-pace": (["learn-pace", "--track", "builtin"], learn_pace_config),
    "study data": (["study", "data", "--track", "builtin"], data_study_config),
}


def _settings(command: str, *extra: str, out: Path = Path("unused")) -> Any:
    argv, build = COMMANDS[command]
    return build(build_parser().parse_args([*argv, *extra, "--out", str(out)]))


def _limits(command: str, settings: Any) -> Any:
    """The speed limits the command drives at (at the ladder's first pace for the pace commands)."""
    if command == "study data":
        return settings.scenario().limits
    study = settings.study() if command == "learn-pace" else settings
    return study.scenario("builtin", settings.paces[0]).limits


def _race_with_training(tmp_path: Path) -> Path:
    path = tmp_path / "race.toml"
    path.write_text(RACE.read_text() + "\n[training]\nseed = 3\nepochs = 4\ndata_laps = 1\n")
    return path


@pytest.mark.parametrize("command", COMMANDS)
def test_each_command_reads_the_race_pace_file(command):
    race = load_car_config(RACE)
    settings = _settings(command, "--config", str(RACE))
    assert settings.car.preset == "f1tenth" and settings.car.source == str(RACE.resolve())
    assert settings.car == race
    assert settings.car.limits == race.limits
    assert _limits(command, settings) == race.limits  # the ladder starts at the file's own pace
    if command != "study data":
        assert settings.paces == car_ladder(race) and settings.paces[0] == (6.0, 5.0)
        assert settings.paces[-1][1] == race.vehicle.drive.max_speed  # capped at the car's top speed


@pytest.mark.parametrize("command", COMMANDS)
def test_the_files_training_settings_reach_the_study(command, tmp_path):
    settings = _settings(command, "--config", str(_race_with_training(tmp_path)))
    assert settings.car.training.epochs == 4
    if command == "study data":  # it sizes its own data; the seeds are --seeds
        assert settings.seeds == (0, 1, 2)
    else:
        assert (settings.car.training.seed, settings.car.training.data_laps) == (3, 1)
    if command == "study pace":
        assert settings.seed == 3


@pytest.mark.parametrize("command", COMMANDS)
def test_flags_win_over_the_file(command, tmp_path):
    path = _race_with_training(tmp_path)
    if command == "study data":
        settings = _settings(command, "--config", str(path), "--epochs", "9", "--max-speed", "4.5")
        assert settings.car.training.epochs == 9
        assert _limits(command, settings) == load_car_config(path).limits.at_pace(None, 4.5)
    else:
        laps = "--data-laps" if command == "study pace" else "--laps"
        given = ("--seed", "7", "--epochs", "9", laps, "2", "--start", "4:3.5", "--steps", "1")
        settings = _settings(command, "--config", str(path), *given)
        training = settings.car.training
        assert (training.seed, training.epochs, training.data_laps) == (7, 9, 2)
        assert settings.paces == ((4.0, 3.5), (4.5, 4.0))
        # At the flag's pace, braking and traction scale from the file's limits, the rest stays.
        assert _limits(command, settings) == load_car_config(path).limits.at_pace(4.0, 3.5)
    with pytest.raises(ValueError, match="--vehicle fullsize contradicts"):
        _settings(command, "--config", str(path), "--vehicle", "fullsize")


@pytest.mark.parametrize("command", COMMANDS)
def test_a_bad_file_is_refused_naming_the_file_and_the_key(command, tmp_path, capsys):
    path = tmp_path / "car.toml"
    path.write_text("[limits]\nlateral_accel = -1\n")
    out = tmp_path / "o"
    argv, _ = COMMANDS[command]
    assert main([*argv, "--config", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{path} [limits.lateral_accel]: SpeedLimits.lateral_accel must be finite and > 0" in err
    assert not out.exists()
    assert main([*argv, "--config", str(tmp_path / "nope.toml"), "--out", str(out)]) == 2
    assert "nope.toml: file not found" in capsys.readouterr().err


@pytest.mark.parametrize("vehicle", ["f1tenth", "fullsize"])
def test_without_a_file_the_settings_are_the_presets_as_before(vehicle):
    assert car_ladder(load_preset(vehicle)) == pace_ladder(vehicle)
    pace = _settings("study pace", "--vehicle", vehicle)
    assert pace.paces == pace_ladder(vehicle) and pace.car.preset == vehicle
    training = pace.car.training
    assert (training.seed, training.data_laps, training.epochs, training.kmpc_samples) == (0, 2, None, 50_000)
    assert pace.car == load_preset(vehicle)
    assert pace.car.source is None
    learn = _settings("learn-pace")
    training = learn.car.training
    assert learn.paces == pace_ladder("f1tenth")
    assert (training.seed, training.data_laps, training.epochs) == (0, 2, None)


def test_the_preset_as_a_car_config_is_the_scenario_of_before():
    pace = (5.0, 4.5)
    settings = _settings("study pace")
    filed = settings.scenario("builtin", pace)
    plain = load_scenario("builtin", limits=load_preset("f1tenth").limits.at_pace(*pace))
    assert (filed.limits, filed.vehicle, filed.zoo_car) == (plain.limits, plain.vehicle, plain.zoo_car)
    assert filed.car == plain.car and filed.dt == plain.dt
    # Every controller is built from the same settings (the car's, at the scenario's period).
    assert filed.car.controllers.with_period(filed.dt) == plain.car.controllers.with_period(plain.dt)
    assert filed.provenance() == plain.provenance()


def _lap() -> LapMetrics:
    return LapMetrics(
        completed=True,
        progress=1.0,
        lap_time_s=20.0,
        lateral_error_mean_m=0.02,
        lateral_error_max_m=0.1,
        heading_error_mean_rad=0.01,
        steer_rate_mean_rad_s=0.1,
        command_rate_mean_rad_s=0.1,
        solve_ms_mean=1.0,
        solve_ms_p99=1.0,
        solve_ms_max=1.0,
        fallback_count=0,
        steps=100,
        lateral_accel_max_m_s2=None,
        status_counts={"ok": 100},
    )


def test_study_data_drives_the_files_car_and_records_it(tmp_path, monkeypatch):
    race = load_car_config(RACE)
    seen: list[Any] = []

    def data_job(cfg, controller, size, seed):
        seen.append(cfg.scenario().limits)
        return DataRun(
            controller=controller,
            size=size,
            seed=seed,
            source={"kind": "lmpc_laps", "laps": 1, "outcome": "completed", "completed": True},
            raw_count=size,
            augmented_count=size,
            valid_origins=size,
            windows=size // 35,
            ratio=0.3,
            target_met=True,
            model_options={},
            train_report={},
            data_s=0.1,
            train_s=0.1,
            fit_s=0.1,
            lap_s=0.1,
            metrics=_lap(),
        )

    def run_controller(scenario, spec, *, model=None, allow_mismatch=False):
        seen.append(scenario.limits)
        return None, _lap()

    monkeypatch.setattr(data_mod, "data_job", data_job)
    monkeypatch.setattr(data_mod, "run_controller", run_controller)
    out = tmp_path / "sd"
    argv = ["study", "data", "--config", str(RACE), "--sizes", "1000", "--seeds", "0", "--jobs", "1"]
    assert main([*argv, "--controllers", "rkmpc", "--epochs", "2", "--out", str(out)]) == 0
    assert seen == [race.limits, race.limits]  # the worker's car and the LMPC's
    recorded = json.loads((out / "study_data.json").read_text())["config"]["car"]
    assert recorded["file"] == str(RACE.resolve()) and len(recorded["sha256"]) == 64
    assert recorded["limits"]["lateral_accel"] == 6.0 and recorded["training"]["epochs"] == 2


def test_the_progress_counts_a_job_s_warnings_and_sums_them_up_at_the_end(tmp_path):
    console = Console(file=io.StringIO(), width=200)
    progress = StudyProgress(console)
    warned = ("IdentificationWarning: servo: kept nominal", "IdentificationWarning: tyres: kept nominal")
    progress(JobOutcome(name="Monza seed 0", index=0, ok=True, seconds=12.0, warnings=warned), 1, 2)
    progress(JobOutcome(name="IMS seed 0", index=1, ok=True, seconds=3.0), 2, 2)
    lines = console.file.getvalue().splitlines()
    assert lines == ["[1/2] Monza seed 0: 12 s, 2 warnings", "[2/2] IMS seed 0: 3 s"]
    summary = progress.summary(tmp_path / "study_tracks.json")
    assert summary is not None and summary.startswith("1 jobs warned (IdentificationWarning x2)")
    assert StudyProgress(console).summary(tmp_path / "x.json") is None
