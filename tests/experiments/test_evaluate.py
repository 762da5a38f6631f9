"""``rkmpc evaluate`` (issue 25): open-loop k-step prediction of recorded driving against the kinematic model.

On one simulated LMPC lap of the built-in track: a residual model (least squares in the fast tier,
``train_to_file`` with 2 epochs in the slow one), an identified model and the nominal ``kinematic``
model, one row per model and horizon. On the real car's logs (slow tier): a residual model trained
on DS2 predicts DS3 better than the kinematic model.
"""

from __future__ import annotations

import itertools
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from csv_logs import REAL_LOGS
from rkmpc.cli import main
from rkmpc.control.learned.residual_config import RKMPCConfig
from rkmpc.core.errors import ParameterError
from rkmpc.experiments.evaluate import MAX_HORIZON, evaluate, model_kind
from rkmpc.experiments.training import train_to_file
from rkmpc.learning.data.augmentation import AugmentConfig
from rkmpc.learning.data.dataset import TransitionDataset
from rkmpc.learning.io import load_any_model
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.learn import learn, save_learned
from rkmpc.learning.recipes import recipe_of_kind

#: The fields of every row, as the issue names them (and the kind, the steps in seconds, the starts).
ROW_FIELDS = {
    "model",
    "file",
    "horizon_steps",
    "horizon_s",
    "samples",
    "position_mean_m",
    "position_p95_m",
    "heading_mean_rad",
    "speed_mean_m_s",
}
HORIZONS = (1, 5, 10, 20)


@pytest.fixture(scope="module")
def files(tmp_path_factory, builtin_scenario, builtin_lap) -> dict[str, Path]:
    """The lap as a data set file, and model files of it: residual and paper (least squares), identified."""
    folder = tmp_path_factory.mktemp("evaluate")
    sc = builtin_scenario
    data = folder / "lap.npz"
    builtin_lap.save(data)
    for kind in ("residual", "paper"):  # least squares: no network, no torch
        learned = learn(
            recipe_of_kind(kind),
            builtin_lap,
            made_for=sc.provenance(),
            vehicle=sc.vehicle,
            model=KoopmanModel(None),
            augment=AugmentConfig(ratio=0.2),
        )
        save_learned(learned, folder / f"{kind}.npz")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train_to_file(builtin_lap, sc.provenance(), sc.vehicle, "identified", folder / "identified.json")
    return {
        "data": data,
        "residual": folder / "residual.npz",
        "identified": folder / "identified.json",
        "paper": folder / "paper.npz",
    }


@pytest.fixture(scope="module")
def evaluation(files, builtin_scenario, builtin_lap):
    models = {name: load_any_model(files[name]) for name in ("residual", "identified")}
    return evaluate(builtin_lap, models, builtin_scenario.vehicle, horizons=HORIZONS, source="lap.npz")


def test_one_row_per_model_and_horizon_the_kinematic_model_first(evaluation, builtin_lap):
    rows = evaluation.rows
    assert [(r.model, r.horizon_steps) for r in rows] == [
        (m, h) for m in ("kinematic", "residual", "identified") for h in HORIZONS
    ]
    assert {r.model: r.file for r in rows} == {
        "kinematic": None,
        "residual": "residual",
        "identified": "identified",
    }
    # Every row scores the same starts: those with 20 transitions ahead in one episode.
    assert {r.samples for r in rows} == {evaluation.starts} and 0 < evaluation.starts <= len(builtin_lap) - 19
    assert all(r.horizon_s == pytest.approx(r.horizon_steps * builtin_lap.dt) for r in rows)
    for r in rows:
        values = (r.position_mean_m, r.position_p95_m, r.heading_mean_rad, r.speed_mean_m_s)
        assert all(math.isfinite(v) and v >= 0 for v in values), r
        assert r.position_p95_m >= r.position_mean_m
    assert evaluation.truth == "the data as recorded"  # the simulator measured every field
    assert evaluation.models == {"residual": "residual", "identified": "identified"}
    assert evaluation.transitions == len(builtin_lap) and evaluation.source == "lap.npz"


def test_the_kinematic_models_errors_grow_with_the_horizon(evaluation):
    rows = [evaluation.row("kinematic", h) for h in HORIZONS]
    for field in ("position_mean_m", "position_p95_m", "heading_mean_rad"):
        values = [getattr(r, field) for r in rows]
        assert all(a < b for a, b in itertools.pairwise(values)), (field, values)
    # Driven by the commands alone, it misses the plant's servo lag and its speed loop.
    assert rows[0].position_mean_m > 1e-3 and rows[-1].position_mean_m > 10 * rows[0].position_mean_m


def test_the_learned_models_predict_the_lap_better_than_the_kinematic_one(evaluation):
    for h in HORIZONS:
        kinematic = evaluation.row("kinematic", h)
        for name in ("residual", "identified"):
            row = evaluation.row(name, h)
            assert row.position_mean_m < kinematic.position_mean_m, (name, h)
            assert row.heading_mean_rad < kinematic.heading_mean_rad, (name, h)
    # The identified model drives the bicycle with the recorded speed command, as the kinematic one.
    assert evaluation.row("identified", 5).speed_mean_m_s == evaluation.row("kinematic", 5).speed_mean_m_s


def test_the_json_and_the_markdown_hold_every_row(evaluation):
    record = evaluation.to_json()
    assert json.loads(json.dumps(record)) == record
    assert len(record["rows"]) == 12 and all(set(row) == ROW_FIELDS for row in record["rows"])
    text = evaluation.to_markdown()
    assert "| model | file | steps | s | position mean (m) | p95 (m) | vs kinematic |" in text
    table = [line for line in text.splitlines() if line.startswith("| ") and "---" not in line][1:]
    assert len(table) == 12 and all(line.startswith("| kinematic | - |") for line in table[:4])
    assert "| 1.00 / 1.00 |" in table[0]


def test_two_files_of_one_kind_are_told_apart_by_their_files(files, builtin_scenario, builtin_lap):
    model = load_any_model(files["identified"])
    models = {"a.json": model, "b.json": model}
    result = evaluate(builtin_lap, models, builtin_scenario.vehicle, horizons=(1,))
    rows = [(r.model, r.file) for r in result.rows]
    assert rows == [("kinematic", None), ("identified", "a.json"), ("identified", "b.json")]
    with pytest.raises(ParameterError, match=r"2 models of kind 'identified' \(a.json, b.json\)"):
        result.row("identified", 1)
    assert result.row("b.json", 1).file == "b.json"
    assert "| identified | a.json | 1 |" in result.to_markdown()
    assert result.label(result.rows[1]) == "identified (a.json)"


def test_a_paper_model_is_refused_with_the_reason(files, builtin_scenario, builtin_lap):
    paper = load_any_model(files["paper"])
    assert model_kind(paper) == "paper"
    with pytest.raises(ParameterError, match=r"a 'paper' model cannot be evaluated on recorded driving: "):
        evaluate(builtin_lap, {"paper": paper}, builtin_scenario.vehicle, horizons=(1,))
    with pytest.raises(ParameterError, match=r"correction dU on the LMPC's plan"):
        evaluate(builtin_lap, {"paper": paper}, builtin_scenario.vehicle, horizons=(1,))


@pytest.mark.parametrize("horizons", [(0,), (1, 500), (MAX_HORIZON + 1,), ()])
def test_a_horizon_out_of_range_is_refused(builtin_scenario, builtin_lap, horizons):
    with pytest.raises(ParameterError, match=rf"horizons must be integers from 1 to {MAX_HORIZON}"):
        evaluate(builtin_lap, {}, builtin_scenario.vehicle, horizons=horizons)


def test_data_shorter_than_the_horizon_are_refused(builtin_scenario, builtin_lap):
    d = builtin_lap
    # Ten transitions in two episodes of five: no 20 (nor 6) in one episode.
    short = TransitionDataset(d.obs[:10], d.command[:10], d.next_obs[:10], d.dt, np.repeat([0, 1], 5))
    with pytest.raises(ParameterError, match="no 6 consecutive transitions"):
        evaluate(short, {}, builtin_scenario.vehicle, horizons=(6,))
    with pytest.raises(ParameterError, match="no 20 consecutive transitions"):
        evaluate(short, {}, builtin_scenario.vehicle, horizons=(20,))


# ---------------------------------------------------------------------------- rkmpc's slip drift


def _sliding_straight(beta: float, speed: float = 2.0, n: int = 40) -> TransitionDataset:
    """A car driving straight at ``speed`` (m/s) with its heading 0.3 rad and its velocity ``beta``
    (rad) off its heading: it travels along ``0.3 + beta`` without turning."""
    dt, yaw = 0.05, 0.3
    t = np.arange(n + 1) * dt
    obs = np.zeros((n + 1, 7))
    obs[:, 0], obs[:, 1] = speed * t * np.cos(yaw + beta), speed * t * np.sin(yaw + beta)
    obs[:, 2], obs[:, 3], obs[:, 5] = yaw, speed, beta
    command = np.tile([speed, 0.0], (n, 1))
    return TransitionDataset(obs[:-1], command, obs[1:], dt, np.zeros(n, dtype=int))


def test_the_drift_rows_predict_a_car_sliding_at_a_fixed_angle(builtin_scenario):
    data = _sliding_straight(0.05)
    settings = RKMPCConfig(slip_drift=True)
    result = evaluate(data, {}, builtin_scenario.vehicle, horizons=(1, 10), rkmpc=settings)
    assert [(r.model, r.horizon_steps) for r in result.rows] == [
        ("kinematic", 1),
        ("kinematic", 10),
        ("kinematic+drift", 1),
        ("kinematic+drift", 10),
    ]
    # The kinematic model drives along the heading: 0.05 rad off, sin(0.05) of the distance.
    assert result.row("kinematic", 10).position_mean_m == pytest.approx(2.0 * 0.5 * 2 * math.sin(0.025))
    # With the slip held, the prediction is where the car went; the heading is the kinematic model's.
    assert result.row("kinematic+drift", 10).position_mean_m < 1e-12
    assert result.row("kinematic+drift", 10).heading_mean_rad == result.row("kinematic", 10).heading_mean_rad
    assert "| kinematic+drift | - | 10 | 0.50 | 0.0000 |" in result.to_markdown()


@pytest.mark.parametrize(
    "settings",
    [RKMPCConfig(slip_drift=False), RKMPCConfig(slip_drift=True, slip_velocity_limit=0.1)],
    ids=["off", "faded"],
)
def test_without_the_drift_or_beyond_its_limit_no_drift_is_predicted(builtin_scenario, settings):
    # 2 m/s at 0.05 rad slide sideways at 0.1 m/s: the limit 0.1 fades all of it.
    data = _sliding_straight(0.05)
    result = evaluate(data, {}, builtin_scenario.vehicle, horizons=(10,), rkmpc=settings)
    drift = [r for r in result.rows if r.model == "kinematic+drift"]
    if not settings.slip_drift:
        assert drift == []
    else:
        assert drift[0].position_mean_m == result.row("kinematic", 10).position_mean_m > 0.04


def test_a_residual_model_gets_its_drift_row_and_an_identified_one_none(files, builtin_scenario, builtin_lap):
    models = {"r.npz": load_any_model(files["residual"]), "i.json": load_any_model(files["identified"])}
    result = evaluate(
        builtin_lap, models, builtin_scenario.vehicle, horizons=(5,), rkmpc=RKMPCConfig(slip_drift=True)
    )
    assert [r.model for r in result.rows] == [
        "kinematic",
        "kinematic+drift",
        "residual",
        "residual+drift",
        "identified",
    ]
    # The lap's slip moves the drift rows off their models' rows; heading and speed are the models'.
    for kind in ("kinematic", "residual"):
        plain, drift = result.row(kind, 5), result.row(f"{kind}+drift", 5)
        assert drift.position_mean_m != plain.position_mean_m
        assert drift.heading_mean_rad == plain.heading_mean_rad
        assert drift.speed_mean_m_s == plain.speed_mean_m_s
    # A file names two rows (its model's and its drift's): the kind picks one.
    message = r"2 rows of 'r.npz' \(residual, residual\+drift\): name the kind"
    with pytest.raises(ParameterError, match=message):
        result.row("r.npz", 5)
    assert result.row("r.npz", 5, kind="residual+drift").model == "residual+drift"
    assert result.label(result.rows[3]) == "residual+drift"
    assert result.figure() is not None


def test_evaluate_refuses_settings_that_are_not_rkmpcs(builtin_scenario):
    data, vehicle = _sliding_straight(0.0), builtin_scenario.vehicle
    with pytest.raises(ParameterError, match="rkmpc must be an RKMPCConfig, got dict"):
        evaluate(data, {}, vehicle, horizons=(1,), rkmpc={"slip_drift": True})


# ---------------------------------------------------------------------------- the command line


def test_rkmpc_evaluate_writes_the_json_the_markdown_and_the_plot(files, tmp_path, capsys):
    out = tmp_path / "eval"
    argv = ["evaluate", "--data", str(files["data"]), "--model", str(files["residual"])]
    argv += ["--model", str(files["identified"]), "--horizons", "1,5", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    record = json.loads((out / "evaluation.json").read_text())
    rows = record["rows"]
    # Models are named by their kind and carry their file's name.
    # The default car (the f1tenth preset) holds rkmpc's slip drift: its rows follow their models'.
    assert [(r["model"], r["file"], r["horizon_steps"]) for r in rows] == [
        ("kinematic", None, 1),
        ("kinematic", None, 5),
        ("kinematic+drift", None, 1),
        ("kinematic+drift", None, 5),
        ("residual", "residual.npz", 1),
        ("residual", "residual.npz", 5),
        ("residual+drift", "residual.npz", 1),
        ("residual+drift", "residual.npz", 5),
        ("identified", "identified.json", 1),
        ("identified", "identified.json", 5),
    ]
    assert all(set(row) == ROW_FIELDS for row in rows)
    assert record["source"] == str(files["data"]) and record["truth"] == "the data as recorded"
    text = (out / "evaluation.md").read_text()
    assert text in printed and "| residual | residual.npz | 5 |" in text
    assert (out / "evaluation.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_rkmpc_evaluate_refuses_a_paper_model_and_writes_nothing(files, tmp_path, capsys):
    out = tmp_path / "eval"
    argv = ["evaluate", "--data", str(files["data"]), "--model", str(files["paper"]), "--out", str(out)]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert "a 'paper' model cannot be evaluated on recorded driving" in error
    assert not out.exists()


@pytest.mark.parametrize("horizons", ["0", "1,500"])
def test_rkmpc_evaluate_refuses_a_horizon_out_of_range(files, tmp_path, capsys, horizons):
    out = tmp_path / "eval"
    argv = ["evaluate", "--data", str(files["data"]), "--model", str(files["identified"])]
    assert main([*argv, "--horizons", horizons, "--out", str(out)]) == 2
    assert f"horizons must be integers from 1 to {MAX_HORIZON}" in capsys.readouterr().err
    assert not out.exists()


# ---------------------------------------------------------------------------- slow: trained models


@pytest.mark.slow
def test_a_residual_model_trained_two_epochs_predicts_better_than_the_kinematic_one(
    files, tmp_path, builtin_scenario, builtin_lap
):
    """Measured: position at 1 step 0.0017 m against 0.0055 m, at 20 steps 0.048 m against 0.37 m."""
    sc = builtin_scenario
    path = tmp_path / "residual.npz"
    train_to_file(builtin_lap, sc.provenance(), sc.vehicle, "residual", path, epochs=2)
    models = {"residual": load_any_model(path), "identified": load_any_model(files["identified"])}
    result = evaluate(builtin_lap, models, sc.vehicle, horizons=HORIZONS)
    for h in HORIZONS:
        kinematic, residual = result.row("kinematic", h), result.row("residual", h)
        assert residual.position_mean_m < 0.5 * kinematic.position_mean_m, h
        assert residual.heading_mean_rad < 0.5 * kinematic.heading_mean_rad, h
        assert residual.speed_mean_m_s < kinematic.speed_mean_m_s, h


@pytest.mark.slow
def test_on_data_without_a_wheel_angle_the_truth_is_the_estimators(builtin_scenario):
    from rkmpc.sim.collect import collect
    from rkmpc.sim.scenario import Scenario

    car = builtin_scenario.car.with_sensors("f1tenth-real")
    scenario = Scenario.from_car(car, "builtin")
    data = collect(scenario, laps=1)
    assert np.isnan(data.obs[:, 6]).all()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        learned = learn(
            recipe_of_kind("identified"), data, made_for=scenario.provenance(), vehicle=car.vehicle
        )
    result = evaluate(data, {"identified": learned.model}, car.vehicle, horizons=(1, 10))
    assert result.truth == "the state estimator's smoothed estimates"
    rows = [result.row(m, h) for m in ("kinematic", "identified") for h in (1, 10)]
    assert all(math.isfinite(r.position_mean_m) and math.isfinite(r.heading_mean_rad) for r in rows)
    assert result.row("kinematic", 10).position_mean_m > result.row("kinematic", 1).position_mean_m


@pytest.mark.slow
def test_a_residual_model_trained_on_ds2_predicts_ds3_better_than_the_kinematic_model(tmp_path, capsys):
    """Train on one real run, evaluate on the other, through the command line (as a user would).

    ``rkmpc collect --from-csv DS2 --csv-spec friction-maps``, ``rkmpc train --kind residual``
    (the recipe's 100 epochs, seed 0), ``rkmpc evaluate --from-csv DS3``. Measured 2026-11-27 (2,411
    starts, truth the smoothed estimates): position 1 step 0.0052 m vs kinematic 0.0061 m (0.85x);
    5 steps 0.026 vs 0.032 m (0.82x); 10 steps 0.058 vs 0.062 m (0.94x); 20 steps 0.142 vs 0.115 m
    (1.23x; 1.05x and 1.10x with seeds 1 and 2); heading at 5 steps 0.014 rad vs 0.058 rad. With
    rkmpc's slip drift (the preset's, ``residual+drift``): 0.24x at 1 step, 0.41x at 5.
    """
    if not (REAL_LOGS / "DS2").is_dir() or not (REAL_LOGS / "DS3").is_dir():
        pytest.skip("../shared/real/f1tenth-car (the real car's logs) is not present")
    data, model, out = tmp_path / "ds2.npz", tmp_path / "residual.npz", tmp_path / "eval"
    spec = ["--csv-spec", "friction-maps"]
    assert main(["collect", "--from-csv", str(REAL_LOGS / "DS2"), *spec, "--out", str(data)]) == 0
    assert main(["train", "--data", str(data), "--kind", "residual", "--out", str(model)]) == 0
    argv = ["evaluate", "--from-csv", str(REAL_LOGS / "DS3"), *spec, "--model", str(model)]
    assert main([*argv, "--horizons", "1,5,10,20", "--out", str(out)]) == 0
    capsys.readouterr()
    record = json.loads((out / "evaluation.json").read_text())
    assert record["truth"] == "the state estimator's smoothed estimates"
    rows = {(r["model"], r["horizon_steps"]): r for r in record["rows"]}
    assert rows[("residual", 1)]["file"] == "residual.npz"
    residual5, kinematic5 = rows[("residual", 5)], rows[("kinematic", 5)]
    assert residual5["heading_mean_rad"] < kinematic5["heading_mean_rad"]
    residual1, kinematic1 = rows[("residual", 1)], rows[("kinematic", 1)]
    assert residual1["position_mean_m"] <= 1.0 * kinematic1["position_mean_m"]
    # What rkmpc predicts (the estimated slip held) halves the kinematic model's error at 5 steps.
    assert rows[("residual+drift", 5)]["position_mean_m"] < 0.6 * kinematic5["position_mean_m"]


def test_the_exact_inputs_predict_what_a_perfect_input_correction_would(evaluation):
    # The kinematic model driven by each recorded step's own U_p: its heading is exact, its position
    # misses only the sideways motion the bicycle cannot make.
    bound = {r.horizon_steps: r for r in evaluation.exact_inputs}
    assert sorted(bound) == list(HORIZONS) and {r.model for r in bound.values()} == {"exact-inputs"}
    assert bound[1].heading_mean_rad < 1e-12
    for h in HORIZONS:
        assert bound[h].heading_mean_rad < 1e-9
        assert bound[h].position_mean_m < 1.05 * evaluation.row("residual", h).position_mean_m
        assert bound[h].position_mean_m < evaluation.row("kinematic", h).position_mean_m
    # What the bound still misses grows with the horizon: the sideways motion the bicycle cannot make.
    assert bound[HORIZONS[-1]].position_mean_m > bound[HORIZONS[0]].position_mean_m > 0
    record = evaluation.to_json()
    assert [row["horizon_steps"] for row in record["exact_inputs"]] == list(HORIZONS)
    assert "Exact inputs (the kinematic model driven by the inputs" in evaluation.to_markdown()
