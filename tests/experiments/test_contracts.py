"""Where data meet a training and a model meets a car: mismatches refused, or allowed and recorded."""

from __future__ import annotations

import json
import warnings
from dataclasses import replace

import pytest

from rkmpc.cli import main
from rkmpc.core.errors import ContractError, ContractWarning
from rkmpc.experiments.compare import CompareConfig, compare
from rkmpc.experiments.models import ModelPlan, learn_models
from rkmpc.learning.contract import CONTRACT_KEY, contract_of
from rkmpc.learning.data.augmentation import AugmentConfig
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.pipeline import TrainConfig, train_model
from rkmpc.sim.build import build_controller, check_model
from rkmpc.sim.scenario import load_scenario


def _config(dt: float | None = None) -> TrainConfig:
    return TrainConfig(kind="paper", augment=AugmentConfig(ratio=0.2), model=KoopmanModel(None), dt=dt)


def _with_contract(model: KoopmanModel, path, **changes) -> str:
    """Save ``model`` as if it had been trained with ``changes`` to its contract; returns the path."""
    contract = replace(contract_of(model.metadata_), **changes)
    model.save(path, metadata={**model.metadata_, CONTRACT_KEY: contract.to_json()})
    return str(path)


# ---------------------------------------------------------------------------- training


def test_a_model_records_what_it_was_trained_with(small_paper_model, builtin_lap):
    contract = contract_of(small_paper_model.metadata_)
    assert contract.recorded
    assert (contract.vehicle, contract.plant, contract.dt, contract.wheelbase, contract.scale) == (
        "f1tenth",
        "f1tenth",
        0.05,
        0.307,
        1.0,
    )
    assert contract.features == ("x", "y", "yaw")
    assert contract.state_min == tuple(small_paper_model.x_min_)
    assert contract.state_max == tuple(small_paper_model.x_max_)
    assert small_paper_model.metadata_["contract_warnings"] == []
    assert builtin_lap.contract.vehicle == "f1tenth" and builtin_lap.contract.scale == 1.0


def test_training_at_another_period_than_the_data_is_refused(builtin_lap):
    with pytest.raises(
        ContractError, match=r"lap\.npz was recorded with dt = 0\.05 s; this run uses dt = 0\.01 s"
    ):
        train_model(builtin_lap, 0.307, _config(dt=0.01), source="lap.npz")


@pytest.mark.parametrize(
    ("wheelbase", "vehicle", "field"), [(2.579, None, "wheelbase"), (0.307, "fullsize", "vehicle")]
)
def test_training_for_another_car_is_refused(builtin_lap, wheelbase, vehicle, field):
    with pytest.raises(ContractError, match=f"with {field} = "):
        train_model(builtin_lap, wheelbase, _config(), vehicle=vehicle)


def test_an_allowed_training_mismatch_is_kept_in_the_model(builtin_lap, tmp_path):
    with pytest.warns(ContractWarning, match="dt"):
        model, _ = train_model(builtin_lap, 0.307, _config(dt=0.01), allow_mismatch=True)
    (warning,) = model.metadata_["contract_warnings"]
    assert "dt = 0.05 s; this run uses dt = 0.01 s (allowed)" in warning
    # The model records the period it really learned, so it is refused at 0.01 s later on.
    model.save(tmp_path / "m.npz", metadata=model.metadata_)
    assert contract_of(KoopmanModel.load(tmp_path / "m.npz").metadata_).dt == 0.05


def test_old_data_train_with_one_warning(builtin_lap):
    old = replace(builtin_lap, metadata={})
    assert not old.contract.recorded
    with pytest.warns(ContractWarning, match="made before contracts") as caught:
        model, _ = train_model(old, 0.307, _config(), vehicle="f1tenth")
    assert len([w for w in caught if issubclass(w.category, ContractWarning)]) == 1
    assert contract_of(model.metadata_).vehicle == "f1tenth"


# ---------------------------------------------------------------------------- a model meets a car


def test_build_controller_refuses_a_model_of_another_period_or_car(
    builtin_scenario, small_paper_model, tmp_path
):
    # make_controller builds what it is given; the scenario's build_controller checks the model.
    sc = builtin_scenario
    fast = KoopmanModel.load(_with_contract(small_paper_model, tmp_path / "fast.npz", dt=0.01))
    with pytest.raises(ContractError, match=r"trained with dt = 0\.01 s; this run uses dt = 0\.05 s"):
        build_controller("rkmpc-paper", sc, fast)
    with pytest.warns(UserWarning, match="made at 1:10"):
        full = load_scenario("builtin", vehicle="fullsize")
    with pytest.raises(ContractError, match="vehicle = 'f1tenth'; this run uses vehicle = 'fullsize'"):
        build_controller("rkmpc-paper", full, small_paper_model)
    with pytest.raises(ContractError, match="plant = 'f1tenth'; this run uses plant = 'gym'"):
        build_controller("rkmpc-paper", load_scenario("builtin", car="gym"), small_paper_model)
    with pytest.warns(ContractWarning, match="dt"):
        ctrl = build_controller("rkmpc-paper", sc, fast, allow_mismatch=True)
    assert ctrl.model is fast
    with pytest.raises(ContractError, match=r"fast\.npz was trained with dt = 0\.01 s"):
        check_model(fast, sc, source="fast.npz")
    with pytest.warns(ContractWarning, match="dt"):
        (warning,) = check_model(fast, sc, source="fast.npz", allow_mismatch=True)
    assert "(allowed)" in warning


def test_build_controller_takes_an_old_model_with_a_warning(builtin_scenario, small_paper_model, tmp_path):
    old = {k: v for k, v in small_paper_model.metadata_.items() if k != CONTRACT_KEY}
    small_paper_model.save(tmp_path / "old.npz", metadata=old)
    model = KoopmanModel.load(tmp_path / "old.npz")
    with pytest.warns(ContractWarning, match="made before contracts"):
        ctrl = build_controller("rkmpc-paper", builtin_scenario, model)
    assert ctrl.model is model
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        build_controller("rkmpc-paper", builtin_scenario, small_paper_model)


def test_a_model_file_of_another_track_scale_is_refused_before_driving(
    builtin_scenario, small_paper_model, tmp_path
):
    path = _with_contract(small_paper_model, tmp_path / "monza.npz", scale=0.1)
    plan = ModelPlan(controllers=("rkmpc-paper",), model_files={"rkmpc-paper": path})
    with pytest.raises(ContractError) as info:
        learn_models(builtin_scenario, plan)
    assert "monza.npz was trained with scale = 0.1; this run uses scale = 1" in str(info.value)
    with pytest.warns(ContractWarning, match="scale"):
        models, training = learn_models(builtin_scenario, replace(plan, allow_mismatch=True))
    assert contract_of(models["rkmpc-paper"].metadata_).scale == 0.1
    (warning,) = training.models["rkmpc-paper"].contract_warnings
    assert "scale = 0.1" in warning and "(allowed)" in warning
    # The model is still of another scale: only a run that allows the mismatch drives it.
    with pytest.raises(ContractError, match=r"scale = 0\.1; this run uses scale = 1"):
        build_controller("rkmpc-paper", builtin_scenario, models["rkmpc-paper"])


def test_an_allowed_mismatch_is_recorded_in_the_results_and_the_log(small_paper_model, tmp_path):
    path = _with_contract(small_paper_model, tmp_path / "monza.npz", scale=0.1)
    config = CompareConfig(
        track="builtin",
        controllers=("rkmpc-paper",),
        model_files=(("rkmpc-paper", path),),
        allow_mismatch=True,
    )
    logs: dict = {}
    with pytest.warns(ContractWarning):
        result = compare(config, logs=logs)
    record = result.to_json()
    warning = record["training"]["rkmpc-paper"]["contract_warnings"][0]
    assert "monza.npz was trained with scale = 0.1" in warning
    assert record["config"]["allow_mismatch"] is True
    assert logs["rkmpc-paper"].metadata["contract_warnings"] == [warning]
    assert result.controllers["rkmpc-paper"].outcome == "completed"


# ---------------------------------------------------------------------------- the command line


def test_cli_train_refuses_data_of_another_period_unless_allowed(builtin_lap, tmp_path, capsys):
    builtin_lap.save(tmp_path / "lap.npz")
    args = ["train", "--data", str(tmp_path / "lap.npz"), "--kind", "identified", "--dt", "0.01"]
    assert main([*args, "--out", str(tmp_path / "id.json")]) == 2
    err = capsys.readouterr().err
    assert "lap.npz was recorded with dt = 0.05 s; this run uses dt = 0.01 s" in err
    assert err.rstrip().endswith("(give --allow-mismatch to use it anyway)") and "allow_mismatch=" not in err
    assert not (tmp_path / "id.json").exists()
    with pytest.warns(ContractWarning):
        assert main([*args, "--allow-mismatch", "--out", str(tmp_path / "id.json")]) == 0
    metadata = json.loads((tmp_path / "id.json").read_text())["metadata"]
    assert metadata[CONTRACT_KEY]["dt"] == 0.05
    assert "(allowed)" in metadata["contract_warnings"][0]


def test_an_identified_model_file_is_checked_against_the_car_it_drives(
    builtin_lap, builtin_scenario, tmp_path
):
    """lmpc-id's JSON keeps its contract when read back: a model of the f1tenth plant on the zoo's gym
    car, or at another period, is refused as a Koopman model is (issue 27: it was never checked)."""
    from rkmpc.config.loader import load_preset
    from rkmpc.experiments.training import train_to_file
    from rkmpc.learning.contract import Provenance
    from rkmpc.learning.io import load_model
    from rkmpc.sim.scenario import Scenario

    vehicle = builtin_scenario.vehicle
    path = tmp_path / "lmpc-id.json"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train_to_file(
            builtin_lap,
            Provenance(vehicle="f1tenth", dt=0.05, wheelbase=vehicle.wheelbase),
            vehicle,
            "identified",
            path,
        )
    model = load_model(path, "identified")
    assert contract_of(model.metadata_).plant == "f1tenth"
    assert check_model(model, builtin_scenario, source="lmpc-id.json") == ()
    gym = Scenario.from_car(load_preset("f1tenth").with_zoo_car("gym"), "builtin")
    with pytest.raises(
        ContractError, match=r"lmpc-id.json was trained with plant = 'f1tenth'; this run uses plant = 'gym'"
    ):
        check_model(model, gym, source="lmpc-id.json")
    with pytest.raises(ContractError, match=r"dt = 0\.05 s; this run uses dt = 0\.1 s"):
        build_controller("lmpc-id", replace(builtin_scenario, dt=0.1), model)
