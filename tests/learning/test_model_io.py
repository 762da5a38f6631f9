"""Model files by kind: identified-model JSON round trip and errors, load_model's kind and feature checks."""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import asdict

import numpy as np
import pytest

from rkmpc.core.errors import InputFileError, ParameterError
from rkmpc.core.jsonutil import to_json_ready
from rkmpc.learning.identification import IdentifiedModel
from rkmpc.learning.io import load_identified, load_model, save_identified
from rkmpc.learning.koopman.model import KoopmanModel
from rkmpc.learning.recipes import KoopmanLearner, model_kinds, recipe_of_kind

KOOPMAN_KINDS = [k for k in model_kinds() if isinstance(recipe_of_kind(k).learner, KoopmanLearner)]


def _identified() -> IdentifiedModel:
    return IdentifiedModel(
        servo_time_constant=0.153,
        understeer_gradient=0.0042,
        servo_fit_r2=0.97,
        understeer_fit_r2=0.81,
        n_samples=1099,
        servo_structure="delay-lag-rate",
        servo_delay=0.032,
        servo_rate_limit=3.1,
        warnings=("understeer: the fit gives K = 0.3 s^2/m, beyond the plausible range; held at 0.1",),
        status="identified",
        status_reason="delay-lag-rate + K predicts the held-out yaw rate with 0.03 rad/s RMS, nominal 0.2",
        fitted_on="yaw_rate",
        folds=5,
        heldout_rmse=0.03,
        nominal_rmse=0.2,
        heldout_r2=0.99,
        heldout_candidates=(("nominal", 0.2), ("delay-lag-rate + K", 0.03)),
    )


def _payload(**changes) -> dict:
    model = json.loads(json.dumps(to_json_ready(_identified())))
    payload = {"format": "rkmpc-identified", "version": 4, "model": model, "metadata": {}}
    payload.update(changes)
    return payload


#: The fields of a version 2 file.
_V2 = (
    "servo_time_constant",
    "understeer_gradient",
    "servo_fit_r2",
    "understeer_fit_r2",
    "n_samples",
    "servo_structure",
    "servo_delay",
    "servo_rate_limit",
    "warnings",
)


def _write(path, payload) -> None:
    path.write_text(json.dumps(payload))


def _koopman(kind: str, features=None, seed: int = 0, **extra) -> KoopmanModel:
    """A small fitted model with the sizes of ``kind``'s recipe, its metadata set as the pipeline does."""
    recipe = recipe_of_kind(kind)
    nx = len(recipe.state.names)
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(40, nx))
    U = rng.normal(size=(40, 2))
    X_next = 0.9 * X + 0.1 * U @ rng.normal(size=(2, nx))
    model = KoopmanModel(None).fit(X, U, X_next)
    model.metadata_ = {"kind": kind, **extra}
    if features is not None:
        model.metadata_["features"] = features
    return model


def _save(model: KoopmanModel, path) -> None:
    model.save(path, metadata=model.metadata_)


# ---------------------------------------------------------------------------- identified models


def test_identified_round_trip(tmp_path):
    path = tmp_path / "model.json"
    model = _identified()
    save_identified(model, path, metadata={"track": "builtin", "dt": np.float64(0.05), "laps": np.int64(2)})
    assert load_identified(path) == model
    # The file is plain JSON with the format tag, the model's fields and the metadata.
    payload = json.loads(path.read_text())
    assert payload["format"] == "rkmpc-identified"
    assert payload["version"] == 4
    assert payload["model"] == {
        **asdict(model),
        "warnings": list(model.warnings),
        "wheel_heldout_rmse": None,  # not measured: null in the file, NaN in the model
        "wheel_nominal_rmse": None,
        "heldout_candidates": [["nominal", 0.2], ["delay-lag-rate + K", 0.03]],
    }
    assert payload["metadata"] == {"track": "builtin", "dt": 0.05, "laps": 2}
    # Written atomically: nothing but the file is left in the folder.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"]


def test_identified_round_trip_of_a_nominal_fallback_without_fits(tmp_path):
    path = tmp_path / "model.json"
    model = IdentifiedModel(0.158, 0.0, math.nan, math.nan, 40, "nominal", warnings=("servo: ...",))
    save_identified(model, path)
    payload = json.loads(path.read_text())  # strict JSON: no NaN in the file
    assert payload["model"]["servo_fit_r2"] is None and payload["model"]["servo_rate_limit"] is None
    loaded = load_identified(path)
    assert math.isnan(loaded.servo_fit_r2) and math.isnan(loaded.understeer_fit_r2)
    assert (loaded.servo_structure, loaded.servo_rate_limit, loaded.warnings) == (
        "nominal",
        None,
        ("servo: ...",),
    )


def test_a_version_1_file_loads_as_a_lag_without_delay_rate_limit_or_warnings(tmp_path):
    path = tmp_path / "old.json"
    v1 = {
        "servo_time_constant": 0.153,
        "understeer_gradient": 0.0042,
        "servo_fit_r2": 0.97,
        "understeer_fit_r2": 0.81,
        "n_samples": 1099,
    }
    _write(path, {"format": "rkmpc-identified", "version": 1, "model": v1, "metadata": {}})
    model = load_identified(path)
    assert model == IdentifiedModel(**v1)
    assert (model.servo_structure, model.servo_delay, model.servo_rate_limit, model.warnings) == (
        "lag",
        0.0,
        None,
        (),
    )


def test_a_version_2_file_loads_unchecked(tmp_path):
    path = tmp_path / "v2.json"
    v2 = {k: v for k, v in _payload()["model"].items() if k in _V2}
    _write(path, {"format": "rkmpc-identified", "version": 2, "model": v2, "metadata": {}})
    model = load_identified(path)
    assert model == IdentifiedModel(**v2)
    assert (model.servo_structure, model.servo_delay, model.servo_rate_limit) == (
        "delay-lag-rate",
        0.032,
        3.1,
    )
    assert (model.status, model.status_reason, model.fitted_on, model.folds) == ("unchecked", "", None, 0)
    assert math.isnan(model.heldout_rmse) and math.isnan(model.error_ratio)


def test_a_version_2_file_with_version_3_fields_is_refused(tmp_path):
    path = tmp_path / "model.json"
    _write(path, _payload(version=2))
    with pytest.raises(InputFileError, match=r"\[model\]: expected the fields .* \(version 2\)"):
        load_identified(path)


def test_a_version_1_file_with_version_2_fields_is_refused(tmp_path):
    path = tmp_path / "model.json"
    _write(path, _payload(version=1, model={k: v for k, v in _payload()["model"].items() if k in _V2}))
    with pytest.raises(InputFileError, match=r"\[model\]: expected the fields .* \(version 1\)") as info:
        load_identified(path)
    assert info.value.field == "model"


@pytest.mark.parametrize("version", [5, 0, "2", None, True])
def test_an_unknown_version_is_refused(tmp_path, version):
    path = tmp_path / "model.json"
    _write(path, _payload(version=version))
    with pytest.raises(InputFileError, match=r"model\.json \[version\]: unknown version") as info:
        load_identified(path)
    assert info.value.field == "version"


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("servo_structure", "quantum"),
        ("servo_structure", None),
        ("servo_delay", -0.01),
        ("servo_delay", "20 ms"),
        ("servo_rate_limit", 0.0),
        ("servo_rate_limit", float("inf")),
        ("warnings", "one long warning"),
        ("warnings", [1, 2]),
        ("n_samples", 10.5),
        ("servo_fit_r2", "good"),
        ("status", "great"),
        ("status", None),
        ("fitted_on", "gps"),
        ("folds", -1),
        ("heldout_rmse", "small"),
        ("heldout_candidates", [["nominal"]]),
        ("heldout_candidates", [[1, 0.2]]),
        ("heldout_candidates", "nominal"),
        ("status_reason", 3),
    ],
)
def test_bad_fields_name_the_field(tmp_path, field, value):
    path = tmp_path / "model.json"
    _write(path, _payload(model=_model_fields(**{field: value})))
    with pytest.raises(InputFileError, match=rf"model\.json \[model\]: IdentifiedModel\.{field}") as info:
        load_identified(path)
    assert info.value.field == "model"


def test_a_model_marked_nominal_must_be_the_nominal_one(tmp_path):
    path = tmp_path / "model.json"
    _write(path, _payload(model=_model_fields(status="nominal")))  # a delay-lag-rate servo and K != 0
    with pytest.raises(InputFileError, match=r"IdentifiedModel\.status is 'nominal' but the model is not"):
        load_identified(path)
    nominal = _model_fields(
        status="nominal",
        servo_structure="nominal",
        servo_delay=0.0,
        servo_rate_limit=None,
        understeer_gradient=0.0,
    )
    _write(path, _payload(model=nominal))
    assert load_identified(path).status == "nominal"


def test_identified_save_overwrites_and_defaults_metadata(tmp_path):
    path = tmp_path / "sub" / "model.json"
    save_identified(_identified(), path, metadata={"a": 1})
    other = IdentifiedModel(0.2, -0.001, 0.5, 0.4, 10)
    save_identified(other, path)
    assert load_identified(path) == other
    assert json.loads(path.read_text())["metadata"] == {}
    assert sorted(p.name for p in path.parent.iterdir()) == ["model.json"]


def test_identified_missing_file(tmp_path):
    path = tmp_path / "absent.json"
    with pytest.raises(InputFileError, match=r"absent\.json.*file not found") as info:
        load_identified(path)
    assert info.value.path == path


@pytest.mark.parametrize("content", ["{not json", "", "\x00\x01"])
def test_identified_not_json(tmp_path, content):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(InputFileError, match=r"bad\.json.*not an identified-model JSON file") as info:
        load_identified(path)
    assert info.value.path == path


def test_identified_binary_file(tmp_path):
    path = tmp_path / "model.npz"
    _save(_koopman("residual"), path)
    with pytest.raises(InputFileError, match=r"model\.npz"):
        load_identified(path)


@pytest.mark.parametrize(
    "payload",
    [
        _payload(format="rkmpc-koopman"),
        {k: v for k, v in _payload().items() if k != "format"},
        [1, 2, 3],
        "rkmpc-identified",
    ],
)
def test_identified_wrong_format(tmp_path, payload):
    path = tmp_path / "model.json"
    _write(path, payload)
    with pytest.raises(InputFileError, match=r"model.json \[format\]: not an rkmpc-identified file") as info:
        load_identified(path)
    assert info.value.field == "format"
    assert info.value.path == path


def _model_fields(**changes) -> dict:
    data = dict(_payload()["model"])
    data.update(changes)
    return data


@pytest.mark.parametrize(
    "model",
    [
        {k: v for k, v in asdict(_identified()).items() if k != "understeer_gradient"},
        _model_fields(extra_field=1.0),
        {},
        None,
        [0.1, 0.2],
    ],
    ids=["missing", "extra", "empty", "null", "list"],
)
def test_identified_missing_or_extra_fields(tmp_path, model):
    path = tmp_path / "model.json"
    _write(path, _payload(model=model))
    with pytest.raises(InputFileError, match=r"model.json \[model\]: expected the fields") as info:
        load_identified(path)
    assert info.value.field == "model"
    assert "servo_time_constant" in str(info.value)


def test_identified_without_model_entry(tmp_path):
    path = tmp_path / "model.json"
    _write(path, {k: v for k, v in _payload().items() if k != "model"})
    with pytest.raises(InputFileError, match=r"\[model\]") as info:
        load_identified(path)
    assert info.value.field == "model"


@pytest.mark.parametrize("tau", [0.0, -0.1, None, "fast"])
def test_identified_non_positive_servo_time_constant(tmp_path, tau):
    path = tmp_path / "model.json"
    _write(path, _payload(model=_model_fields(servo_time_constant=tau)))
    with pytest.raises(InputFileError, match=r"model.json \[model\]") as info:
        load_identified(path)
    assert info.value.field == "model"
    if tau is not None and not isinstance(tau, str):
        assert "servo_time_constant" in info.value.problem


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("understeer_gradient", -5.0),
        ("understeer_gradient", 1e6),
        ("servo_time_constant", 1.4e7),
        ("servo_time_constant", 1e-6),
        ("servo_delay", 3.0),
        ("servo_rate_limit", 1e9),
    ],
)
def test_hand_edited_implausible_parameters_are_refused(tmp_path, field, value):
    # Issue 13: K = -5 and K = 1e6 were accepted.
    path = tmp_path / "model.json"
    _write(path, _payload(model=_model_fields(**{field: value})))
    with pytest.raises(
        InputFileError, match=rf"model\.json \[model\]: IdentifiedModel\.{field} must be a number in"
    ) as info:
        load_identified(path)
    assert "plausible" in info.value.problem


def test_identified_non_finite_understeer_gradient(tmp_path):
    path = tmp_path / "model.json"
    path.write_text(json.dumps(_payload(model=_model_fields(understeer_gradient=float("inf")))))
    with pytest.raises(InputFileError, match="understeer_gradient") as info:
        load_identified(path)
    assert info.value.field == "model"


# ---------------------------------------------------------------------------- load_model by kind


def test_load_model_identified(tmp_path):
    path = tmp_path / "id.json"
    save_identified(_identified(), path)
    loaded = load_model(path, "identified")
    assert isinstance(loaded, IdentifiedModel)
    assert loaded == _identified()


def test_load_model_identified_refuses_a_koopman_file(tmp_path):
    path = tmp_path / "model.npz"
    _save(_koopman("residual", features=list(recipe_of_kind("residual").state.names)), path)
    with pytest.raises(InputFileError, match=r"model\.npz"):
        load_model(path, "identified")


@pytest.mark.parametrize("kind", KOOPMAN_KINDS)
def test_load_model_koopman_kinds(tmp_path, kind):
    names = list(recipe_of_kind(kind).state.names)
    model = _koopman(kind, features=names, data_hash="abc")
    path = tmp_path / f"{kind}.npz"
    _save(model, path)
    loaded = load_model(path, kind)
    assert isinstance(loaded, KoopmanModel)
    assert loaded.metadata_["kind"] == kind
    assert loaded.metadata_["features"] == names
    assert loaded.metadata_["data_hash"] == "abc"
    np.testing.assert_array_equal(loaded.A_, model.A_)
    np.testing.assert_array_equal(loaded.B_, model.B_)
    assert loaded.nx_ == len(names) and loaded.nu_ == 2


@pytest.mark.parametrize("kind", KOOPMAN_KINDS)
def test_load_model_without_recorded_features(tmp_path, kind):
    path = tmp_path / "model.npz"
    _save(_koopman(kind), path)
    assert "features" not in load_model(path, kind).metadata_


def test_residual_recipe_sizes():
    # The residual model: speed, yaw rate, wheel angle and the command sent one step before.
    assert recipe_of_kind("residual").state.names == (
        "speed",
        "yaw_rate",
        "steer_angle",
        "previous_speed_command",
        "previous_steer_command",
    )
    assert set(KOOPMAN_KINDS) == {"residual", "paper", "koopman"}


@pytest.mark.parametrize("kind", KOOPMAN_KINDS)
def test_load_model_refuses_another_kind(tmp_path, kind):
    other = next(k for k in KOOPMAN_KINDS if k != kind)
    path = tmp_path / "model.npz"
    _save(_koopman(other, features=list(recipe_of_kind(other).state.names)), path)
    with pytest.raises(InputFileError, match=rf"model.npz \[kind\]: holds a '{other}' model") as info:
        load_model(path, kind)
    assert info.value.field == "kind"
    assert repr(kind) in info.value.problem


def test_load_model_refuses_a_model_without_kind(tmp_path):
    model = _koopman("residual")
    model.metadata_ = {"features": list(recipe_of_kind("residual").state.names)}
    path = tmp_path / "model.npz"
    _save(model, path)
    with pytest.raises(InputFileError, match="holds a None model") as info:
        load_model(path, "residual")
    assert info.value.field == "kind"


@pytest.mark.parametrize(
    "features",
    [
        ["speed", "yaw_rate", "slip_angle"],
        ["yaw_rate", "speed", "steer_angle"],  # same names, other order
        ["speed", "yaw_rate"],
        [],
    ],
)
def test_load_model_refuses_other_features(tmp_path, features):
    path = tmp_path / "model.npz"
    _save(_koopman("residual", features=features), path)
    with pytest.raises(InputFileError, match=r"model.npz \[features\]: the model was trained on") as info:
        load_model(path, "residual")
    assert info.value.field == "features"
    assert "steer_angle" in info.value.problem


def test_load_model_refuses_features_of_another_recipe(tmp_path):
    path = tmp_path / "model.npz"
    _save(_koopman("koopman", features=list(recipe_of_kind("residual").state.names)), path)
    with pytest.raises(InputFileError, match=r"\[features\]"):
        load_model(path, "koopman")


@pytest.mark.parametrize("kind", ["nope", "rkmpc", "", "Residual"])
def test_load_model_unknown_kind(tmp_path, kind):
    path = tmp_path / "id.json"
    save_identified(_identified(), path)
    with pytest.raises(ParameterError, match="unknown model kind"):
        load_model(path, kind)


def test_load_model_missing_koopman_file(tmp_path):
    with pytest.raises(InputFileError, match=r"absent\.npz"):
        load_model(tmp_path / "absent.npz", "residual")


def test_a_model_file_of_the_other_format_says_which_it_is(tmp_path):
    """A residual archive given to lmpc-id, or an identified JSON to rkmpc: no numpy pickle advice."""
    archive = tmp_path / "residual.rkm"
    _save(_koopman("residual"), archive)
    with pytest.raises(InputFileError, match=r"learned \(Koopman\) model archive.*--kind identified"):
        load_model(archive, "identified")
    identified = tmp_path / "identified.json"
    save_identified(_identified(), identified)
    with pytest.raises(InputFileError, match=r"holds a JSON file.*'residual' model archive") as info:
        load_model(identified, "residual")
    assert "pickle" not in str(info.value)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_model_path_that_is_no_file_says_what_it_is(tmp_path):
    """``--model`` naming a device, a folder or a FIFO: what it is, not "file not found" (nor a hang)."""
    from rkmpc.learning.io import load_any_model

    fifo = tmp_path / "model.rkm"
    os.mkfifo(fifo)  # opening it would block until a writer comes
    cases = [("/dev/null", "a character device"), (str(tmp_path), "a folder"), (str(fifo), "a FIFO")]
    loads = (lambda p: load_model(p, "residual"), lambda p: load_model(p, "identified"), load_any_model)
    for path, what in cases:
        for load in loads:
            with pytest.raises(InputFileError, match=rf"^{path}: {re.escape(what)}\b.*, not a regular file"):
                load(path)
